"""Validation rows, cases and the case registry behind ``magsoro validate``.

A *case* is a named function that runs one physical check (a closed form, or the MPM engine against the
independent Kirchhoff rod of ``magsoro.rod``) and returns :class:`Row` objects: one compared quantity each,
with its reference, the simulated value, the error and the tolerance the error must not exceed.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable


@dataclass
class Row:
    """One compared quantity.

    ``reference`` and ``value`` are in the unit the quantity name or its case documents (SI, or a ratio);
    ``error`` is the case's error measure (relative unless the case says otherwise) and ``passed`` is
    ``error <= tolerance`` with every number finite.
    """

    case: str
    quantity: str
    inputs: dict
    reference: float
    value: float
    error: float
    tolerance: float

    @property
    def passed(self) -> bool:
        nums = (self.reference, self.value, self.error, self.tolerance)
        return all(math.isfinite(float(v)) for v in nums) and float(self.error) <= float(self.tolerance)

    def as_dict(self) -> dict:
        """The JSON form printed by ``magsoro validate --json``."""
        return {
            "case": self.case,
            "quantity": self.quantity,
            "inputs": dict(self.inputs),
            "reference": float(self.reference),
            "value": float(self.value),
            "error": float(self.error),
            "tolerance": float(self.tolerance),
            "passed": bool(self.passed),
        }


def relative_error(value: float, reference: float) -> float:
    """|value - reference| / |reference| (dimensionless)."""
    return abs(float(value) - float(reference)) / abs(float(reference))


@dataclass
class Context:
    """What a case gets: ``quick`` (set by ``--quick``; a case may use it to cut its cost, the current cases run
    the same either way), ``out`` (folder for plots and data, or None for no files) and ``log`` (progress lines,
    to stderr)."""

    quick: bool = False
    out: Path | None = None
    log: Callable[[str], None] = field(default=lambda msg: print(msg, file=sys.stderr, flush=True))


@dataclass
class CaseResult:
    """Rows of one case plus what the report shows besides them: figures written (paths), run facts
    (``info``: particle counts, wall times, resolution) and the case's wall time in s."""

    case: str
    rows: list[Row]
    figures: list[Path] = field(default_factory=list)
    info: dict = field(default_factory=dict)
    wall_s: float = 0.0

    @property
    def passed(self) -> bool:
        return bool(self.rows) and all(r.passed for r in self.rows)


@dataclass
class Case:
    """A registered validation case. ``run(ctx)`` returns a :class:`CaseResult`. ``quick`` marks the cases
    ``magsoro validate --quick`` runs when no case is named; ``cost`` is a one-line wall-time estimate."""

    name: str
    summary: str
    run: Callable[[Context], CaseResult]
    quick: bool = True
    cost: str = ""
    group: str = "physics"  # "robots": run only when named or with --all


CASES: dict[str, Case] = {}


def register(name: str, summary: str, quick: bool = True, cost: str = "", group: str = "physics"):
    """Decorator adding ``fn(ctx) -> CaseResult`` to :data:`CASES` under ``name``."""

    def wrap(fn):
        if name in CASES:
            raise ValueError(f"validation case {name!r} registered twice")
        CASES[name] = Case(name, summary, fn, quick, cost, group)
        return fn

    return wrap


def run_case(case: Case, ctx: Context) -> CaseResult:
    """Run one case, timing it."""
    t0 = time.perf_counter()
    result = case.run(ctx)
    result.wall_s = time.perf_counter() - t0
    return result
