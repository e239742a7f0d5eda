"""OpenGL renderer on moderngl: draws a cloth mesh and collider meshes with a shader.

It takes vertex arrays, never springs or solvers. Offscreen it makes its own
EGL context and a multisampled framebuffer; in a window it draws into
whatever framebuffer the window has bound.
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass, field

import numpy as np

from ..errors import RenderError
from . import assets
from .camera import Light, OrbitCamera
from .geometry import FLOATS_PER_VERTEX, Mesh, cloth_colors
from .shaders import ShaderLibrary

BACKGROUND = (0.11, 0.12, 0.15)
COLLIDER_COLOR = (0.78, 0.78, 0.8)
_ATTRS = (("in_position", "4f", 16), ("in_normal", "4f", 16), ("in_tangent", "4f", 16), ("in_uv", "2f", 8))


@dataclass
class DrawSettings:
    """Everything about the look of a frame that a user may change."""

    shader: str = "Phong"
    color: tuple[float, float, float] = (0.80, 0.22, 0.20)
    """cloth colour, linear RGB in [0, 1]"""
    wire_color: tuple[float, float, float] = (0.95, 0.95, 0.95)
    normal_scaling: float = 40.0
    height_scaling: float = 0.02
    """[m] of displacement at height 1 (also scales Bump)"""
    ka: float = 0.1
    kd: float = 1.0
    ks: float = 0.5
    p: float = 100.0
    light: Light = field(default_factory=Light)
    background: tuple[float, float, float] = BACKGROUND


def _current(method):
    """Run a GL method with this renderer's own context current, then release it.

    Several offscreen renderers may live in one process (tests, sweeps) and GL
    calls go to whichever context is current, so each entry point makes its
    own current. It is released afterwards, so that a window's GLX context can
    be made current on the same thread (X aborts the process otherwise).
    glcontext's exit is not re-entrant, so only the outermost call enters.
    """
    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        if not self.offscreen or self._depth:
            return method(self, *args, **kwargs)
        self._depth += 1
        try:
            with self.ctx:
                return method(self, *args, **kwargs)
        finally:
            self._depth -= 1
    return wrapper


def _drop_current_egl() -> None:
    """Leave no EGL context current on this thread.

    A released moderngl context stays current; a GLX window made current on
    the same thread afterwards then fails with BadAccess, and Xlib exits.
    """
    try:
        egl = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return
    egl.eglGetCurrentDisplay.restype = ctypes.c_void_p
    egl.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
    display = egl.eglGetCurrentDisplay()
    if display:
        egl.eglMakeCurrent(display, None, None, None)


def create_context():
    """A standalone OpenGL 3.3 context: EGL first (no display needed), then the default."""
    import moderngl

    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            return moderngl.create_standalone_context(require=330, **kwargs)
        except Exception as exc:  # each backend fails in its own way
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}")
    raise RenderError("cannot create an OpenGL 3.3 context (" + "; ".join(errors) +
                      "); on Debian install libegl1 and libgl1-mesa-dri")


class Renderer:
    def __init__(self, ctx=None, size: tuple[int, int] = (800, 800), shaders: ShaderLibrary | None = None,
                 samples: int = 4, texture: np.ndarray | None = None, height_map: np.ndarray | None = None,
                 cubemap: dict[str, np.ndarray] | None = None,
                 textures: dict[int, np.ndarray] | None = None) -> None:
        """``textures``: images of the units ``u_texture_1`` .. ``u_texture_4`` by number;
        ``texture`` and ``height_map`` are units 1 and 2 (where ``textures`` lacks them).
        A unit not given gets its built-in image: 1 a plaid, 2 and 3 weave height maps,
        4 unit 1's image."""
        self.offscreen = ctx is None
        self.ctx = ctx if ctx is not None else create_context()
        self.size = size
        self.library = shaders or ShaderLibrary()
        self._programs: dict[str, object] = {}
        self._vaos: dict[tuple[str, int, str], object] = {}
        self._cloth: Mesh | None = None
        self._cloth_vbo = None
        self._meshes: list[tuple[object, object, object, int]] = []  # vbo, tri ibo, edge ibo, id
        self._poses: list[np.ndarray] = []  # a (4, 4) model matrix per collider mesh
        self.samples = 0
        self._depth = 0
        units = {1: texture, 2: height_map, **(textures or {})}
        self._setup(size, samples, units, cubemap)

    @_current
    def _setup(self, size, samples, units, cubemap) -> None:
        if self.offscreen:
            self._make_framebuffers(size, samples)
        self._textures = self._make_textures(units, cubemap)

    # ------------------------------------------------------------ resources

    def _make_framebuffers(self, size, samples) -> None:
        ctx = self.ctx
        self.samples = min(samples, ctx.max_samples) if samples > 1 else 0
        self._fbo_ms = ctx.framebuffer(
            color_attachments=[ctx.renderbuffer(size, 4, samples=self.samples)],
            depth_attachment=ctx.depth_renderbuffer(size, samples=self.samples))
        self._fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer(size, 4)],
                                    depth_attachment=ctx.depth_renderbuffer(size))

    def _make_textures(self, units: dict[int, np.ndarray | None], cubemap) -> dict[str, object]:
        ctx = self.ctx
        color = units.get(1) if units.get(1) is not None else assets.plaid_texture()
        defaults = {1: color, 2: assets.weave_height, 3: lambda: assets.weave_height(256, 8), 4: color}
        faces = cubemap if cubemap is not None else assets.sky_environment()
        out = {}
        for unit, default in defaults.items():
            img = units.get(unit)
            if img is None:
                img = default() if callable(default) else default
            name = f"u_texture_{unit}"
            # as in CS184 (which uploads the decoded rows as they are): the image's first
            # row, its top, is GL's first row, at v = 0
            img = np.ascontiguousarray(img)
            tex = ctx.texture((img.shape[1], img.shape[0]), 3, img.tobytes())
            tex.build_mipmaps()
            tex.repeat_x = tex.repeat_y = True
            out[name] = tex
        size = faces["posx"].shape[0]
        data = b"".join(np.ascontiguousarray(faces[f]).tobytes() for f in assets.CUBE_FACES)
        cube = ctx.texture_cube((size, size), 3, data)
        import moderngl
        cube.filter = (moderngl.LINEAR, moderngl.LINEAR)
        out["u_texture_cubemap"] = cube
        return out

    @_current
    def program(self, name: str):
        if name not in self._programs:
            self._programs[name] = self.library.compile(self.ctx, name)
        return self._programs[name]

    @_current
    def set_cloth(self, mesh: Mesh) -> None:
        """Topology of the cloth, uploaded once; ``update_cloth`` streams vertices each frame."""
        self._release_vaos(0)
        self._cloth = mesh
        self._cloth_vbo = self.ctx.buffer(reserve=mesh.vertices.nbytes, dynamic=True)
        self._cloth_vbo.write(mesh.vertices.astype(np.float32, copy=False).tobytes())
        self._cloth_tris = self.ctx.buffer(mesh.triangles.astype(np.int32).tobytes())
        self.set_cloth_lines(mesh.lines if mesh.lines is not None else _edges(mesh.triangles))

    @_current
    def set_cloth_lines(self, lines: np.ndarray) -> None:
        """Segments the Wireframe shader draws (the enabled springs)."""
        self._release_vaos(0, "lines")
        data = np.ascontiguousarray(lines, dtype=np.int32)
        self._cloth_lines = self.ctx.buffer(data.tobytes() if data.size else b"\0" * 8)
        self._cloth_line_count = data.size

    @_current
    def update_cloth(self, vertices: np.ndarray) -> None:
        """One buffer write per frame: the packed (N, 14) float32 vertices."""
        self._cloth_vbo.write(vertices.astype(np.float32, copy=False).tobytes())

    @_current
    def set_colliders(self, meshes: list[Mesh]) -> None:
        """The colliders' meshes in their rest poses, uploaded once; each is drawn
        at its model matrix (``set_collider_poses``; the identity until then).
        A mesh's ``lines`` (else its triangles' edges) are its wireframe."""
        for vbo, tri, edge, ident in self._meshes:
            self._release_vaos(ident)
            for buf in (vbo, tri, edge):
                buf.release()
        self._meshes = []
        for k, m in enumerate(meshes, start=1):
            lines = m.lines if m.lines is not None else _edges(m.triangles)
            self._meshes.append((self.ctx.buffer(m.vertices.astype(np.float32).tobytes()),
                                 self.ctx.buffer(m.triangles.astype(np.int32).tobytes()),
                                 self.ctx.buffer(np.ascontiguousarray(lines, dtype=np.int32).tobytes()), k))
        self._poses = [np.eye(4)] * len(meshes)

    def set_collider_poses(self, matrices: list[np.ndarray]) -> None:
        """Where each collider is now: a (4, 4) model matrix per mesh given to
        ``set_colliders``, in its order (``x_now = M @ x_rest``); no GL call, it
        takes effect at the next draw through the shaders' ``u_model``."""
        if len(matrices) != len(self._meshes):
            raise ValueError(f"{len(matrices)} collider poses for {len(self._meshes)} colliders")
        self._poses = [np.asarray(m, dtype=np.float64) for m in matrices]

    def _release_vaos(self, ident: int, kind: str | None = None) -> None:
        for key in [k for k in self._vaos if k[1] == ident and (kind is None or k[2] == kind)]:
            self._vaos.pop(key).release()

    def _vao(self, name: str, prog, ident: int, kind: str, vbo, ibo):
        key = (name, ident, kind)
        if key not in self._vaos:
            fmt, names = [], []
            for attr, f, nbytes in _ATTRS:
                if attr in prog:
                    fmt.append(f)
                    names.append(attr)
                else:
                    fmt.append(f"{nbytes}x")
            # a program that reads no attribute (an empty main(), the course skeleton) gets a
            # vertex array without content: moderngl refuses a buffer that feeds nothing, but
            # draws an empty one, with the index buffer's count of vertices
            content = [(vbo, " ".join(fmt), *names)] if names else []
            self._vaos[key] = self.ctx.vertex_array(prog, content, ibo, index_element_size=4)
        return self._vaos[key]

    # ------------------------------------------------------------ drawing

    def _set_uniforms(self, prog, camera: OrbitCamera, s: DrawSettings, aspect: float, color) -> None:
        values = {
            "u_model": np.eye(4), "u_view_projection": camera.view_projection(aspect),
            "u_color": (*color, 1.0), "u_cam_pos": tuple(camera.position),
            "u_light_pos": tuple(s.light.position), "u_light_intensity": tuple(s.light.intensity),
            "u_normal_scaling": s.normal_scaling, "u_height_scaling": s.height_scaling,
            "u_ka": s.ka, "u_kd": s.kd, "u_ks": s.ks, "u_p": s.p,
        }
        for name, value in values.items():
            if name in prog:
                if isinstance(value, np.ndarray):
                    prog[name].write(value.T.astype("f4").tobytes())  # GLSL is column-major
                else:
                    prog[name].value = value
        for unit, (name, tex) in enumerate(self._textures.items()):
            if name in prog:
                tex.use(location=unit)
                prog[name].value = unit
            size_name = name + "_size"
            if size_name in prog:
                prog[size_name].value = tuple(float(v) for v in tex.size)

    @_current
    def draw(self, camera: OrbitCamera, settings: DrawSettings, aspect: float | None = None) -> None:
        """Draw the cloth and colliders into the bound framebuffer."""
        import moderngl

        ctx = self.ctx
        aspect = aspect or self.size[0] / self.size[1]
        prog = self.program(settings.shader)
        wire = settings.shader == "Wireframe"
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        if self._cloth is not None:
            self._set_uniforms(prog, camera, settings, aspect, settings.wire_color if wire else settings.color)
            if wire:
                if self._cloth_line_count:
                    self._vao(settings.shader, prog, 0, "lines", self._cloth_vbo, self._cloth_lines).render(
                        moderngl.LINES, vertices=self._cloth_line_count)
            else:
                vao = self._vao(settings.shader, prog, 0, "tris", self._cloth_vbo, self._cloth_tris)
                parts = self._cloth.parts
                if len(parts) <= 1:
                    vao.render(moderngl.TRIANGLES)
                else:  # several cloths, each in its own colour
                    for (first, count), color in zip(parts, cloth_colors(settings.color, len(parts))):
                        if "u_color" in prog:
                            prog["u_color"].value = (*color, 1.0)
                        vao.render(moderngl.TRIANGLES, vertices=3 * count, first=3 * first)
        if self._meshes:
            self._set_uniforms(prog, camera, settings, aspect, settings.wire_color if wire else COLLIDER_COLOR)
            for (vbo, tri, edge, ident), pose in zip(self._meshes, self._poses):
                if "u_model" in prog:
                    prog["u_model"].write(pose.T.astype("f4").tobytes())  # GLSL is column-major
                if wire:
                    self._vao(settings.shader, prog, ident, "edges", vbo, edge).render(moderngl.LINES)
                else:
                    self._vao(settings.shader, prog, ident, "tris", vbo, tri).render(moderngl.TRIANGLES)

    @_current
    def render(self, camera: OrbitCamera, settings: DrawSettings) -> np.ndarray:
        """Offscreen image, uint8 (H, W, 3), row 0 at the top."""
        if not self.offscreen:
            raise RenderError("render() needs an offscreen renderer; in a window call draw()")
        self._fbo_ms.use()
        self.ctx.clear(*settings.background, 1.0)
        self.draw(camera, settings)
        self.ctx.copy_framebuffer(self._fbo, self._fbo_ms)
        w, h = self.size
        data = self._fbo.read(components=3, alignment=1)
        return np.frombuffer(data, dtype=np.uint8).reshape(h, w, 3)[::-1].copy()

    def release(self) -> None:
        if self.offscreen:
            self.ctx.__enter__()  # no exit: release() destroys the context it would restore
            self.ctx.release()  # takes every object of the context with it
            _drop_current_egl()
        else:
            for vao in self._vaos.values():
                vao.release()
        self._vaos.clear()


def _edges(triangles: np.ndarray) -> np.ndarray:
    """Unique undirected edges of a triangle list, int32 (E, 2)."""
    t = np.asarray(triangles)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e.sort(axis=1)
    return np.unique(e, axis=0).astype(np.int32)


__all__ = ["DrawSettings", "Renderer", "create_context", "FLOATS_PER_VERTEX"]
