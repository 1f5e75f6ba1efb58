"""One-line messages for pydantic validation errors of magsoro's input files (rod, actuation designs, ...).

Scene files have their own formatter in :mod:`magsoro.scene.load`, which also resolves discriminated unions.
"""

from __future__ import annotations

from pydantic import BaseModel, ValidationError


def model_at(model: type[BaseModel], loc) -> type[BaseModel] | None:
    """The pydantic model that owns the last element of ``loc`` (to list the allowed keys), or None."""
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        field = model.model_fields.get(part)
        if field is None:
            return None
        ann = field.annotation
        candidates = [ann, *getattr(ann, "__args__", ())]
        for c in list(candidates):
            candidates.extend(getattr(c, "__args__", ()))
        sub = next((c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)), None)
        if sub is None:
            return None
        model = sub
    return model


def format_loc(loc) -> str:
    """``('a', 0, 'b')`` -> ``'a[0].b'``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def format_config_error(exc: ValidationError, root: type[BaseModel], source: str = "", vector_length: int | None = None) -> str:
    """One line naming each bad key, what is wrong and, for an unknown key, the allowed keys.

    ``vector_length``: when every list of numbers in the file has this length, a short list is reported as such
    rather than as a missing key.
    """
    parts = []
    for err in exc.errors():
        loc = tuple(err["loc"])
        where = format_loc(loc) or "(top level)"
        if err["type"] == "extra_forbidden":
            owner = model_at(root, loc)
            allowed = ", ".join(owner.model_fields) if owner else "?"
            parts.append(f"{where}: unknown key (allowed here: {allowed})")
        elif err["type"] == "missing" and vector_length and loc and isinstance(loc[-1], int):
            parts.append(f"{format_loc(loc[:-1])}: expected {vector_length} numbers, got fewer")
        elif err["type"] == "missing":
            parts.append(f"{where}: required key is missing")
        elif err["type"] == "value_error":
            parts.append(f"{where + ': ' if loc else ''}{err['msg'].removeprefix('Value error, ')}")
        else:
            parts.append(f"{where}: {err['msg']} (got {short_repr(err.get('input'))})")
    prefix = f"{source}: " if source else ""
    return prefix + "; ".join(parts)


MAX_NESTING = 16  # tables and arrays deeper than this in an input file are refused (no input of ours nests past 5)


def short_repr(value, limit: int = 60) -> str:
    """repr of an offending input for a message: a table or array by its kind and size (their repr can be huge,
    or too deep for Python to print), anything else cut to ``limit`` characters."""
    if isinstance(value, dict):
        return f"a table of {len(value)} key{'s' if len(value) != 1 else ''}"
    if isinstance(value, (list, tuple)):
        return f"an array of {len(value)} item{'s' if len(value) != 1 else ''}"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def nesting_error(data, limit: int = MAX_NESTING) -> str | None:
    """The key path (``a.b[2]``) where tables or arrays in ``data`` nest deeper than ``limit``, or None. Checked
    before validation: a value nested thousands deep makes the validator and the messages recurse past Python's
    limit."""
    stack = [(data, "", 0)]
    while stack:
        value, where, depth = stack.pop()
        if depth > limit:
            return where or "(top level)"
        if isinstance(value, dict):
            stack.extend((v, f"{where}.{k}" if where else str(k), depth + 1) for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            stack.extend((v, f"{where}[{i}]", depth + 1) for i, v in enumerate(value))
    return None


def check_nesting(data, source: str, error, limit: int = MAX_NESTING) -> None:
    """Raise ``error`` (one line naming the key) when ``data`` nests deeper than ``limit``."""
    where = nesting_error(data, limit)
    if where is not None:
        key = where.split("[")[0].split(".")[0] if where != "(top level)" else where
        path = where if len(where) <= 80 else where[:77] + "..."
        raise error(f"{source + ': ' if source else ''}{key}: tables or arrays nested more than {limit} deep "
                    f"(at {path})")
