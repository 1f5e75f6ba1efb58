"""Text and Markdown tables of validation rows."""

from __future__ import annotations

import json

from magsoro.validation.registry import Row

COLUMNS = ("case", "quantity", "inputs", "reference", "simulated", "error", "tolerance", "pass")


def _num(v: float) -> str:
    return f"{v:.4g}"


def _inputs(inputs: dict) -> str:
    """Compact one-line form of a row's inputs: keys that tell rows of one case apart."""
    keep = ("bn", "psi_deg", "dim", "formulation", "t_over_dx", "coarser_t_over_dx", "cfl", "support", "friction", "start_sites")
    items = [(k, v) for k, v in inputs.items() if k in keep] or list(inputs.items())[:2]
    out = []
    for k, v in items:
        if isinstance(v, list):
            v = "[" + ",".join(_num(x) if isinstance(x, float) else str(x) for x in v) + "]"
        elif isinstance(v, float):
            v = _num(v)
        out.append(f"{k}={v}")
    return " ".join(out)


def cells(row: Row) -> list[str]:
    return [row.case, row.quantity, _inputs(row.inputs), _num(row.reference), _num(row.value), _num(row.error),
            _num(row.tolerance), "yes" if row.passed else "NO"]


def text_table(rows: list[Row]) -> str:
    """Aligned plain-text table (what ``magsoro validate`` prints)."""
    body = [list(COLUMNS)] + [cells(r) for r in rows]
    widths = [max(len(line[i]) for line in body) for i in range(len(COLUMNS))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in body]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def markdown_table(rows: list[Row]) -> str:
    """GitHub Markdown table of the rows (docs/validation.md)."""
    head = "| " + " | ".join(COLUMNS) + " |\n|" + "---|" * len(COLUMNS) + "\n"
    return head + "\n".join("| " + " | ".join(c.replace("|", "/") for c in cells(r)) + " |" for r in rows) + "\n"


def json_rows(rows: list[Row]) -> str:
    """The list printed by ``magsoro validate --json``."""
    return json.dumps([r.as_dict() for r in rows], indent=1)
