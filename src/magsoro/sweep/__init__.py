"""Parameter sweeps over scene keys, run on dask.distributed (docs/sweeps.md).

>>> from magsoro.sweep import make_plan, run_sweep                          # doctest: +SKIP
>>> plan = make_plan("scenes/cantilever_2d.toml", ["fields.0.B=[0,0.002,0],[0,0.004,0]"])  # doctest: +SKIP
>>> result = run_sweep(plan, "sweeps/b", workers=2)                          # doctest: +SKIP
"""

from magsoro.sweep.params import Param, RunSpec, SweepError, parse_param, set_path
from magsoro.sweep.plan import SweepPlan, make_plan
from magsoro.sweep.runner import Progress, SweepResult, run_sweep

__all__ = ["Param", "RunSpec", "SweepError", "parse_param", "set_path", "SweepPlan", "make_plan", "Progress", "SweepResult", "run_sweep"]
