"""The Dear ImGui panel: every live parameter, and the status line.

A scene of one cloth shows its material under "Springs"; a scene of several
shows one collapsing section per cloth, named by the cloth, each with that
cloth's own toggles, ks, density and damping (``sim.cloths[i].params``).
"Simulation" has a friction slider per collider, "Wind" edits ``sim.wind``
(or adds one).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from imgui_bundle import imgui

from ..world_spec import WindSpec

if TYPE_CHECKING:
    from .app import ViewerApp

PANEL_WIDTH = 370


def _slider(label: str, value: float, lo: float, hi: float, fmt: str = "%.3g", log: bool = False) -> tuple[bool, float]:
    flags = imgui.SliderFlags_.logarithmic.value if log else 0
    return imgui.slider_float(label, float(value), lo, hi, fmt, flags)


def _remember(app: ViewerApp, key: str) -> None:
    """where the last widget was drawn (its centre, window pixels): scripted input
    and the tests click there"""
    lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
    app.panel_items[key] = ((lo.x + hi.x) / 2, (lo.y + hi.y) / 2)


def _material(app: ViewerApp, cloth) -> None:
    """the spring toggles and sliders of one cloth's live material"""
    m = cloth.params
    _, m.enable_structural = imgui.checkbox("structural", m.enable_structural)
    _remember(app, f"{cloth.name}/structural")
    imgui.same_line()
    _, m.enable_shearing = imgui.checkbox("shearing", m.enable_shearing)
    _remember(app, f"{cloth.name}/shearing")
    imgui.same_line()
    _, m.enable_bending = imgui.checkbox("bending", m.enable_bending)
    _remember(app, f"{cloth.name}/bending")
    _, m.ks = _slider("ks [N/m]", m.ks, 1.0, 100000.0, "%.0f", log=True)
    _remember(app, f"{cloth.name}/ks")
    _, m.density = _slider("density", m.density, 1.0, 100000.0, "%.0f", log=True)
    _, m.damping = _slider("damping [%]", m.damping, 0.0, 100.0, "%.2f")


def _wind(app: ViewerApp, sim) -> None:
    """``sim.wind`` edited live: velocity [m/s], turbulence, drag and lift; a
    button adds a breeze along +x where the scene has none"""
    w = sim.wind
    if w is None:
        if imgui.button("add wind"):
            sim.wind = WindSpec(velocity=(2.0, 0.0, 0.0))
        _remember(app, "wind/add")
        return
    _, v = imgui.slider_float3("velocity [m/s]", list(w.velocity), -20.0, 20.0)
    w.velocity = tuple(float(c) for c in v)
    _remember(app, "wind/velocity")
    _, w.turbulence = _slider("turbulence", w.turbulence, 0.0, 1.0, "%.2f")
    _remember(app, "wind/turbulence")
    _, w.drag = _slider("drag", w.drag, 0.0, 5.0, "%.2f")
    _remember(app, "wind/drag")
    _, w.lift = _slider("lift", w.lift, 0.0, 5.0, "%.2f")
    _remember(app, "wind/lift")


def draw_panel(app: ViewerApp) -> None:
    sim, p, s = app.sim, app.sim.params, app.settings
    app.panel_items = {}
    imgui.set_next_window_pos((8, 8), imgui.Cond_.first_use_ever.value)
    imgui.set_next_window_size((PANEL_WIDTH, app.window_size[1] - 16), imgui.Cond_.first_use_ever.value)
    imgui.begin("clothsim")

    cloths = sim.cloths
    if len(cloths) == 1:
        if imgui.collapsing_header("Springs", imgui.TreeNodeFlags_.default_open.value):
            _material(app, cloths[0])
    else:  # one section per cloth, each with its own material
        for k, cloth in enumerate(cloths):
            title = f"{cloth.name}  ({cloth.model.num_points} points)##cloth{k}"
            if imgui.collapsing_header(title, imgui.TreeNodeFlags_.default_open.value):
                imgui.push_id(f"cloth{k}")
                _material(app, cloth)
                imgui.pop_id()

    if imgui.collapsing_header("Simulation", imgui.TreeNodeFlags_.default_open.value):
        _, fps = imgui.slider_int("frames/s", int(p.frames_per_sec), 10, 240)
        p.frames_per_sec = float(fps)
        _, p.simulation_steps = imgui.slider_int("steps/frame", int(p.simulation_steps), 1, 200)
        _, g = imgui.slider_float3("gravity", list(p.gravity), -20.0, 20.0)
        p.gravity = tuple(g)
        _, p.self_collision = imgui.checkbox("self-collision", p.self_collision)
        for kind, colliders in (("sphere", sim.spheres), ("plane", sim.planes), ("box", sim.boxes),
                                ("mesh", sim.mesh_colliders)):
            for k, c in enumerate(colliders):
                _, c.friction = _slider(f"{kind} {k} friction", c.friction, 0.0, 1.0, "%.2f")
                _remember(app, f"{kind}{k}/friction")

    if imgui.collapsing_header("Wind", imgui.TreeNodeFlags_.default_open.value):
        _wind(app, sim)

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
