"""The Dear ImGui panel: every live parameter, and the status line."""

from __future__ import annotations

from typing import TYPE_CHECKING

from imgui_bundle import imgui

if TYPE_CHECKING:
    from .app import ViewerApp

PANEL_WIDTH = 370


def _slider(label: str, value: float, lo: float, hi: float, fmt: str = "%.3g", log: bool = False) -> tuple[bool, float]:
    flags = imgui.SliderFlags_.logarithmic.value if log else 0
    return imgui.slider_float(label, float(value), lo, hi, fmt, flags)


def draw_panel(app: ViewerApp) -> None:
    sim, p, s = app.sim, app.sim.params, app.settings
    imgui.set_next_window_pos((8, 8), imgui.Cond_.first_use_ever.value)
    imgui.set_next_window_size((PANEL_WIDTH, app.window_size[1] - 16), imgui.Cond_.first_use_ever.value)
    imgui.begin("clothsim")

    if imgui.collapsing_header("Springs", imgui.TreeNodeFlags_.default_open.value):
        _, p.enable_structural = imgui.checkbox("structural", p.enable_structural)
        imgui.same_line()
        _, p.enable_shearing = imgui.checkbox("shearing", p.enable_shearing)
        imgui.same_line()
        _, p.enable_bending = imgui.checkbox("bending", p.enable_bending)
        _, p.ks = _slider("ks [N/m]", p.ks, 1.0, 100000.0, "%.0f", log=True)
        _, p.density = _slider("density", p.density, 1.0, 100000.0, "%.0f", log=True)
        _, p.damping = _slider("damping [%]", p.damping, 0.0, 100.0, "%.2f")

    if imgui.collapsing_header("Simulation", imgui.TreeNodeFlags_.default_open.value):
        _, fps = imgui.slider_int("frames/s", int(p.frames_per_sec), 10, 240)
        p.frames_per_sec = float(fps)
        _, p.simulation_steps = imgui.slider_int("steps/frame", int(p.simulation_steps), 1, 200)
        _, g = imgui.slider_float3("gravity", list(p.gravity), -20.0, 20.0)
        p.gravity = tuple(g)
        _, p.self_collision = imgui.checkbox("self-collision", p.self_collision)
        for k, sphere in enumerate(sim.spheres):
            _, sphere.friction = _slider(f"sphere {k} friction", sphere.friction, 0.0, 1.0, "%.2f")
        for k, plane in enumerate(sim.planes):
            _, plane.friction = _slider(f"plane {k} friction", plane.friction, 0.0, 1.0, "%.2f")

    if imgui.collapsing_header("Appearance", imgui.TreeNodeFlags_.default_open.value):
        names = app.shader_names
        current = names.index(s.shader) if s.shader in names else 0
        changed, current = imgui.combo("shader", current, names)
        if changed:
            app.set_shader(names[current])
        _, color = imgui.color_edit3("cloth colour", list(s.color))
        s.color = tuple(color)
        _, s.normal_scaling = _slider("normal scaling", s.normal_scaling, 0.0, 200.0, "%.1f")
        _, s.height_scaling = _slider("height scaling", s.height_scaling, 0.0, 0.1, "%.3f")
        _, s.ka = _slider("ambient ka", s.ka, 0.0, 1.0, "%.2f")
        _, s.kd = _slider("diffuse kd", s.kd, 0.0, 2.0, "%.2f")
        _, s.ks = _slider("specular ks", s.ks, 0.0, 2.0, "%.2f")
        _, s.p = _slider("shininess p", s.p, 1.0, 500.0, "%.0f", log=True)
        _, light = imgui.slider_float3("light", list(s.light.position), -5.0, 5.0)
        s.light.position = tuple(light)
        changed, res = imgui.slider_int2("sphere lat/lon", list(app.sphere_res), 2, 128)
        if changed:
            app.set_sphere_res((max(2, res[0]), max(3, res[1])))

    imgui.separator()
    for line in app.status_lines():
        imgui.text(line)
    imgui.end()
