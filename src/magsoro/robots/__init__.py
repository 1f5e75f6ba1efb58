"""The robot library: every robot of the source documents as a scene (``scenes/<name>.toml``) plus a
``reproduce`` function that draws the quantity the paper plots (docs/robots.md).

>>> from magsoro.robots import ROBOTS, reproduce         # doctest: +SKIP
>>> res = reproduce("pentahedron", out="runs/pentahedron", preview=True)   # doctest: +SKIP

Robot modules in this package register themselves by defining ``ROBOT`` (a :class:`Robot`); they are found by
name, so adding a robot is adding a module and its scene.
"""

from __future__ import annotations

import importlib
import pkgutil
import time
from pathlib import Path

from magsoro.robots.base import Context, ReproduceResult, Robot, RobotError, scene_notes, scenes_dir

_NOT_ROBOTS = {"base", "cli", "gallery"}


def _discover() -> dict[str, Robot]:
    found = []
    for info in pkgutil.iter_modules(__path__):
        if info.name in _NOT_ROBOTS or info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        robot = getattr(mod, "ROBOT", None)
        if isinstance(robot, Robot):
            found.append(robot)
    # seed order (000, 001, 002), then name
    found.sort(key=lambda r: (r.source.split()[1] if r.source.startswith("seed ") else r.source, r.name))
    return {r.name: r for r in found}


ROBOTS: dict[str, Robot] = _discover()


def get(name: str) -> Robot:
    """The registry entry of ``name``; an unknown name raises RobotError listing the known ones."""
    if name not in ROBOTS:
        raise RobotError(f"unknown robot {name!r}; known: {', '.join(ROBOTS)}")
    return ROBOTS[name]


def reproduce(name: str, out=None, preview: bool = False, device: str | None = None, log=None,
              workers: int = 1) -> ReproduceResult:
    """Run robot ``name`` and write its curve (CSV, PNG) and animation into ``out``
    (default runs/reproduce/<name>, or runs/reproduce/<name>-preview). ``workers``: processes the robot's
    independent simulations may run in at once (:func:`magsoro.robots.base.run_jobs`; 1: one after the other)."""
    robot = get(name)
    out = Path(out) if out is not None else Path("runs") / "reproduce" / (name + ("-preview" if preview else ""))
    out.mkdir(parents=True, exist_ok=True)
    ctx = Context(out=out, preview=preview, device=device, workers=max(1, int(workers)))
    if log is not None:
        ctx.log = log
    from magsoro.bench.runner import provenance

    made = provenance()  # the commit whose code runs: taken before a long run during which HEAD may move on
    t0 = time.perf_counter()
    scene_notes()  # forget earlier reproductions' runs
    res = robot.reproduce(ctx)
    wall = time.perf_counter() - t0
    notes = scene_notes()
    for note in notes:
        ctx.log(f"{name}: note: {note}")
    from magsoro.io.files import atomic_write_json

    atomic_write_json(out / "result.json", {
        "name": name, "title": robot.title, "source": robot.source, "quantity": robot.quantity,
        "preview": bool(preview), "wall_s": round(wall, 1), "run": made, "summary": res.summary,
        "files": {"csv": res.csv.name, "png": res.png.name, "animation": res.animation.name if res.animation else None,
                  "figures": [{"csv": Path(f["csv"]).name, "png": Path(f["png"]).name, "caption": f["caption"]}
                              for f in res.figures]},
        "info": res.info | {"workers": ctx.workers}, "checks": [r.as_dict() for r in res.rows], "passed": res.passed, "notes": notes,
    })
    return res


__all__ = ["ROBOTS", "Robot", "Context", "ReproduceResult", "RobotError", "get", "reproduce", "scenes_dir"]
