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
            parts.append(f"{where}: {err['msg']} (got {err.get('input')!r})")
    prefix = f"{source}: " if source else ""
    return prefix + "; ".join(parts)
