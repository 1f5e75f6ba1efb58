"""magsoro: simulator for magnetic soft robots.

The public scripting API lives here; see README.md and docs/ for the tour.

>>> import magsoro                                                          # doctest: +SKIP
>>> sim = magsoro.Simulation.from_file("examples/tutorial/strip.toml")      # doctest: +SKIP
>>> sim.run(duration=0.05).metrics["tip_y"]                                 # doctest: +SKIP

Sweeps (``magsoro.sweep``) need the ``sweep`` extra: ``pip install 'magsoro[sweep]'``.
"""

from importlib import import_module

from magsoro._version import __version__
from magsoro.constants import MU0
from magsoro.errors import MagsoroError, OutputError, SceneError, SimulationError

# Names that load Warp (and with it the engine) on first use, so `import magsoro` stays cheap: name -> module
_LAZY = {
    "Simulation": "magsoro.simulation",
    "RunResult": "magsoro.simulation",
    "StaticRun": "magsoro.simulation",
    "RelaxResult": "magsoro.simulation",
    "prepare_static": "magsoro.simulation",
    "Scene": "magsoro.scene",
    "load_scene": "magsoro.scene",
    "parse_scene": "magsoro.scene",
}
# Subpackages reachable as attributes (magsoro.fields.CylinderMagnet) without importing them first
_SUBPACKAGES = ("fields", "materials", "rod")

__all__ = ["MU0", "MagsoroError", "OutputError", "SceneError", "SimulationError", "__version__",
           *_LAZY, *_SUBPACKAGES]


def __getattr__(name):
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
    elif name in _SUBPACKAGES:
        value = import_module(f"magsoro.{name}")
    else:
        raise AttributeError(f"module 'magsoro' has no attribute {name!r}")
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
