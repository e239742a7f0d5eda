"""Cloth meshes made by our own code, and the OBJ files of the standard scenes.

Every generator returns a :class:`Mesh`: vertices [m] float64 (N, 3), faces
int64 (F, 3) or (F, 4) of vertex indices (counter-clockwise seen from the
side the cloth's normal points to), and texture coordinates in [0, 1]²
float64 (N, 2). Vertices are ordered so that neighbours on the cloth are near
in memory (rows of a grid; Morton order of scattered points), which the
solver's gathers need to run fast.

``python -m clothsim.procedural [folder]`` rewrites the shipped meshes
(``clothsim/scenes/meshes/*.obj``) byte for byte; the tests check that it does.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

UP = np.array([0.0, 1.0, 0.0])
FRONT = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class Mesh:
    vertices: np.ndarray
    """positions [m], float64 (N, 3)"""
    faces: np.ndarray
    """vertex indices, int64 (F, 3) for triangles or (F, 4) for quads"""
    uvs: np.ndarray
    """texture coordinates in [0, 1]², float64 (N, 2)"""
    comment: str = ""
    """what made it (the OBJ file's first line)"""


# ---------------------------------------------------------------- ordering


def morton_order(points: np.ndarray, bits: int = 16) -> np.ndarray:
    """The permutation that sorts 2-D ``points`` (N, 2) along a Z-order curve.

    Each axis is quantised to ``bits`` bits over the points' bounding box and
    the bits interleaved; ties (never for distinct points at 16 bits and a
    cloth's spacing) keep their input order.
    """
    p = np.asarray(points, dtype=np.float64)
    lo, span = p.min(axis=0), np.ptp(p, axis=0)
    q = np.floor((p - lo) / np.where(span > 0, span, 1.0) * ((1 << bits) - 1) + 0.5).astype(np.uint64)
    code = np.zeros(len(p), dtype=np.uint64)
    for b in range(bits):
        for axis in range(2):
            bit = (q[:, axis] >> np.uint64(b)) & np.uint64(1)
            code |= bit << np.uint64(2 * b + axis)
    return np.argsort(code, kind="stable")


def reorder(mesh: Mesh, order: np.ndarray) -> Mesh:
    """``mesh`` with its vertices in ``order`` (new vertex k is old ``order[k]``)
    and its faces renumbered, then put in canonical order (each face starting at
    its lowest index, winding kept; faces sorted), so the result depends on the
    geometry only, not on the order a triangulator happened to emit."""
    new_index = np.empty(len(order), dtype=np.int64)
    new_index[order] = np.arange(len(order))
    faces = new_index[mesh.faces]
    faces = np.array([np.roll(f, -int(np.argmin(f))) for f in faces], dtype=np.int64).reshape(faces.shape)
    faces = faces[np.lexsort(faces.T[::-1])]
    return Mesh(mesh.vertices[order], faces, mesh.uvs[order], mesh.comment)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted normals (F, 3) of planar or near-planar faces (Newell's
    method: twice the area for a triangle), unnormalised."""
    v = vertices[faces]
    nxt = np.roll(v, -1, axis=1)
    return np.cross(v, nxt).sum(axis=1)


def orient(vertices: np.ndarray, faces: np.ndarray, side: np.ndarray) -> np.ndarray:
    """``faces`` with every face whose normal points away from ``side`` reversed."""
    flip = face_normals(vertices, faces) @ side < 0
    out = faces.copy()
    out[flip] = out[flip, ::-1]
    return out


def planar_uvs(vertices: np.ndarray, axes: tuple[int, int]) -> np.ndarray:
    """Texture coordinates (N, 2): the two coordinate ``axes`` scaled to [0, 1]
    by the larger side of the bounding box (so a square texel stays square)."""
    p = vertices[:, axes]
    lo = p.min(axis=0)
    side = float(np.ptp(p, axis=0).max()) or 1.0
    return (p - lo) / side


# -------------------------------------------------------------- generators


def disc(radius: float = 0.7, rings: int = 25) -> Mesh:
    """A horizontal disc (the y=0 plane, centred on the origin) of triangles.

    Ring k (1..``rings``) holds 6k vertices evenly on the circle of radius
    ``radius * k / rings`` [m]; consecutive rings are stitched by walking both
    in angle, so the triangles are nearly equilateral (sides about
    ``radius / rings``). 1 + 3 rings (rings + 1) vertices, 6 rings² triangles,
    all counter-clockwise seen from +y; Morton-ordered.
    """
    angles = [np.zeros(1)] + [2 * np.pi * np.arange(6 * k) / (6 * k) for k in range(1, rings + 1)]
    radii = [0.0] + [radius * k / rings for k in range(1, rings + 1)]
    starts = np.cumsum([0] + [len(a) for a in angles])
    xs = np.concatenate([r * np.cos(a) for r, a in zip(radii, angles)])
    zs = np.concatenate([-r * np.sin(a) for r, a in zip(radii, angles)])
    vertices = np.stack([xs, np.zeros_like(xs), zs], axis=1)
    faces = []
    for k in range(1, rings + 1):
        inner, outer = starts[k - 1], starts[k]
        n_in, n_out = len(angles[k - 1]), len(angles[k])
        i = j = 0
        while j < n_out or (k > 1 and i < n_in):
            # advance the ring whose step makes the shorter new edge (the
            # Delaunay choice for two concentric rows)
            a, b = inner + i % n_in, outer + j % n_out
            a_next, b_next = inner + (i + 1) % n_in, outer + (j + 1) % n_out
            if k == 1 or i >= n_in or (j < n_out and _dist(vertices, a, b_next) <= _dist(vertices, a_next, b)):
                faces.append((a, b, b_next))
                j += 1
            else:
                faces.append((a, b, a_next))
                i += 1
    faces = orient(vertices, np.array(faces, dtype=np.int64), UP)
    uvs = (vertices[:, [0, 2]] + radius) / (2 * radius)
    mesh = Mesh(vertices, faces, uvs, f"disc(radius={radius:g}, rings={rings})")
    return reorder(mesh, morton_order(vertices[:, [0, 2]]))


def _dist(vertices: np.ndarray, a: int, b: int) -> float:
    return float(np.linalg.norm(vertices[a] - vertices[b]))


def quad_grid(columns: int = 40, rows: int = 20, width: float = 1.0, height: float = 0.5,
              vertical: bool = True, jitter: float = 0.0, seed: int = 0) -> Mesh:
    """A ``width`` x ``height`` [m] sheet of (columns-1)(rows-1) quads, its
    vertices row-major (``columns`` a row). Vertical: in the z=0 plane, x in
    [0, width], y in [0, height], quads counter-clockwise seen from +z.
    Horizontal: in the y=0 plane centred on the origin, counter-clockwise seen
    from +y. ``jitter`` [m] moves each vertex off the plane by a seeded uniform
    amount in [-jitter, jitter], as CS184 does for a vertical grid, so that a
    sheet hanging in its own plane can buckle out of it."""
    u = np.linspace(0.0, width, columns)
    v = np.linspace(0.0, height, rows)
    uu, vv = np.meshgrid(u, v)
    uu, vv = uu.ravel(), vv.ravel()
    if vertical:
        vertices = np.stack([uu, vv, np.zeros_like(uu)], axis=1)
    else:
        vertices = np.stack([uu - width / 2, np.zeros_like(uu), vv - height / 2], axis=1)
    if jitter:
        vertices[:, 2 if vertical else 1] = np.random.default_rng(seed).uniform(-jitter, jitter, len(vertices))
    c = np.arange(columns - 1)
    r = np.arange(rows - 1)[:, None]
    a = (r * columns + c).ravel()
    faces = np.stack([a, a + 1, a + columns + 1, a + columns], axis=1).astype(np.int64)
    faces = orient(vertices, faces, FRONT if vertical else UP)
    uvs = np.stack([uu / width, vv / height], axis=1)
    kind = "vertical" if vertical else "horizontal"
    extra = f", jitter={jitter:g}, seed={seed}" if jitter else ""
    return Mesh(vertices, faces, uvs, f"quad_grid(columns={columns}, rows={rows}, width={width:g}, "
                                      f"height={height:g}, {kind}{extra})")


def poisson_points(count: int, side: float, spacing: float, seed: int) -> np.ndarray:
    """``count`` points (N, 2) [m] in the square [-side/2, side/2]², seeded:
    the square's edges evenly divided at about ``1.4 * spacing``, then random
    points (numpy's PCG64 stream of ``seed``) each kept only if it lies at least
    ``spacing`` from every point kept so far (dart throwing), so no two are
    closer than ``spacing`` and the triangulation has no slivers from
    near-coincident points."""
    per_edge = max(1, round(side / (1.4 * spacing)))
    t = np.arange(per_edge) / per_edge * side - side / 2
    h = side / 2
    edge = np.concatenate([np.stack([t, np.full_like(t, -h)], 1), np.stack([np.full_like(t, h), t], 1),
                           np.stack([-t, np.full_like(t, h)], 1), np.stack([np.full_like(t, -h), -t], 1)])
    kept = [tuple(p) for p in edge]
    cell = spacing / math.sqrt(2)
    grid: dict[tuple[int, int], tuple[float, float]] = {}

    def key(p):
        return math.floor((p[0] + h) / cell), math.floor((p[1] + h) / cell)

    for p in kept:
        grid[key(p)] = p
    rng = np.random.default_rng(seed)
    limit2 = spacing * spacing
    tries = 0
    while len(kept) < count:
        tries += 1
        if tries > 200 * count:
            raise ValueError(f"cannot place {count} points {spacing} m apart in a {side} m square")
        x, y = (rng.random(2) * (side - spacing) - (side - spacing) / 2).tolist()
        cx, cy = key((x, y))
        if any((q := grid.get((cx + dx, cy + dy))) is not None and (q[0] - x) ** 2 + (q[1] - y) ** 2 < limit2
               for dx in range(-2, 3) for dy in range(-2, 3)):
            continue
        grid[(cx, cy)] = (x, y)
        kept.append((x, y))
    return np.array(kept, dtype=np.float64)


def delaunay_square(count: int = 2500, side: float = 1.0, spacing: float = 0.014, seed: int = 20) -> Mesh:
    """An irregular horizontal sheet: the Delaunay triangulation (scipy's
    qhull) of :func:`poisson_points` in a ``side`` [m] square in the y=0 plane,
    centred on the origin; triangles counter-clockwise seen from +y,
    vertices Morton-ordered."""
    from scipy.spatial import Delaunay

    points = poisson_points(count, side, spacing, seed)
    tri = Delaunay(points)
    if len(tri.coplanar):
        raise ValueError("some points were left out of the triangulation")
    vertices = np.stack([points[:, 0], np.zeros(len(points)), points[:, 1]], axis=1)
    faces = orient(vertices, tri.simplices.astype(np.int64), UP)
    mesh = Mesh(vertices, faces, planar_uvs(vertices, (0, 2)),
                f"delaunay_square(count={count}, side={side:g}, spacing={spacing:g}, seed={seed})")
    return reorder(mesh, morton_order(points))


def torus(major: float = 0.25, minor: float = 0.08, segments: int = 64, sides: int = 24) -> Mesh:
    """A closed torus of triangles about the y axis, centred on the origin: the
    circle of radius ``major`` [m] in the y=0 plane is its centre-line, and the
    tube around it has radius ``minor`` [m]. ``segments`` vertices along the
    centre-line times ``sides`` around the tube, every vertex on the exact
    surface; each quad of that grid is split along the same diagonal into two
    triangles, 2 ``segments`` ``sides`` in all, every one wound
    counter-clockwise seen from outside (its normal points away from the
    centre-line). No vertex is repeated (the grid wraps round both ways), so
    every edge is in exactly two triangles: a solid. UVs: the two angles
    scaled to [0, 1)."""
    if not 0 < minor < major:
        raise ValueError(f"expected 0 < minor < major, got minor={minor}, major={major}")
    a = 2 * np.pi * np.arange(segments) / segments  # along the centre-line
    b = 2 * np.pi * np.arange(sides) / sides  # around the tube, from the outer equator up
    aa, bb = np.meshgrid(a, b, indexing="ij")
    ring = major + minor * np.cos(bb)
    vertices = np.stack([ring * np.cos(aa), minor * np.sin(bb), -ring * np.sin(aa)], axis=-1).reshape(-1, 3)
    i = np.arange(segments)[:, None]
    j = np.arange(sides)[None, :]
    p00 = (i * sides + j).ravel()
    p10 = (((i + 1) % segments) * sides + j).ravel()
    p01 = (i * sides + (j + 1) % sides).ravel()
    p11 = (((i + 1) % segments) * sides + (j + 1) % sides).ravel()
    faces = np.concatenate([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)]).astype(np.int64)
    # outward: each face's normal against the direction from the centre-line to its centroid
    centroid = vertices[faces].mean(axis=1)
    foot = centroid * [1.0, 0.0, 1.0]
    foot *= major / np.linalg.norm(foot, axis=1)[:, None]
    flip = np.einsum("ij,ij->i", face_normals(vertices, faces), centroid - foot) < 0
    faces[flip] = faces[flip, ::-1]
    uvs = np.stack([aa / (2 * np.pi), bb / (2 * np.pi)], axis=-1).reshape(-1, 2)
    mesh = Mesh(vertices, faces, uvs, f"torus(major={major:g}, minor={minor:g}, segments={segments}, sides={sides})")
    return reorder(mesh, np.arange(len(vertices)))


# ---------------------------------------------------------------- OBJ files


def _num(x: float) -> str:
    """A coordinate to 6 decimals (µm for metres), no trailing zeros, no '-0'."""
    text = np.format_float_positional(round(float(x), 6), precision=6, trim="-")
    return "0" if text in ("-0", "0") else text


def obj_text(mesh: Mesh) -> str:
    """The OBJ text of ``mesh``: a comment, ``v`` and ``vt`` lines (vertex k's
    uv is texture vertex k) and ``f`` lines, quads as 4-vertex faces."""
    lines = [f"# clothsim.procedural: {mesh.comment}" if mesh.comment else "# clothsim.procedural",
             f"# {len(mesh.vertices)} vertices, {len(mesh.faces)} faces"]
    lines += ["v " + " ".join(_num(c) for c in p) for p in mesh.vertices]
    lines += ["vt " + " ".join(_num(c) for c in t) for t in mesh.uvs]
    lines += ["f " + " ".join(f"{k + 1}/{k + 1}" for k in f) for f in mesh.faces.tolist()]
    return "\n".join(lines) + "\n"


def write_obj(path: str | Path, mesh: Mesh) -> Path:
    """Write ``mesh`` as an OBJ file (``\\n`` line ends, UTF-8) and return its path."""
    path = Path(path)
    path.write_bytes(obj_text(mesh).encode("utf-8"))
    return path


STANDARD_MESHES = {
    "disc.obj": lambda: disc(radius=0.7, rings=25),
    "flag.obj": lambda: quad_grid(columns=40, rows=20, width=1.0, height=0.5, vertical=True, jitter=0.001, seed=1),
    "sheet.obj": lambda: quad_grid(columns=32, rows=32, width=0.8, height=0.8, vertical=False),
    "delaunay_square.obj": lambda: delaunay_square(count=2500, side=1.0, spacing=0.014, seed=20),
    "torus.obj": lambda: torus(major=0.25, minor=0.08, segments=64, sides=24),
}
"""the meshes the standard scenes use (cloths, and the torus a collider), by file name, and how each is made"""


def meshes_dir() -> Path:
    """The packaged meshes' folder (``clothsim/scenes/meshes``)."""
    return Path(__file__).resolve().parent / "scenes" / "meshes"


def write_standard_meshes(folder: str | Path | None = None) -> list[Path]:
    """Write every mesh of :data:`STANDARD_MESHES` into ``folder`` (the
    packaged one by default, created if missing); returns the paths."""
    folder = Path(folder) if folder is not None else meshes_dir()
    folder.mkdir(parents=True, exist_ok=True)
    return [write_obj(folder / name, make()) for name, make in STANDARD_MESHES.items()]


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) > 1 or args and args[0].startswith("-"):
        print("usage: python -m clothsim.procedural [folder]   (default: the packaged meshes)", file=sys.stderr)
        return 2
    for path in write_standard_meshes(args[0] if args else None):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
