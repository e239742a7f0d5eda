"""A web player: one self-contained HTML page that plays a run in a browser.

The page holds everything it needs: a small WebGL2 player written for
clothsim (no library, no network at view time: it works opened from disk),
the frames, the colliders and the scene's name and parameters. It draws every
cloth of the run (one mesh: the frames hold every cloth's points in scene
order, ``meta.cloths`` says which are whose) with per-vertex normals computed
in the page and Blinn-Phong shading in the cloth colour (the back a darker
shade of it), spheres and planes in the renderer's neutral grey, and has an
orbit (drag), pan (shift-drag or right drag) and zoom (wheel) camera, a
play/pause button and a time slider.

How the frames are stored (``FORMAT``), per coordinate axis ``a``:

* each position is quantized to 16 bits over the run's bounding box:
  ``q = round((x - lo[a]) / step[a])`` with ``step[a] = (hi[a] - lo[a]) / 65535``,
  so a decoded position is within ``step[a] / 2`` of the simulated one;
* the frames are delta-coded in time: frame 0 as it is, frame k as
  ``d = q[k] - q[k-1]`` modulo 2**16;
* each delta, zigzag-coded (0, -1, 1, -2, ... as 0, 1, 2, 3, ...), takes one
  byte when under 255; the byte 255 stands for the next of the escapes, the
  deltas that do not fit (and frame 0), kept whole as little-endian uint16;
* the F x N bytes (frame by frame, point by point), then the escapes, are
  zlib-compressed (run-length strategy: as small as level 6 and faster than
  level 1; the page inflates it with the browser's own ``DecompressionStream``)
  and base64-coded into ``<script id="clothsim-pos-a">``; ``meta.escapes[a]``
  says how many escapes there are.

A 5 s run of a 50x50 cloth (451 frames of 2,500 points) takes 2.2 MB. The
three axes are coded in threads (numpy and zlib let go of the GIL); the
whole page costs about 60 ms of CPU, a tenth of the 0.6 s simulation.

The page answers to ``#frame=K`` (or ``#frame=last``, ``#t=SECONDS``) in its
address by showing that frame, paused; without it, it plays. For tests and
notebooks it exposes ``window.clothsimPlayer``: ``ready`` (true once the
frames are decoded and drawn), ``frames`` (their count), ``frame`` (the one
shown), ``playing``, ``error`` (a message, or null), ``setFrame(k)``,
``play()``, ``pause()`` and ``stepped`` (how many times playing moved to
another frame); the same state is mirrored on the ``<html>`` element as
``data-state`` ("loading", "ready" or "error: ..."), ``data-frame``,
``data-playing`` and ``data-stepped``.
"""

from __future__ import annotations

import base64
import html
import json
import math
import zlib
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..render.camera import FOV_Y_DEG, NEAR, Light, OrbitCamera, fit_points, framing
from ..render.renderer import BACKGROUND, COLLIDER_COLOR, DrawSettings

if TYPE_CHECKING:  # the Trajectory's notebook display imports this module
    from ..trajectory import Trajectory

FORMAT = "clothsim-player/1"
DEFAULT_COLOR: tuple[float, float, float] = DrawSettings.color
"""the cloth colour of the renderer (linear RGB in [0, 1])"""
SPHERE_DRAW_SCALE = 0.96
"""spheres drawn a little smaller, as the renderer does (the cloth lying on one is not pierced between its vertices)"""
LEVELS = 65535
"""quantization steps per axis (16 bits)"""
ESCAPE = 255
"""the byte that stands for a delta kept whole"""
CHUNK = 1 << 17
"""coordinates coded at a time"""


# ---------------------------------------------------------------------------
# the frames, encoded and decoded


def encode_positions(positions: np.ndarray) -> tuple[dict, list[str]]:
    """The frames ``positions`` (F, N, 3) as the page stores them (see the module's
    docstring): the quantization (``lo``, ``hi``, ``step`` per axis), the count of
    ``escapes`` per axis, and one base64 text per axis."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[2] != 3 or positions.shape[0] < 1:
        raise ValueError(f"positions: expected an array (frames, points, 3), got shape {positions.shape}")
    frames = positions.shape[0]
    rows = positions.reshape(frames, -1)  # min and max along the frames first: fast in this layout
    lo = rows.min(axis=0).reshape(-1, 3).min(axis=0)
    hi = rows.max(axis=0).reshape(-1, 3).max(axis=0)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        raise ValueError("positions: not finite (an unstable run?)")
    span = hi - lo
    step = np.where(span > 0, span / LEVELS, 0.0)
    scale = np.where(span > 0, LEVELS / np.where(span > 0, span, 1.0), 0.0)
    escapes = [0, 0, 0]
    points = positions.shape[1]
    chunk = max(1, CHUNK // max(points, 1))

    def axis_text(a: int) -> str:
        # a few frames at a time: the scratch stays in cache, and no array of
        # the whole run is made (its fresh pages cost more than the arithmetic)
        packer = zlib.compressobj(1, zlib.DEFLATED, 15, 9, zlib.Z_RLE)
        parts, kept = [], []
        x = np.empty((chunk, points))
        q = np.zeros((chunk + 1, points), np.uint16)  # q[0]: the frame before (none: 0)
        for f0 in range(0, frames, chunk):
            n = min(frames, f0 + chunk) - f0
            np.multiply(positions[f0:f0 + n, :, a], scale[a], out=x[:n])
            x[:n] += 0.5 - lo[a] * scale[a]
            q[1:n + 1] = x[:n]  # truncated: rounded, as x >= 0.5; within [0, 65535]
            d = q[1:n + 1] - q[:n]  # wraps modulo 2**16
            z = (d << 1) ^ (0 - (d >> 15))  # zigzag of d as int16, in uint16 arithmetic
            whole = z >= ESCAPE
            small = z.astype(np.uint8)
            small[whole] = ESCAPE
            kept.append(d[whole])
            parts.append(packer.compress(small))
            q[0] = q[n]
        whole_deltas = np.concatenate(kept).astype("<u2")
        escapes[a] = int(whole_deltas.size)
        parts += [packer.compress(whole_deltas), packer.flush()]
        return base64.b64encode(b"".join(parts)).decode("ascii")

    with ThreadPoolExecutor(3) as pool:
        texts = list(pool.map(axis_text, range(3)))
    return {"lo": lo.tolist(), "hi": hi.tolist(), "step": step.tolist(), "escapes": escapes}, texts


def decode_positions(quant: dict, texts: Sequence[str], frames: int, points: int) -> np.ndarray:
    """The inverse of :func:`encode_positions`, as the page decodes them: float64 (F, N, 3)."""
    out = np.empty((frames, points, 3))
    count = frames * points
    for a, text in enumerate(texts):
        data = zlib.decompress(base64.b64decode(text))
        if len(data) != count + 2 * quant["escapes"][a]:
            raise ValueError(f"axis {a}: {len(data)} bytes, expected {count + 2 * quant['escapes'][a]}")
        small = np.frombuffer(data, np.uint8, count).astype(np.uint16)
        d = (small >> 1) ^ (0 - (small & 1))  # zigzag back, modulo 2**16
        whole = small == ESCAPE
        d[whole] = np.frombuffer(data, "<u2", offset=count)
        q = np.cumsum(d.reshape(frames, points), axis=0, dtype=np.uint16)  # modulo 2**16, as made
        out[:, :, a] = quant["lo"][a] + q * quant["step"][a]
    return out


def _blob(array: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(np.ascontiguousarray(array).astype("<u4").tobytes(), 6)).decode("ascii")


def read_player(text: str) -> dict:
    """What a page written by :func:`player_html` holds, decoded in Python:
    ``meta`` (its JSON; ``meta["cloths"]``: each cloth's ``name``, points
    ``start:stop`` and triangles ``tri_start:tri_stop``), ``positions`` float64
    (F, N, 3), ``times``, ``triangles``."""
    def script(ident: str) -> str:
        start = text.index(f'id="{ident}"')
        start = text.index(">", start) + 1
        return text[start:text.index("</script>", start)].strip()

    meta = json.loads(script("clothsim-meta"))
    if meta.get("format") != FORMAT:
        raise ValueError(f"not a {FORMAT} page (format {meta.get('format')!r})")
    frames, points = meta["frames"], meta["points"]
    positions = decode_positions(meta, [script(f"clothsim-pos-{a}") for a in range(3)], frames, points)
    triangles = np.frombuffer(zlib.decompress(base64.b64decode(script("clothsim-tris"))), "<u4")
    return {"meta": meta, "positions": positions, "times": np.array(meta["times"]),
            "triangles": triangles.reshape(-1, 3).astype(np.int32)}


# ---------------------------------------------------------------------------
# the page


def _floats(value, count: int, name: str, lo: float | None = None, hi: float | None = None) -> list[float]:
    try:
        values = [float(v) for v in value]
    except (TypeError, ValueError):
        values = []
    ok = len(values) == count and all(math.isfinite(v) for v in values)
    if ok and lo is not None:
        ok = all(lo <= v for v in values)
    if ok and hi is not None:
        ok = all(v <= hi for v in values)
    if not ok:
        where = "" if lo is None else f" in [{lo:g}, {hi:g}]" if hi is not None else f" >= {lo:g}"
        raise ValueError(f"{name}: expected {count} numbers{where}, got {value!r}")
    return values


def _box(traj: Trajectory, quant: dict) -> tuple[np.ndarray, np.ndarray]:
    """Where the cloth went over the run (``quant``'s bounds), and the spheres."""
    lo, hi = np.array(quant["lo"]), np.array(quant["hi"])
    for s in traj.spheres:
        lo = np.minimum(lo, np.asarray(s.origin) - s.radius)
        hi = np.maximum(hi, np.asarray(s.origin) + s.radius)
    return lo, hi


def player_html(traj: Trajectory, color: Sequence[float] = DEFAULT_COLOR, width: int | None = None,
                height: int | None = None, *, camera: Sequence[float] | None = None,
                phong: Sequence[float] | None = None, light: Light | None = None, title: str | None = None) -> str:
    """The self-contained HTML page that plays ``traj``.

    ``color``: the cloth's, linear RGB in [0, 1]. ``width``, ``height``: the
    player's size in CSS pixels; without them it fills the browser window.
    ``camera``: (azimuth, elevation [degrees], distance [m]) to start from,
    aimed at the middle of where the cloth goes (default 30, 25 and a distance
    that frames it). ``phong``: (ka, kd, ks, shininess) of the Blinn-Phong
    shading; ``light``: its point light (both default to the renderer's).
    ``title``: the name shown (default the scene's).
    """
    color = _floats(color, 3, "color", 0.0, 1.0)
    for name, value in (("width", width), ("height", height)):
        if value is not None and (not isinstance(value, (int, np.integer)) or not 16 <= value <= 16384):
            raise ValueError(f"{name}: expected a whole number of CSS pixels in 16..16384 or None, got {value!r}")
    defaults = DrawSettings()
    ka, kd, ks, p = _floats(phong if phong is not None else (defaults.ka, defaults.kd, defaults.ks, defaults.p),
                            4, "phong", 0.0)
    light = light or Light()
    light_pos = _floats(light.position, 3, "light position")
    light_int = _floats(light.intensity, 3, "light intensity", 0.0)

    positions = np.asarray(traj.positions)
    frames, points = positions.shape[0], positions.shape[1]
    quant, pos_texts = encode_positions(positions)
    lo, hi = _box(traj, quant)
    target, distance = framing(lo, hi)
    cam = fit_points(OrbitCamera(target=target, distance=distance), positions[0])  # the start in view
    if camera is not None:
        cam.azimuth, cam.elevation, cam.distance = _floats(camera, 3, "camera")
    reach = positions[0].max(axis=0) - positions[0].min(axis=0)
    plane_size = 2.5 * max(float(reach.max()), 0.5)  # as the renderer: 2.5 cloth sizes
    center = (lo + hi) / 2.0
    name = traj.name if title is None else title
    duration = float(traj.times[-1] - traj.times[0]) if frames > 1 else 0.0

    meta = {
        "format": FORMAT, "name": name, "description": traj.description,
        "frames": frames, "points": points, "triangles": int(len(traj.triangles)),
        "cloths": [{"name": c.name, "start": c.start, "stop": c.stop, "tri_start": c.tri_start,
                    "tri_stop": c.tri_stop} for c in traj.parts],
        "fps": float(traj.frames_per_sec), "duration": duration,
        "times": [round(float(t), 6) for t in traj.times],
        **quant,
        "spheres": [{"origin": list(map(float, s.origin)), "radius": SPHERE_DRAW_SCALE * float(s.radius)}
                    for s in traj.spheres],
        "planes": [{"point": list(map(float, pl.point)), "normal": list(map(float, pl.normal)),
                    "center": center.tolist(), "size": plane_size} for pl in traj.planes],
        "camera": {"target": np.asarray(cam.target, float).tolist(), "azimuth": cam.azimuth,
                   "elevation": cam.elevation, "distance": cam.distance, "fov_y": FOV_Y_DEG, "near": NEAR},
        "look": {"color": color, "back": [0.6 * c for c in color], "collider": list(COLLIDER_COLOR),
                 "background": list(BACKGROUND), "ka": ka, "kd": kd, "ks": ks, "p": p,
                 "light_position": light_pos, "light_intensity": light_int},
    }
    meta_json = json.dumps(meta, separators=(",", ":")).replace("<", "\\u003c")
    tris_text = _blob(np.asarray(traj.triangles))
    data = "\n".join(f'<script type="application/octet-stream" id="clothsim-pos-{a}">{t}</script>'
                     for a, t in enumerate(pos_texts))
    if width is None or height is None:
        box_css = "#clothsim{position:fixed;inset:0}"
    else:
        box_css = f"#clothsim{{position:relative;width:{int(width)}px;height:{int(height)}px}}"
    bg = ",".join(str(round(255 * c)) for c in BACKGROUND)
    return (_PAGE.replace("%TITLE%", html.escape(f"{name} - clothsim"))
                 .replace("%BOX_CSS%", box_css).replace("%BG%", bg)
                 .replace("%NAME%", html.escape(name)).replace("%DESCRIPTION%", html.escape(traj.description))
                 .replace("%META%", meta_json).replace("%TRIS%", tris_text)
                 .replace("%JS%", _PLAYER_JS).replace("%DATA%", data))


def write_player(path: str | Path, traj: Trajectory, **look) -> None:
    """Write :func:`player_html` of ``traj`` to ``path`` (keywords as there)."""
    Path(path).write_text(player_html(traj, **look), encoding="utf-8")


# The page. The %NAMES% are filled in by player_html; the data comes last so
# that the page's own text stays at the top of the file.
_PAGE = """<!DOCTYPE html>
<html lang="en" data-state="loading" data-frame="0">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="clothsim">
<title>%TITLE%</title>
<style>
html,body{margin:0;padding:0;background:rgb(%BG%);color:#e8e8ec;font:13px/1.35 system-ui,sans-serif}
%BOX_CSS%
#clothsim{overflow:hidden;background:rgb(%BG%);user-select:none}
#clothsim canvas{position:absolute;inset:0;width:100%;height:100%;display:block;touch-action:none;cursor:grab}
#clothsim canvas:active{cursor:grabbing}
#clothsim .info{position:absolute;left:10px;top:8px;max-width:calc(100% - 20px);pointer-events:none;
  text-shadow:0 1px 2px #000}
#clothsim .info b{font-size:15px}
#clothsim .info .params,#clothsim .info .hint{opacity:.8;font-size:12px}
#clothsim .bar{position:absolute;left:0;right:0;bottom:0;display:flex;gap:10px;align-items:center;
  padding:8px 12px;background:rgba(0,0,0,.35)}
#clothsim button{width:34px;height:26px;border:1px solid #888;border-radius:4px;background:#2a2c33;
  color:#eee;font-size:14px;cursor:pointer;padding:0}
#clothsim input[type=range]{flex:1;min-width:60px}
#clothsim .time{font-variant-numeric:tabular-nums;white-space:nowrap;min-width:9em;text-align:right}
#clothsim .message{position:absolute;left:50%;top:50%;transform:translate(-50%,-50%);padding:12px 16px;
  background:rgba(0,0,0,.6);border-radius:6px;max-width:80%;text-align:center}
</style>
</head>
<body>
<div id="clothsim">
<canvas></canvas>
<div class="info"><b>%NAME%</b><div class="params">%DESCRIPTION%</div><div class="stats"></div>
<div class="hint">drag: orbit &middot; shift-drag: pan &middot; wheel: zoom &middot; double-click: reset &middot; space: play/pause</div></div>
<div class="bar"><button type="button" class="play" title="play / pause (space)">&#9654;</button>
<input type="range" class="slider" min="0" max="0" value="0" step="1" aria-label="frame">
<span class="time"></span></div>
<div class="message">loading&hellip;</div>
</div>
<script type="application/json" id="clothsim-meta">%META%</script>
<script type="application/octet-stream" id="clothsim-tris">%TRIS%</script>
<script>
%JS%
</script>
%DATA%
</body>
</html>
"""

# The player, run once the page (data included) is parsed: the script waits
# for DOMContentLoaded, as the frames' <script> elements come after it.
_PLAYER_JS = r"""
(function () {
"use strict";
const root = document.getElementById("clothsim");
const meta = JSON.parse(document.getElementById("clothsim-meta").textContent);
const F = meta.frames, N = meta.points;
const canvas = root.querySelector("canvas");
const playButton = root.querySelector(".play");
const slider = root.querySelector(".slider");
const timeLabel = root.querySelector(".time");
const message = root.querySelector(".message");
root.querySelector(".stats").textContent =
  (meta.cloths.length > 1 ? meta.cloths.length + " cloths \u00b7 " : "") +
  N + " points \u00b7 " + F + " frames \u00b7 " + meta.duration.toFixed(2) + " s at " + meta.fps + " frames/s";

let ready = false, playing = false, frame = 0, clock = 0, error = null, stepped = 0;
let gl = null, draw = null, dirty = true;

const api = {
  get ready() { return ready; },
  frames: F,
  times: meta.times,
  get frame() { return frame; },
  get playing() { return playing; },
  get error() { return error; },
  get stepped() { return stepped; },
  setFrame: function (k) { setFrame(k, true); },
  play: function () { play(); },
  pause: function () { pause(); },
};
window.clothsimPlayer = api;

function mark() {
  document.documentElement.dataset.state = error ? "error: " + error : (ready ? "ready" : "loading");
  document.documentElement.dataset.frame = String(frame);
  document.documentElement.dataset.playing = String(playing);
  document.documentElement.dataset.stepped = String(stepped);
}

function fail(text) {
  error = text;
  message.textContent = text;
  message.style.display = "";
  mark();
}

// ---- decoding -------------------------------------------------------------

function base64Bytes(id) {
  const text = document.getElementById(id).textContent.trim();
  if (typeof Uint8Array.fromBase64 === "function") return Uint8Array.fromBase64(text);
  const bin = atob(text), out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

async function inflate(bytes) {
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

// The frames stay quantized (2 bytes a coordinate); framePositions makes one
// frame's floats when it is shown.
async function decode() {
  const quant = new Uint16Array(F * N * 3), count = F * N;
  for (let a = 0; a < 3; a++) {
    const b = await inflate(base64Bytes("clothsim-pos-" + a));
    if (b.length !== count + 2 * meta.escapes[a]) throw new Error("frame data of axis " + a + " has the wrong length");
    const acc = new Uint16Array(N);
    let e = count;  // the next escape: a delta kept whole, little-endian
    for (let f = 0; f < F; f++) {
      const base = f * N;
      for (let p = 0; p < N; p++) {
        const i = base + p, z = b[i];
        let d;
        if (z === 255) { d = b[e] | (b[e + 1] << 8); e += 2; }
        else d = (z >>> 1) ^ -(z & 1);  // zigzag back to a signed delta
        acc[p] += d;  // a Uint16Array wraps modulo 2**16, as the deltas do
        quant[3 * i + a] = acc[p];
      }
    }
  }
  const tb = await inflate(base64Bytes("clothsim-tris"));
  const tris = new Uint32Array(tb.buffer, tb.byteOffset, tb.length / 4);
  return {quant: quant, tris: tris};
}

function framePositions(quant, f, out) {
  const o = 3 * N * f, lo = meta.lo, step = meta.step;
  for (let i = 0; i < 3 * N; i += 3) {
    out[i] = lo[0] + quant[o + i] * step[0];
    out[i + 1] = lo[1] + quant[o + i + 1] * step[1];
    out[i + 2] = lo[2] + quant[o + i + 2] * step[2];
  }
  return out;
}

// Area-weighted vertex normals of one frame's positions (as clothsim's mesh.vertex_normals).
function frameNormals(pos, tris, out) {
  out.fill(0);
  for (let t = 0; t < tris.length; t += 3) {
    const a = 3 * tris[t], b = 3 * tris[t + 1], c = 3 * tris[t + 2];
    const e1x = pos[b] - pos[a], e1y = pos[b + 1] - pos[a + 1], e1z = pos[b + 2] - pos[a + 2];
    const e2x = pos[c] - pos[a], e2y = pos[c + 1] - pos[a + 1], e2z = pos[c + 2] - pos[a + 2];
    const nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
    out[a] += nx; out[a + 1] += ny; out[a + 2] += nz;
    out[b] += nx; out[b + 1] += ny; out[b + 2] += nz;
    out[c] += nx; out[c + 1] += ny; out[c + 2] += nz;
  }
  for (let v = 0; v < out.length; v += 3) {
    const l = Math.sqrt(out[v] * out[v] + out[v + 1] * out[v + 1] + out[v + 2] * out[v + 2]);
    if (l > 0) { out[v] /= l; out[v + 1] /= l; out[v + 2] /= l; }
  }
  return out;
}

// ---- matrices (column-major, as WebGL takes them) ---------------------------

function perspective(fovyDeg, aspect, near, far) {
  const f = 1 / Math.tan(fovyDeg * Math.PI / 360), m = new Float32Array(16);
  m[0] = f / aspect; m[5] = f; m[10] = (far + near) / (near - far); m[11] = -1;
  m[14] = 2 * far * near / (near - far);
  return m;
}
function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function unit(a) { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; }
function lookAt(eye, target) {
  const fwd = unit(sub(target, eye));
  let side = cross(fwd, [0, 1, 0]);
  if (Math.hypot(side[0], side[1], side[2]) < 1e-9) side = cross(fwd, [0, 0, -1]);
  side = unit(side);
  const up = cross(side, fwd), m = new Float32Array(16);
  m[0] = side[0]; m[4] = side[1]; m[8] = side[2];
  m[1] = up[0]; m[5] = up[1]; m[9] = up[2];
  m[2] = -fwd[0]; m[6] = -fwd[1]; m[10] = -fwd[2];
  m[12] = -dot(side, eye); m[13] = -dot(up, eye); m[14] = dot(fwd, eye); m[15] = 1;
  return {m: m, side: side, up: up};
}
function multiply(a, b) {
  const r = new Float32Array(16);
  for (let c = 0; c < 4; c++) for (let i = 0; i < 4; i++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += a[4 * k + i] * b[4 * c + k];
    r[4 * c + i] = s;
  }
  return r;
}

// ---- camera -----------------------------------------------------------------

const home = meta.camera;
const cam = {target: home.target.slice(), azimuth: home.azimuth, elevation: home.elevation, distance: home.distance};
function resetCamera() {
  cam.target = home.target.slice(); cam.azimuth = home.azimuth;
  cam.elevation = home.elevation; cam.distance = home.distance; dirty = true;
}
function eye() {
  const az = cam.azimuth * Math.PI / 180, el = cam.elevation * Math.PI / 180;
  return [cam.target[0] + cam.distance * Math.cos(el) * Math.sin(az),
          cam.target[1] + cam.distance * Math.sin(el),
          cam.target[2] + cam.distance * Math.cos(el) * Math.cos(az)];
}

let drag = null;
canvas.addEventListener("pointerdown", function (e) {
  drag = {x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2};
  canvas.setPointerCapture(e.pointerId);
});
canvas.addEventListener("pointermove", function (e) {
  if (!drag) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX; drag.y = e.clientY;
  if (drag.pan) {
    const v = lookAt(eye(), cam.target), h = canvas.clientHeight || 1;
    const s = cam.distance * 2 * Math.tan(home.fov_y * Math.PI / 360) / h;
    for (let i = 0; i < 3; i++) cam.target[i] += s * (-dx * v.side[i] + dy * v.up[i]);
  } else {
    cam.azimuth = (cam.azimuth - 0.4 * dx) % 360;
    cam.elevation = Math.max(-89, Math.min(89, cam.elevation + 0.4 * dy));
  }
  dirty = true;
});
canvas.addEventListener("pointerup", function () { drag = null; });
canvas.addEventListener("pointercancel", function () { drag = null; });
canvas.addEventListener("contextmenu", function (e) { e.preventDefault(); });
canvas.addEventListener("dblclick", resetCamera);
canvas.addEventListener("wheel", function (e) {
  e.preventDefault();
  const lines = e.deltaMode === 1 ? 40 : (e.deltaMode === 2 ? 800 : 1);
  cam.distance = Math.max(0.02, Math.min(1000, cam.distance * Math.exp(0.0015 * e.deltaY * lines)));
  dirty = true;
}, {passive: false});

// ---- playback ---------------------------------------------------------------

function showTime() {
  const t = meta.times[frame] - meta.times[0];
  timeLabel.textContent = t.toFixed(2) + " / " + meta.duration.toFixed(2) + " s";
  slider.value = String(frame);
  playButton.innerHTML = playing ? "&#10074;&#10074;" : "&#9654;";
  mark();
}
function setFrame(k, moveClock) {
  k = Math.max(0, Math.min(F - 1, Math.round(Number(k)) || 0));
  if (moveClock) clock = meta.times[k] - meta.times[0];
  if (k !== frame) { frame = k; dirty = true; }
  showTime();
}
function play() {
  if (F < 2) return;
  if (frame >= F - 1) setFrame(0, true);
  playing = true; last = null; showTime();
}
function pause() { playing = false; showTime(); }
function frameAt(t) {  // the last frame at or before t seconds into the run
  let lo = 0, hi = F - 1;
  while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (meta.times[mid] - meta.times[0] <= t + 1e-9) lo = mid; else hi = mid - 1; }
  return lo;
}

playButton.addEventListener("click", function () { if (playing) pause(); else play(); });
slider.addEventListener("input", function () { setFrame(slider.value, true); });
document.addEventListener("keydown", function (e) {
  if (e.target && e.target.tagName === "INPUT" && e.key !== " ") return;
  if (e.key === " ") { e.preventDefault(); if (playing) pause(); else play(); }
  else if (e.key === "ArrowRight") { pause(); setFrame(frame + 1, true); }
  else if (e.key === "ArrowLeft") { pause(); setFrame(frame - 1, true); }
  else if (e.key === "Home") { setFrame(0, true); }
  else if (e.key === "End") { setFrame(F - 1, true); }
});

// #frame=K, #frame=last or #t=SECONDS: that frame, paused. True when the address names one.
function fromHash() {
  const h = new URLSearchParams(location.hash.replace(/^#/, ""));
  if (h.has("frame")) {
    const v = h.get("frame");
    pause(); setFrame(v === "last" ? F - 1 : parseInt(v, 10), true);
    return true;
  }
  if (h.has("t")) { pause(); setFrame(frameAt(parseFloat(h.get("t")) || 0), true); return true; }
  return false;
}
window.addEventListener("hashchange", fromHash);

let last = null;
function tick(now) {
  if (playing) {
    if (last !== null) clock += Math.min(0.1, (now - last) / 1000);
    if (clock > meta.duration + 0.5 / meta.fps) clock = 0;  // loop
    const k = frameAt(clock);
    if (k !== frame) { frame = k; stepped++; dirty = true; showTime(); }
  }
  last = now;
  if (dirty && draw) { draw(); dirty = false; }
  requestAnimationFrame(tick);
}

// ---- WebGL2 -----------------------------------------------------------------

const VERT = `#version 300 es
in vec3 a_pos;
in vec3 a_nrm;
uniform mat4 u_mvp;
out vec3 v_pos;
out vec3 v_nrm;
void main() { v_pos = a_pos; v_nrm = a_nrm; gl_Position = u_mvp * vec4(a_pos, 1.0); }`;

// Blinn-Phong as clothsim's Phong shader; the back of a face lit with its
// normal turned round, in the back colour.
const FRAG = `#version 300 es
precision highp float;
uniform vec3 u_front;
uniform vec3 u_back;
uniform vec3 u_cam;
uniform vec3 u_light_pos;
uniform vec3 u_light_int;
uniform vec4 u_k;
in vec3 v_pos;
in vec3 v_nrm;
out vec4 o;
void main() {
  vec3 n = normalize(v_nrm);
  vec3 base = u_front;
  if (!gl_FrontFacing) { n = -n; base = u_back; }
  vec3 to_light = u_light_pos - v_pos;
  vec3 l = normalize(to_light);
  vec3 v = normalize(u_cam - v_pos);
  vec3 h = normalize(l + v);
  vec3 radiance = u_light_int / dot(to_light, to_light);
  vec3 c = u_k.x * base + u_k.y * base * radiance * max(dot(n, l), 0.0)
         + u_k.z * radiance * pow(max(dot(n, h), 0.0), u_k.w);
  o = vec4(c, 1.0);
}`;

function shader(type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
  return s;
}

function mesh(program, pos, nrm, idx, dynamic) {
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const usage = dynamic ? gl.DYNAMIC_DRAW : gl.STATIC_DRAW, buffers = [];
  [["a_pos", pos], ["a_nrm", nrm]].forEach(function (pair) {
    const buf = gl.createBuffer(), loc = gl.getAttribLocation(program, pair[0]);
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, pair[1], usage);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    buffers.push(buf);
  });
  const ibuf = gl.createBuffer();
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibuf);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  return {vao: vao, pos: buffers[0], nrm: buffers[1], count: idx.length};
}

function sphereMesh(program, center, radius) {
  const lat = 32, lon = 48, pos = [], nrm = [], idx = [];
  for (let i = 0; i <= lat; i++) {
    const th = Math.PI * i / lat;
    for (let j = 0; j <= lon; j++) {
      const ph = 2 * Math.PI * j / lon;
      const n = [Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph)];
      nrm.push(n[0], n[1], n[2]);
      pos.push(center[0] + radius * n[0], center[1] + radius * n[1], center[2] + radius * n[2]);
    }
  }
  for (let i = 0; i < lat; i++) for (let j = 0; j < lon; j++) {
    const a = i * (lon + 1) + j, b = a + lon + 1;
    idx.push(a, a + 1, b, a + 1, b + 1, b);  // counter-clockwise seen from outside
  }
  return mesh(program, new Float32Array(pos), new Float32Array(nrm), new Uint32Array(idx), false);
}

function planeMesh(program, plane) {
  const n = unit(plane.normal), p = plane.point, c = plane.center, h = plane.size / 2;
  const off = dot(sub(c, p), n), m = [c[0] - off * n[0], c[1] - off * n[1], c[2] - off * n[2]];
  let u = cross(n, Math.abs(n[1]) < 0.9 ? [0, 1, 0] : [1, 0, 0]);
  u = unit(u);
  const w = cross(n, u), pos = [];
  for (const [su, sw] of [[-1, -1], [1, -1], [1, 1], [-1, 1]])
    pos.push(m[0] + h * (su * u[0] + sw * w[0]), m[1] + h * (su * u[1] + sw * w[1]), m[2] + h * (su * u[2] + sw * w[2]));
  const nrm = [];
  for (let i = 0; i < 4; i++) nrm.push(n[0], n[1], n[2]);
  return mesh(program, new Float32Array(pos), new Float32Array(nrm), new Uint32Array([0, 1, 2, 0, 2, 3]), false);
}

function setUp(data) {
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, VERT));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, FRAG));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(program));
  const u = {};
  ["u_mvp", "u_front", "u_back", "u_cam", "u_light_pos", "u_light_int", "u_k"].forEach(function (name) {
    u[name] = gl.getUniformLocation(program, name);
  });
  const positions = framePositions(data.quant, 0, new Float32Array(3 * N)), normals = new Float32Array(3 * N);
  const cloth = mesh(program, positions, frameNormals(positions, data.tris, normals), data.tris, true);
  const colliders = meta.spheres.map(function (s) { return sphereMesh(program, s.origin, s.radius); })
    .concat(meta.planes.map(function (p) { return planeMesh(program, p); }));
  const look = meta.look, bg = look.background;
  let shown = 0;

  draw = function () {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    if (shown !== frame) {
      gl.bindBuffer(gl.ARRAY_BUFFER, cloth.pos);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, framePositions(data.quant, frame, positions));
      gl.bindBuffer(gl.ARRAY_BUFFER, cloth.nrm);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, frameNormals(positions, data.tris, normals));
      shown = frame;
    }
    gl.viewport(0, 0, w, h);
    gl.clearColor(bg[0], bg[1], bg[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(program);
    const e = eye();
    const mvp = multiply(perspective(home.fov_y, w / h, home.near, Math.max(100, 10 * cam.distance)),
                         lookAt(e, cam.target).m);
    gl.uniformMatrix4fv(u.u_mvp, false, mvp);
    gl.uniform3fv(u.u_cam, e);
    gl.uniform3fv(u.u_light_pos, look.light_position);
    gl.uniform3fv(u.u_light_int, look.light_intensity);
    gl.uniform4f(u.u_k, look.ka, look.kd, look.ks, look.p);
    gl.uniform3fv(u.u_front, look.color);
    gl.uniform3fv(u.u_back, look.back);
    gl.bindVertexArray(cloth.vao);
    gl.drawElements(gl.TRIANGLES, cloth.count, gl.UNSIGNED_INT, 0);
    gl.uniform4f(u.u_k, look.ka, look.kd, 0.2 * look.ks, look.p);
    gl.uniform3fv(u.u_front, look.collider);
    gl.uniform3fv(u.u_back, look.collider);
    colliders.forEach(function (c) { gl.bindVertexArray(c.vao); gl.drawElements(gl.TRIANGLES, c.count, gl.UNSIGNED_INT, 0); });
    gl.bindVertexArray(null);
  };
}

async function start() {
  slider.max = String(F - 1);
  showTime();
  gl = canvas.getContext("webgl2", {antialias: true, preserveDrawingBuffer: true});
  if (!gl) { fail("This page needs WebGL2, which this browser does not offer."); return; }
  if (typeof DecompressionStream !== "function") { fail("This page needs a browser with DecompressionStream."); return; }
  try {
    setUp(await decode());
  } catch (e) {
    fail("Could not show the run: " + (e && e.message ? e.message : e));
    return;
  }
  message.style.display = "none";
  const named = fromHash();
  dirty = true;
  draw();
  dirty = false;
  ready = true;
  if (!named) play();
  showTime();
  // drawn at once on a resize, not at the next animation frame: a canvas
  // stretched to its new size until then looks squashed (and a headless
  // browser's screenshot may come first)
  const redraw = function () { if (draw) { draw(); dirty = false; } };
  new ResizeObserver(redraw).observe(canvas);
  window.addEventListener("resize", redraw);
  requestAnimationFrame(tick);
}

if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
else start();
})();
"""
