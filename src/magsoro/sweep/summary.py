"""The sweep's table: one row per planned run, written as CSV and Parquet, atomically, after every finished run.

Columns: index, run (directory name under runs/), one column per --param key (as given, e.g.
``fields.0.B``), status (pending, running, interrupted, completed, failed), error, wall_time_s, cpu_time_s, steps,
sim_time_s, then the final value of every probe column (metrics.csv names, m).
"""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
from pathlib import Path

from magsoro.io.files import _file_mode, atomic_write_text
from magsoro.sweep.params import format_value

FIXED = ["status", "error", "wall_time_s", "cpu_time_s", "steps", "sim_time_s"]


def columns(records: list[dict], param_keys: list[str]) -> list[str]:
    probes: list[str] = []
    for r in records:
        for k in r["probes"]:
            if k not in probes:
                probes.append(k)
    return ["index", "run", *param_keys, *FIXED, *probes]


def rows(records: list[dict], param_keys: list[str]) -> tuple[list[str], list[list]]:
    """Header and rows (Python values, None for missing) in index order."""
    cols = columns(records, param_keys)
    out = []
    for r in sorted(records, key=lambda r: r["index"]):
        flat = {"index": r["index"], "run": r["run"], **r["params"], **{k: r.get(k) for k in FIXED}, **r["probes"]}
        out.append([flat.get(c) for c in cols])
    return cols, out


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.9g}"
    if isinstance(value, (list, dict, bool)):
        return format_value(value)
    return str(value)


def write_csv(path, records: list[dict], param_keys: list[str]) -> None:
    cols, table = rows(records, param_keys)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for row in table:
        w.writerow([_cell(v) for v in row])
    atomic_write_text(path, buf.getvalue())


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def write_parquet(path, records: list[dict], param_keys: list[str]) -> bool:
    """Parquet copy of the table (needs pyarrow); numeric columns stay numeric, vectors become JSON text.
    Returns False when pyarrow is not importable."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return False
    cols, table = rows(records, param_keys)
    arrays = {}
    for j, name in enumerate(cols):
        values = [row[j] for row in table]
        present = [v for v in values if v is not None]
        if name in ("index", "steps") and all(isinstance(v, int) for v in present):
            arrays[name] = pa.array(values, type=pa.int64())
        elif present and all(_is_number(v) for v in present):
            arrays[name] = pa.array([None if v is None else float(v) for v in values], type=pa.float64())
        else:
            arrays[name] = pa.array([None if v is None else (v if isinstance(v, str) else format_value(v)) for v in values], type=pa.string())
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        pq.write_table(pa.table(arrays), tmp)
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return True


def write_summary(out_dir, records: list[dict], param_keys: list[str]) -> None:
    """summary.csv and (with pyarrow) summary.parquet in out_dir."""
    out_dir = Path(out_dir)
    write_csv(out_dir / "summary.csv", records, param_keys)
    write_parquet(out_dir / "summary.parquet", records, param_keys)


def read_summary(path) -> tuple[list[str], list[dict]]:
    """summary.csv as (columns, rows of str -> str)."""
    with Path(path).open(newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


def parse_cell(text: str):
    """Inverse of the CSV cell format: number, JSON vector/bool, or the text itself ('' -> None)."""
    if text == "":
        return None
    try:
        return json.loads(text)
    except ValueError:
        return text
