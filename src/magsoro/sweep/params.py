"""Sweep parameters: the ``--param KEY=VALUES`` grammar and dotted scene paths.

Grammar of VALUES (documented in docs/sweeps.md)::

    VALUES  := RANGE | LIST
    RANGE   := NUMBER ":" NUMBER ":" COUNT        # linspace(a, b, COUNT), both ends included
    LIST    := ITEM ("," ITEM)*                   # commas inside [...] or "..." do not split
    ITEM    := JSON value (number, true/false, null, "string", [vector], {table})
             | bare word (anything else, taken as a string, surrounding spaces dropped)

so ``0:0.05:11``, ``1e5,2e5,4e5``, ``ecoflex-00-30,dragon-skin-10`` and ``[0,0.01,0],[0,0.02,0]`` all work.

KEY is a dotted path into the scene as read from TOML. A part that names a list (``bodies``, ``fields``,
``probes``, ``colliders``, ``clamps``, ``robot.parts``) is followed by the ``name`` of an entry or by its
0-based index: ``bodies.beam.material.shear_modulus``, ``fields.0.B``. Names are matched generically (any
list entry whose ``name`` equals the part), so field tables become addressable by name as soon as they carry one.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import re
from dataclasses import dataclass, field

from magsoro.errors import MagsoroError


class SweepError(MagsoroError):
    """A sweep specification is invalid (bad --param, bad path, scene invalid for some run)."""


#: runs a sweep may plan without --allow-large: more is usually a range count typed one digit too long
MAX_RUNS = 1000
#: runs a sweep may plan at all: each holds its scene while the plan is validated (about 10 kB each)
HARD_MAX_RUNS = 100_000


@dataclass
class Param:
    """One ``--param``: the scene path, the values to take and the text as the user wrote it."""

    key: str
    values: list
    text: str = ""

    @property
    def parts(self) -> list[str]:
        """The dotted scene path split at its dots (``fields.0.B`` -> ``['fields', '0', 'B']``)."""
        return self.key.split(".")


_RANGE = re.compile(r'^\s*([^:,\[\]{}"]+):([^:,\[\]{}"]+):([^:,\[\]{}"]+)\s*$')  # no quotes: "a:b:c" is a string


def _number(text: str, what: str, spec: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise SweepError(f"--param {spec}: {what} '{text.strip()}' is not a number") from None
    if not math.isfinite(value):
        raise SweepError(f"--param {spec}: {what} must be finite, got '{text.strip()}'")
    return value


def split_items(text: str, spec: str) -> list[str]:
    """Split at top-level commas: commas inside brackets, braces or double quotes belong to the item."""
    items, depth, quoted, start = [], 0, False, 0
    for i, ch in enumerate(text):
        if quoted:
            if ch == '"' and text[i - 1] != "\\":
                quoted = False
        elif ch == '"':
            quoted = True
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
            if depth < 0:
                raise SweepError(f"--param {spec}: unbalanced '{ch}' at character {i + 1} of the values")
        elif ch == "," and depth == 0:
            items.append(text[start:i])
            start = i + 1
    if quoted or depth:
        raise SweepError(f"--param {spec}: unclosed {'quote' if quoted else 'bracket'} in the values")
    items.append(text[start:])
    return items


def parse_item(item: str, spec: str, flag: str = "--param"):
    """One list item: a JSON value when it parses as one, otherwise the bare word as a string (``flag``: the
    option named in errors)."""
    s = item.strip()
    if not s:
        raise SweepError(f"{flag} {spec}: empty value in the list (two commas in a row or a trailing comma?)")
    try:
        value = json.loads(s)
    except json.JSONDecodeError:
        if s[0] in "[{\"":
            raise SweepError(f"{flag} {spec}: '{s}' looks like JSON but does not parse") from None
        # Python-style floats JSON refuses ('1.', '.5', '+3', 'inf') are meant as numbers, not words
        try:
            value = float(s)
        except ValueError:
            return s
    if isinstance(value, float) and not math.isfinite(value):
        raise SweepError(f"{flag} {spec}: value '{s}' must be finite")
    return value


def parse_param(spec: str) -> Param:
    """Parse ``KEY=VALUES`` (see the module docstring for the grammar)."""
    if "=" not in spec:
        raise SweepError(f"--param {spec}: expected KEY=VALUES, e.g. fields.0.B=[0,0.01,0],[0,0.02,0]")
    key, text = spec.split("=", 1)
    key = key.strip()
    if not key or any(not p for p in key.split(".")):
        raise SweepError(f"--param {spec}: the key must be a dotted scene path such as bodies.beam.material.shear_modulus")
    m = _RANGE.match(text)
    if m:
        a = _number(m.group(1), "range start", spec)
        b = _number(m.group(2), "range end", spec)
        n = _number(m.group(3), "range count", spec)
        if n != int(n) or n < 1:
            raise SweepError(f"--param {spec}: range count must be a whole number >= 1, got '{m.group(3).strip()}'")
        if n > HARD_MAX_RUNS:
            raise SweepError(f"--param {spec}: range count {n:.0f} is more than the {HARD_MAX_RUNS} runs a sweep may have")
        n = int(n)
        values = [a] if n == 1 else [a + (b - a) * k / (n - 1) for k in range(n)]
        # land exactly on the end the user typed, not on a + (b - a) with round-off
        values[-1] = b if n > 1 else a
        return Param(key, values, spec)
    values = [parse_item(s, spec) for s in split_items(text, spec)]
    return Param(key, values, spec)


def _describe(container) -> str:
    if isinstance(container, list):
        names = [e.get("name") for e in container if isinstance(e, dict) and isinstance(e.get("name"), str)]
        idx = f"indices 0..{len(container) - 1}" if container else "no entries"
        return f"{idx}" + (f", names {', '.join(names)}" if names else "")
    if isinstance(container, dict):
        return "keys " + ", ".join(sorted(container)) if container else "no keys"
    return f"a {type(container).__name__}"


def set_path(data: dict, key: str, value, spec: str = "", flag: str = "--param") -> None:
    """Set ``value`` at dotted ``key`` in the scene dict ``data`` (in place); errors name ``flag`` and ``spec``.

    Intermediate parts must exist (a typo should fail here, not create a new table); the last part may be a
    new key of a table, so an optional scene key can be switched on by a sweep (parse_scene then refuses keys
    the schema does not know, naming the allowed ones).
    """
    spec = spec or f"{key}=..."
    parts = key.split(".")
    node = data
    walked = []
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        where = ".".join(walked) or "the scene"
        if isinstance(node, list):
            matches = [j for j, e in enumerate(node) if isinstance(e, dict) and e.get("name") == part]
            if len(matches) > 1:
                raise SweepError(f"{flag} {spec}: '{part}' names {len(matches)} entries of {where}; use an index")
            if matches:
                index = matches[0]
            elif re.fullmatch(r"-?\d+", part):
                index = int(part)
                if not -len(node) <= index < len(node):
                    raise SweepError(f"{flag} {spec}: {where} has no entry {part} ({_describe(node)})")
            else:
                raise SweepError(f"{flag} {spec}: {where} has no entry named '{part}' ({_describe(node)})")
            if last:
                node[index] = copy.deepcopy(value)
                return
            node = node[index]
        elif isinstance(node, dict):
            if last:
                node[part] = copy.deepcopy(value)
                return
            if part not in node:
                raise SweepError(f"{flag} {spec}: {where} has no key '{part}' ({_describe(node)})")
            node = node[part]
        else:
            raise SweepError(f"{flag} {spec}: {where} is {_describe(node)} = {node!r}, it has no '{part}' inside")
        walked.append(part)


def get_path(data: dict, key: str):
    """Value at dotted ``key`` (same addressing as :func:`set_path`); KeyError when absent."""
    node = data
    for part in key.split("."):
        if isinstance(node, list):
            matches = [e for e in node if isinstance(e, dict) and e.get("name") == part]
            if matches:
                node = matches[0]
            else:
                try:
                    node = node[int(part)]
                except (ValueError, IndexError):
                    raise KeyError(key) from None
        elif isinstance(node, dict):
            node = node[part]
        else:
            raise KeyError(key)
    return node


def format_value(value) -> str:
    """Compact text of a parameter value, as written in summaries and run directory names."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (int, str)):
        return str(value)
    return json.dumps(value, separators=(",", ":"))


def slug(params: dict, limit: int = 60) -> str:
    """Short, filesystem-safe summary of a run's parameters: last path part = value, joined by '_'."""
    pieces = []
    for key, value in params.items():
        text = format_value(value)
        text = re.sub(r"[^A-Za-z0-9.+-]+", "-", text).strip("-") or "x"
        pieces.append(f"{key.split('.')[-1]}={text}")
    s = "_".join(pieces)
    return s[:limit].rstrip("-_=") or "run"


@dataclass
class RunSpec:
    """One run of a sweep: its index, parameters, directory name and full scene dict."""

    index: int
    params: dict
    name: str
    scene: dict = field(repr=False)


def run_count(params: list[Param], zipped: bool = False) -> int:
    """How many runs :func:`combine` makes, without making them."""
    if zipped:
        return max((len(p.values) for p in params), default=0)
    return math.prod(len(p.values) for p in params)


def check_run_count(params: list[Param], zipped: bool = False, allow_large: bool = False) -> int:
    """The number of runs, refused (SweepError naming the --param values) above MAX_RUNS unless ``allow_large``
    and above HARD_MAX_RUNS in any case; checked before a single run is made."""
    n = run_count(params, zipped)
    limit = HARD_MAX_RUNS if allow_large else MAX_RUNS
    if n > limit:
        sizes = " x ".join(f"{len(p.values)} ({p.key})" for p in params)
        how = "" if allow_large else f"; add --allow-large for up to {HARD_MAX_RUNS}"
        raise SweepError(f"--param: {sizes} make {n:,} runs, more than {limit:,}: fewer values, or --zip{how}")
    return n


def combine(params: list[Param], zipped: bool = False) -> list[dict]:
    """Parameter dicts of every run: the cartesian product (last --param varies fastest) or, with ``zipped``,
    the i-th value of every --param together (all lists must then have the same length)."""
    if not params:
        raise SweepError("give at least one --param KEY=VALUES")
    keys = [p.key for p in params]
    dup = {k for k in keys if keys.count(k) > 1}
    if dup:
        raise SweepError(f"--param {sorted(dup)[0]}: given more than once")
    if zipped:
        lengths = {p.text or p.key: len(p.values) for p in params}
        if len(set(lengths.values())) > 1:
            detail = ", ".join(f"{k.split('=')[0]}: {n}" for k, n in lengths.items())
            raise SweepError(f"--zip needs the same number of values in every --param ({detail})")
        rows = zip(*(p.values for p in params))
    else:
        rows = itertools.product(*(p.values for p in params))
    return [dict(zip(keys, row)) for row in rows]
