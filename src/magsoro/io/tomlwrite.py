"""A small TOML writer (the standard library reads TOML but does not write it): scene files
(:func:`magsoro.scene.write_scene`), designs written by the optimiser, calibrations.

Floats are written with ``repr``, so they read back bit-identical; tables become ``[a.b]`` headers and lists of
tables ``[[a.b]]`` headers, at any depth (a table inside an item of a list of tables is written as
``[list.key]`` after the item's own keys, which TOML attaches to that item)."""

from __future__ import annotations

import json
import math
import re

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
_INT64 = (-(2**63), 2**63 - 1)


def toml_value(v, signed_zero: bool = True) -> str:
    """TOML text of one value (bool, int, float, str, list, dict as an inline table, numpy scalar).
    ``signed_zero=False`` writes -0.0 as 0.0 (tidier text where the sign of a zero means nothing)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        if not _INT64[0] <= v <= _INT64[1]:
            raise ValueError(f"the integer {v} does not fit TOML's 64 bits")
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write the non-finite number {v} to TOML")
        return repr(v if signed_zero else v + 0.0)  # v + 0.0: -0.0 -> 0.0
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(x, signed_zero)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x, signed_zero) for x in v) + "]"
    if hasattr(v, "item") and getattr(v, "ndim", 0) == 0:  # numpy scalar
        return toml_value(v.item(), signed_zero)
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def toml_string(s: str) -> str:
    """A TOML basic string: JSON's escapes are TOML's, except that TOML also wants DEL escaped and has no surrogate
    pairs (so characters beyond the BMP are written as themselves, in UTF-8)."""
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")


def toml_key(k: str) -> str:
    """A key, bare where TOML allows it (ASCII letters, digits, '_', '-'), quoted otherwise."""
    return k if _BARE_KEY.fullmatch(k) else toml_string(k)


def _is_table_array(v) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _emit(lines: list[str], path: list[str], table: dict) -> None:
    # TOML wants a table's own keys before any sub-table header
    for k, v in table.items():
        if not isinstance(v, dict) and not _is_table_array(v):
            lines.append(f"{toml_key(k)} = {toml_value(v)}")
    for k, v in table.items():
        if isinstance(v, dict):
            lines += ["", f"[{'.'.join(toml_key(p) for p in [*path, k])}]"]
            _emit(lines, [*path, k], v)
    for k, v in table.items():
        if _is_table_array(v):
            for item in v:
                lines += ["", f"[[{'.'.join(toml_key(p) for p in [*path, k])}]]"]
                _emit(lines, [*path, k], item)


def dumps(data: dict) -> str:
    """TOML text of ``data`` (nested dicts, lists, str, int, float, bool)."""
    lines: list[str] = []
    _emit(lines, [], data)
    return "\n".join(lines).lstrip("\n") + "\n"
