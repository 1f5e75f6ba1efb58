"""The robot library as validation cases (``robot-<name>``): each runs the robot's ``--preview`` reproduction
and reports its acceptance checks (docs/robots.md). Run by ``magsoro validate --all`` or by name."""

from __future__ import annotations

from magsoro.validation.registry import CaseResult, register


def _case(name: str):
    def run(ctx):
        from magsoro.robots import reproduce

        out = ctx.out / f"robot-{name}" if ctx.out is not None else None
        if out is None:
            import tempfile

            out = tempfile.mkdtemp(prefix=f"magsoro-{name}-")
        res = reproduce(name, out=out, preview=True, log=ctx.log)
        rows = list(res.rows)
        for r in rows:
            r.case = f"robot-{name}"
        figures = [p for p in (res.png, res.animation) if p is not None and ctx.out is not None]
        return CaseResult(f"robot-{name}", rows, figures=figures, info=dict(res.info, summary=res.summary))

    return run


def _register_all() -> None:
    from magsoro.robots import ROBOTS

    for name, robot in ROBOTS.items():
        register(f"robot-{name}", f"{robot.title}: {robot.quantity} (preview resolution)", quick=False,
                 cost="< 3 min", group="robots")(_case(name))


_register_all()
