"""A small TOML writer for scene tables (the standard library reads TOML but does not write it)."""

import json
import math


def toml_value(v) -> str:
    """TOML text of one value (bool, int, float, str, list, dict as an inline table, numpy scalar); -0.0 is
    written 0.0."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write the non-finite number {v} to TOML")
        return repr(v + 0.0)  # -0.0 -> 0.0
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if hasattr(v, "item"):  # numpy scalar
        return toml_value(v.item())
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)


def _is_table_array(v) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _emit(lines, path, table):
    plain = [(k, v) for k, v in table.items() if not isinstance(v, dict) and not _is_table_array(v)]
    for k, v in plain:
        lines.append(f"{_key(k)} = {toml_value(v)}")
    for k, v in table.items():
        if isinstance(v, dict):
            name = ".".join(_key(p) for p in [*path, k])
            lines.append("")
            lines.append(f"[{name}]")
            _emit(lines, [*path, k], v)
    for k, v in table.items():
        if _is_table_array(v):
            name = ".".join(_key(p) for p in [*path, k])
            for item in v:
                lines.append("")
                lines.append(f"[[{name}]]")
                # nested tables of an array item are written inline, which keeps them attached to the item
                for kk, vv in item.items():
                    lines.append(f"{_key(kk)} = {toml_value(vv)}")


def dumps(data: dict) -> str:
    """TOML text of ``data`` (nested dicts, lists, str, int, float, bool)."""
    lines = []
    _emit(lines, [], data)
    return "\n".join(lines).lstrip("\n") + "\n"
