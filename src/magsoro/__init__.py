"""magsoro: simulator for magnetic soft robots.

The public scripting API lives here; see README.md and docs/ for the tour.
"""

__version__ = "0.1.0"

MU0 = 1.25663706212e-6
"""Vacuum permeability, T m / A."""

from magsoro.errors import MagsoroError, SceneError, SimulationError  # noqa: E402

__all__ = ["MU0", "MagsoroError", "SceneError", "SimulationError", "__version__"]


def __getattr__(name):
    # Heavy modules (Warp) load only when the API is used, so `import magsoro` stays cheap.
    if name in ("Simulation", "load_scene", "Scene"):
        from magsoro import simulation, scene

        return {"Simulation": simulation.Simulation, "load_scene": scene.load_scene, "Scene": scene.Scene}[name]
    raise AttributeError(f"module 'magsoro' has no attribute {name!r}")
