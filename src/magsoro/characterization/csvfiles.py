"""Reading measurement CSV files.

Both tools read plain comma-separated files with one header line; lines starting with ``#`` and blank lines are
skipped, so a file can carry its own notes. Column names are matched after stripping blanks and lower-casing.
Every value must be a finite number unless the column is declared as a label column.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from magsoro.characterization.errors import CharacterizationDataError
from magsoro.io.files import read_text_file


def read_columns(
    path: str | Path,
    required: tuple[str, ...],
    optional: tuple[str, ...] = (),
    labels: tuple[str, ...] = (),
) -> dict[str, np.ndarray]:
    """Read ``path`` and return the named columns.

    Parameters
    ----------
    path : the CSV file.
    required : columns that must be present (numeric, float64).
    optional : numeric columns returned when present.
    labels : columns (among ``required``/``optional``) kept as strings, e.g. a specimen name.

    Returns
    -------
    dict mapping each present column name to a 1D array (float64, or str for label columns).

    Raises
    ------
    CharacterizationDataError naming the file, and the column and line where a value is bad.
    """
    path = Path(path)
    text = read_text_file(path, CharacterizationDataError, "data file")
    rows = [
        (lineno, row)
        for lineno, row in enumerate(csv.reader(text.splitlines()), start=1)
        if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")
    ]
    if not rows:
        raise CharacterizationDataError(f"{path}: the file has no header line (expected columns {', '.join(required)})")
    header_line, header = rows[0]
    names = [h.strip().lower() for h in header]
    missing = [c for c in required if c not in names]
    if missing:
        raise CharacterizationDataError(
            f"{path}: missing column(s) {', '.join(repr(c) for c in missing)} in the header on line {header_line} "
            f"(found {', '.join(repr(n) for n in names)}; required {', '.join(repr(c) for c in required)})"
        )
    data_rows = rows[1:]
    if not data_rows:
        raise CharacterizationDataError(f"{path}: the file has a header but no data rows")
    out: dict[str, np.ndarray] = {}
    for col in (*required, *optional):
        if col not in names:
            continue
        k = names.index(col)
        if col in labels:
            out[col] = np.array([row[k].strip() if k < len(row) else "" for _, row in data_rows], dtype=object)
            continue
        values = np.empty(len(data_rows))
        for i, (lineno, row) in enumerate(data_rows):
            cell = row[k].strip() if k < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                raise CharacterizationDataError(
                    f"{path}: column {col!r} on line {lineno} holds {cell!r}, which is not a number"
                ) from None
            if not math.isfinite(v):
                raise CharacterizationDataError(f"{path}: column {col!r} on line {lineno} is not finite ({cell!r})")
            values[i] = v
        out[col] = values
    out["_line"] = np.array([lineno for lineno, _ in data_rows])
    return out
