"""clothsim: a mass-spring cloth simulator with GLSL rendering."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("clothsim")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+src"

from .errors import ClothsimError, RenderError, SceneError, SceneWarning, SimulationError
from .scene import Scene, load_scene, parse_scene

_LAZY = {"Params": "simulation", "Simulation": "simulation", "Trajectory": "trajectory", "record": "trajectory"}
"""names imported on first use: the simulation pulls in numba and the kernels,
which ``clothsim --help`` and ``--version`` must not wait for"""


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module

        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ClothsimError", "RenderError", "Params", "Scene", "SceneError", "SceneWarning", "Simulation",
           "SimulationError", "Trajectory", "load_scene", "parse_scene", "record", "__version__"]
