"""The viewer window: simulation, drawing, panel and input, kept in step frame by frame."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from ..errors import ClothsimError
from ..render.renderer import DrawSettings, Renderer
from ..render.scene_view import SimulationView, default_camera
from ..render.shaders import ShaderLibrary
from ..simulation import Simulation
from . import picking

KEY_NAMES = {"esc": "ESCAPE", "space": "SPACE", "r": "R", "p": "P", "n": "N", "s": "S",
             **{str(d): f"NUMBER_{d}" for d in range(1, 10)}}


def require_display() -> None:
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ClothsimError("no display to open a window on (DISPLAY is not set); run `clothsim view` on a "
                            "desktop or under Xvfb, or render images headless with "
                            "`clothsim render SCENE -o out.png`")


class ViewerApp:
    """One window showing one Simulation; ``frame()`` advances and draws one frame."""

    def __init__(self, sim: Simulation, size: tuple[int, int] = (1280, 800), shaders: ShaderLibrary | None = None,
                 shader: str = "Phong", visible: bool = True, sphere_res: tuple[int, int] = (40, 40),
                 textures: dict | None = None, cubemap: dict | None = None) -> None:
        require_display()
        import moderngl_window as mglw
        from imgui_bundle import imgui
        from moderngl_window.integrations.imgui_bundle import ModernglWindowRenderer

        try:
            cls = mglw.get_local_window_cls("glfw")
            self.wnd = cls(title="clothsim", size=size, vsync=False, gl_version=(3, 3), resizable=True,
                           visible=visible, samples=4)
        except Exception as exc:  # GLFW reports missing displays and GL versions in its own ways
            raise ClothsimError(f"cannot open a window ({exc}); use `clothsim render SCENE -o out.png` "
                                "to render without one") from None
        mglw.activate_context(window=self.wnd)
        self.ctx = self.wnd.ctx
        imgui.create_context()
        imgui.get_io().set_ini_filename("")  # no imgui.ini left in the user's folder
        self.imgui = imgui
        self.gui = ModernglWindowRenderer(self.wnd)
        self.renderer = Renderer(ctx=self.ctx, size=self.wnd.buffer_size, shaders=shaders or ShaderLibrary(),
                                 textures=textures, cubemap=cubemap)
        self.shader_names = self.renderer.library.names()
        self.settings = DrawSettings(shader=shader)
        self.renderer.program(shader)
        self.sphere_res = sphere_res
        self.sim = sim
        self.view = SimulationView(self.renderer, sim, sphere_res)
        self.camera = default_camera(sim)
        self.paused = False
        self._step_once = False
        self._grab_anchor: np.ndarray | None = None
        self._last_frame = time.perf_counter()
        self._display_fps = 0.0
        self._sim_rate = 0.0
        self._behind = 0.0
        self.message = ""
        self.panel_items: dict[str, tuple[float, float]] = {}
        """the centre of some panel widgets as last drawn (window pixels), by
        ``CLOTH/structural|shearing|bending|ks``: where scripted clicks go"""
        self.screenshot_dir = Path.cwd()
        self._wire_events()

    # ----------------------------------------------------------- events

    def _wire_events(self) -> None:
        w = self.wnd
        w.key_event_func = self._on_key
        w.mouse_press_event_func = self._on_press
        w.mouse_release_event_func = self._on_release
        w.mouse_drag_event_func = self._on_drag
        w.mouse_position_event_func = self.gui.mouse_position_event
        w.mouse_scroll_event_func = self._on_scroll
        w.unicode_char_entered_func = self.gui.unicode_char_entered
        w.resize_func = self._on_resize
        try:
            import glfw

            glfw.set_drop_callback(w._window, lambda _win, paths: self.load(paths[0]))
        except Exception:  # drop support is a convenience, not a requirement
            pass

    @property
    def window_size(self) -> tuple[int, int]:
        return self.wnd.size

    def _gui_wants_mouse(self) -> bool:
        return bool(self.imgui.get_io().want_capture_mouse)

    def _on_key(self, key, action, modifiers) -> None:
        self.gui.key_event(key, action, modifiers)
        if action != self.wnd.keys.ACTION_PRESS or self.imgui.get_io().want_capture_keyboard:
            return
        k = self.wnd.keys
        names = {getattr(k, v): n for n, v in KEY_NAMES.items() if hasattr(k, v)}
        if key in names:
            self.press(names[key])

    def press(self, name: str) -> None:
        """Apply a key by name: esc, r, space, p, n, s, 1..9 (the same as pressing it)."""
        if name == "esc":
            self.wnd.close()
        elif name == "r":
            self.sim.reset()
        elif name == "space":
            self.camera = default_camera(self.sim)
        elif name == "p":
            self.paused = not self.paused
        elif name == "n":
            if self.paused:
                self._step_once = True
        elif name == "s":
            self.message = f"saved {self.save_screenshot()}"
        elif name.isdigit() and 1 <= int(name) <= len(self.shader_names):
            self.set_shader(self.shader_names[int(name) - 1])
        else:
            raise ClothsimError(f"--keys: unknown key {name!r}; expected one of {', '.join(KEY_NAMES)}")

    def _on_press(self, x, y, button) -> None:
        self.gui.mouse_press_event(x, y, button)
        if self._gui_wants_mouse():
            return
        mods = self.wnd.modifiers
        if button == self.wnd.mouse.left and mods.shift:
            self.grab_at((x, y))

    def _on_release(self, x, y, button) -> None:
        self.gui.mouse_release_event(x, y, button)
        if self._grab_anchor is not None:
            self.sim.release()
            self._grab_anchor = None

    def _on_drag(self, x, y, dx, dy) -> None:
        self.gui.mouse_drag_event(x, y, dx, dy)
        if self._grab_anchor is not None:
            self.drag_to((x, y))
            return
        if self._gui_wants_mouse():
            return
        states, mods = self.wnd.mouse_states, self.wnd.modifiers
        if states.right or (states.left and mods.ctrl):
            self.camera.pan(-dx / self.window_size[1], dy / self.window_size[1])
        elif states.left:
            self.camera.orbit(-dx * 0.3, dy * 0.3)

    def _on_scroll(self, x_offset, y_offset) -> None:
        self.gui.mouse_scroll_event(x_offset, y_offset)
        if not self._gui_wants_mouse():
            self.camera.zoom(0.9 ** y_offset)

    def _on_resize(self, width, height) -> None:
        self.gui.resize(width, height)

    # ----------------------------------------------------------- actions

    def _view_projection(self) -> np.ndarray:
        w, h = self.window_size
        return self.camera.view_projection(w / h)

    def grab_at(self, cursor: tuple[float, float]) -> int:
        """Grab the cloth point under the cursor (any cloth, any mesh:
        :func:`.picking.pick_point`); return its index or -1."""
        index = picking.pick_point(self.sim.positions, self.sim.model.triangles, self._view_projection(),
                                   self.window_size, cursor)
        if index >= 0 and not self.sim.model.pinned[index]:
            self._grab_anchor = self.sim.positions[index].copy()
            self.sim.grab(index, self._grab_anchor)
            return index
        return -1

    def drag_to(self, cursor: tuple[float, float]) -> None:
        """Move the grabbed point's target along the plane facing the camera."""
        facing = self.camera.position - np.asarray(self.camera.target, float)
        facing /= np.linalg.norm(facing)
        target = picking.drag_target(self._view_projection(), self.window_size, cursor, self._grab_anchor, facing)
        self.sim.grab(self.sim.grabbed, target)

    def set_shader(self, name: str) -> None:
        try:
            self.renderer.program(name)
        except ClothsimError as exc:
            self.message = str(exc)
            return
        self.settings.shader = name

    def set_sphere_res(self, res: tuple[int, int]) -> None:
        self.sphere_res = res
        self.view.set_sphere_res(res)

    def load(self, path: str) -> None:
        """Replace the scene (a dropped file); a bad file leaves the current one running."""
        try:
            sim = Simulation.from_file(path)
        except ClothsimError as exc:
            self.message = str(exc)
            return
        self.sim = sim
        self.view.attach(sim)
        self.camera = default_camera(sim)
        self.message = f"loaded {Path(path).name}"

    def save_screenshot(self, path: str | Path | None = None) -> Path:
        """The window as it was last drawn, panel included; never overwrites a file."""
        from PIL import Image

        if path is None:
            stamp = time.strftime("%Y%m%d-%H%M%S")
            path = self.screenshot_dir / f"clothsim-{stamp}.png"
            k = 1
            while path.exists():
                path = self.screenshot_dir / f"clothsim-{stamp}-{k}.png"
                k += 1
        w, h = self.wnd.fbo.size
        data = self.wnd.fbo.read(components=3, alignment=1)
        Image.fromarray(np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1]).save(path)
        return Path(path)

    # ----------------------------------------------------------- frames

    def status_lines(self) -> list[str]:
        m = self.sim.model
        cloths = f"{len(m.cloths)} cloths, " if len(m.cloths) > 1 else ""
        lines = [f"display {self._display_fps:5.1f} fps   t = {self.sim.time:6.2f} s",
                 f"{self._sim_rate:,.0f} substeps/s   {cloths}{m.num_points} points, {m.num_springs} springs"]
        if self.paused:
            lines.append("PAUSED  (P resume, N step)")
        if self._behind > 1.05:
            lines.append(f"behind real time: {1 / self._behind:.2f}x speed")
        if self.message:
            lines.append(self.message[:60])
        return lines

    def frame(self, realtime: bool = True) -> None:
        """Advance one simulation frame (unless paused) and draw it with the panel."""
        imgui = self.imgui
        if not self.paused or self._step_once:
            start = time.perf_counter()
            try:
                self.sim.step()
            except ClothsimError as exc:
                self.paused = True
                self.message = str(exc)
            spent = time.perf_counter() - start
            self._sim_rate = self.sim.params.simulation_steps / max(spent, 1e-9)
            self._behind = spent * self.sim.params.frames_per_sec
            self._step_once = False
        self._make_current()
        self.view.sync()
        self.wnd.use()
        self.ctx.clear(*self.settings.background, 1.0)
        w, h = self.wnd.buffer_size
        self.renderer.draw(self.camera, self.settings, aspect=w / h)
        imgui.new_frame()
        from .panel import draw_panel
        draw_panel(self)
        imgui.render()
        self.gui.render(imgui.get_draw_data())
        now = time.perf_counter()
        if realtime:  # one simulated frame per displayed frame, at frames_per_sec
            wait = 1.0 / self.sim.params.frames_per_sec - (now - self._last_frame)
            if wait > 0:
                time.sleep(wait)
                now = time.perf_counter()
        self._display_fps = 0.9 * self._display_fps + 0.1 / max(now - self._last_frame, 1e-6)
        self._last_frame = now

    def _make_current(self) -> None:
        """Offscreen (EGL) renderers in the same thread may have taken the GL binding."""
        try:
            import glfw

            glfw.make_context_current(self.wnd._window)
        except Exception:
            pass

    def swap(self) -> None:
        self.wnd.swap_buffers()

    def run(self) -> None:
        while not self.wnd.is_closing:
            self.frame()
            self.swap()
        self.close()

    def run_script(self, frames: int, keys: list[str], screenshot: str | None) -> None:
        """Scripted mode: key i is pressed before frame i+1; the last frame is saved."""
        for i in range(frames):
            if i < len(keys):
                self.press(keys[i])
            self.frame(realtime=False)
            if i == frames - 1 and screenshot:
                self.save_screenshot(screenshot)
            self.swap()

    def close(self) -> None:
        self.wnd.destroy()
