"""magsoro: simulator for magnetic soft robots.

The public scripting API lives here; see README.md and docs/ for the tour.
"""

from magsoro._version import __version__
from magsoro.constants import MU0
from magsoro.errors import MagsoroError, SceneError, SimulationError

__all__ = ["MU0", "MagsoroError", "SceneError", "SimulationError", "__version__"]


def __getattr__(name):
    # Heavy modules (Warp) load only when the API is used, so `import magsoro` stays cheap.
    if name in ("Simulation", "load_scene", "Scene"):
        from magsoro import simulation, scene

        return {"Simulation": simulation.Simulation, "load_scene": scene.load_scene, "Scene": scene.Scene}[name]
    raise AttributeError(f"module 'magsoro' has no attribute {name!r}")
