"""clothsim: a mass-spring cloth simulator with GLSL rendering."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("clothsim")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+src"

from .errors import ClothsimError, RenderError, SceneError, SimulationError
from .scene import Scene, load_scene, parse_scene
from .simulation import Params, Simulation

__all__ = ["ClothsimError", "RenderError", "Params", "Scene", "SceneError", "Simulation",
           "SimulationError", "load_scene", "parse_scene", "__version__"]
