"""Validation cases behind ``magsoro validate`` (docs/validation.md).

Each case compares the engine with a closed form or with the independent Kirchhoff rod (``magsoro.rod``)
and returns rows (case, quantity, inputs, reference, value, error, tolerance, passed). Cases register
themselves in :data:`CASES` when their module is imported; :func:`run_validation` runs a selection.

>>> from magsoro.validation import CASES, run_validation     # doctest: +SKIP
>>> results = run_validation(["neo_hookean"], quick=True)     # doctest: +SKIP
>>> all(r.passed for res in results for r in res.rows)       # doctest: +SKIP
"""

from __future__ import annotations

from pathlib import Path

from magsoro.validation import closed_form, collider_force, beam, contact, self_contact, hertz, hertz_bodies, everted_wall, implicit, robots  # noqa: F401, I001  (registers the cases, fast ones first)
from magsoro.validation.registry import CASES, Case, CaseResult, Context, Row, run_case


def select_cases(names=None, quick: bool = False, all_cases: bool = False) -> list[Case]:
    """Cases named in ``names`` (in that order), or the physics cases (``quick``: those marked quick), or with
    ``all_cases`` every case including the robot library's. Unknown names raise KeyError naming the known ones."""
    if names:
        unknown = [n for n in names if n not in CASES]
        if unknown:
            raise KeyError(f"unknown validation case {unknown[0]!r}; known: {', '.join(CASES)}")
        return [CASES[n] for n in names]
    if all_cases:
        return list(CASES.values())
    return [c for c in CASES.values() if c.group == "physics" and (c.quick or not quick)]


def run_validation(names=None, quick: bool = False, out=None, log=None, all_cases: bool = False) -> list[CaseResult]:
    """Run the selected cases (see :func:`select_cases`); plots go to ``out`` (a folder) when given."""
    ctx = Context(quick=quick, out=Path(out) if out is not None else None)
    if log is not None:
        ctx.log = log
    results = []
    for case in select_cases(names, quick, all_cases):
        ctx.log(f"validate: {case.name} ...")
        res = run_case(case, ctx)
        ctx.log(f"validate: {case.name}: {sum(r.passed for r in res.rows)}/{len(res.rows)} rows pass "
                f"({res.wall_s:.1f} s)")
        results.append(res)
    return results


__all__ = ["CASES", "Case", "CaseResult", "Context", "Row", "run_validation", "select_cases"]
