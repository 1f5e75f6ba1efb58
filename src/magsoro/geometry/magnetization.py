"""Magnetisation profiles: the reference-frame remanence Br (T) of each particle from its reference position (m).

A profile is a function ``positions (N, 3) -> Br (N, 3)``. Besides a constant vector, this module provides the
profiles that published robots use: a direction rotating along an axis (the sinusoidal profile of Hu et al.'s
walker, seed 000 sec 4.5), a piecewise table along an axis (segment-wise vectors of Pittiglio et al.'s
tentacles, seed 000 sec 4.5), values sampled at points in an array file, and a small arithmetic expression in
x, y, z evaluated safely (parsed with ``ast``; only numbers, x, y, z, pi, e, arithmetic, comparisons and a fixed
list of math functions are allowed; nothing is passed to ``eval``).
"""

from __future__ import annotations

import ast
import operator
from pathlib import Path
from typing import Callable

import numpy as np

Profile = Callable[[np.ndarray], np.ndarray]


class ExpressionError(ValueError):
    """An expression uses something outside the allowed arithmetic."""


_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv, ast.Pow: operator.pow, ast.Mod: operator.mod}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal}
FUNCTIONS = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
    "atan2": np.arctan2, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh, "exp": np.exp, "log": np.log,
    "log10": np.log10, "sqrt": np.sqrt, "abs": np.abs, "hypot": np.hypot, "floor": np.floor, "ceil": np.ceil,
    "sign": np.sign, "min": np.minimum, "max": np.maximum, "where": np.where,
}
CONSTANTS = {"pi": np.pi, "e": np.e}
VARIABLES = ("x", "y", "z")
MAX_EXPRESSION_LENGTH = 2000


def compile_expression(text: str):
    """Parse ``text`` and return a function f(x, y, z) -> array evaluating it with numpy.

    Raises ExpressionError naming the first construct that is not allowed.
    """
    if not isinstance(text, str) or not text.strip():
        raise ExpressionError("expression is empty")
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_EXPRESSION_LENGTH} characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"cannot parse '{text}': {exc.msg}") from None
    _check(tree.body, text)

    def evaluate(x, y, z):
        env = {"x": x, "y": y, "z": z}
        with np.errstate(all="ignore"):
            return _eval(tree.body, env)

    return evaluate


def _check(node, text):
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise ExpressionError(f"'{text}': only numbers are allowed as constants, got {node.value!r}")
    elif isinstance(node, ast.Name):
        if node.id not in VARIABLES and node.id not in CONSTANTS:
            raise ExpressionError(f"'{text}': unknown name '{node.id}'; allowed: x, y, z, pi, e and functions {', '.join(sorted(FUNCTIONS))}")
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BINOPS:
            raise ExpressionError(f"'{text}': operator {type(node.op).__name__} is not allowed")
        _check(node.left, text)
        _check(node.right, text)
    elif isinstance(node, ast.UnaryOp):
        if type(node.op) not in _UNARY:
            raise ExpressionError(f"'{text}': operator {type(node.op).__name__} is not allowed")
        _check(node.operand, text)
    elif isinstance(node, ast.Compare):
        if len(node.ops) != 1 or type(node.ops[0]) not in _COMPARE:
            raise ExpressionError(f"'{text}': only single comparisons <, <=, >, >= are allowed")
        _check(node.left, text)
        _check(node.comparators[0], text)
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            name = getattr(node.func, "id", ast.dump(node.func))
            raise ExpressionError(f"'{text}': function '{name}' is not allowed; allowed: {', '.join(sorted(FUNCTIONS))}")
        if node.keywords:
            raise ExpressionError(f"'{text}': keyword arguments are not allowed")
        for a in node.args:
            _check(a, text)
    else:
        raise ExpressionError(f"'{text}': {type(node).__name__} is not allowed (only arithmetic on x, y, z)")


def _eval(node, env):
    if isinstance(node, ast.Constant):
        return float(node.value)  # floats cannot blow up memory the way Python big integers can
    if isinstance(node, ast.Name):
        return env[node.id] if node.id in env else CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval(node.left, env), _eval(node.right, env))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_eval(node.operand, env))
    if isinstance(node, ast.Compare):
        return _COMPARE[type(node.ops[0])](_eval(node.left, env), _eval(node.comparators[0], env)).astype(np.float64)
    return FUNCTIONS[node.func.id](*[_eval(a, env) for a in node.args])


def _unit(v, what="direction"):
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = np.linalg.norm(v)
    if n == 0:
        raise ValueError(f"{what} must be non-zero")
    return v / n


def uniform(vector) -> Profile:
    """The same Br (T, 3 components) everywhere."""
    v = np.asarray(vector, dtype=np.float64).reshape(3)
    return lambda X: np.tile(v, (len(X), 1))


def rotating(magnitude: float, axis, origin, period: float, u, v, phase: float = 0.0) -> Profile:
    """Br(s) = magnitude [cos(2 pi s / period + phase) u + sin(2 pi s / period + phase) v], s = (X - origin) . axis.

    With period equal to the body length this is the single-period sinusoidal profile of Hu et al.'s walker
    (seed 000 sec 4.5). magnitude in T, origin in m, period in m, phase in rad; u, v span the plane (v is
    orthogonalised against u).
    """
    a, uu = _unit(axis, "axis"), _unit(u, "u")
    vv = np.asarray(v, dtype=np.float64) - np.dot(v, uu) * uu
    vv = _unit(vv, "v (after removing its part along u)")
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    if not period > 0:
        raise ValueError("period must be > 0")

    def f(X):
        s = (np.asarray(X, dtype=np.float64) - o) @ a
        t = 2 * np.pi * s / period + phase
        return magnitude * (np.cos(t)[:, None] * uu + np.sin(t)[:, None] * vv)

    return f


def table(axis, origin, positions, vectors, interpolation: str = "step") -> Profile:
    """Br along an axis from a table: ``positions`` s_k (m, increasing) and ``vectors`` Br_k (T).

    'step': Br = Br_k for s_k <= s < s_(k+1) (the last row holds to the end, the first before it), so a table
    of segment starts gives piecewise-constant segments. 'linear': linear interpolation, held outside.
    """
    a = _unit(axis, "axis")
    o = np.asarray(origin, dtype=np.float64).reshape(3)
    s_k = np.asarray(positions, dtype=np.float64).ravel()
    B_k = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    if len(s_k) != len(B_k) or len(s_k) == 0:
        raise ValueError("positions and vectors need the same, non-zero number of rows")
    if np.any(np.diff(s_k) <= 0):
        raise ValueError("positions must be strictly increasing")

    def f(X):
        s = (np.asarray(X, dtype=np.float64) - o) @ a
        if interpolation == "linear":
            return np.stack([np.interp(s, s_k, B_k[:, c]) for c in range(3)], axis=1)
        k = np.clip(np.searchsorted(s_k, s, side="right") - 1, 0, len(s_k) - 1)
        return B_k[k]

    return f


def expression(components) -> Profile:
    """Br = (fx(x, y, z), fy(x, y, z), fz(x, y, z)) in T from three expression strings (x, y, z in m)."""
    if len(components) != 3:
        raise ExpressionError(f"needs 3 expressions (x, y, z components), got {len(components)}")
    funcs = [compile_expression(c) for c in components]

    def f(X):
        X = np.asarray(X, dtype=np.float64)
        cols = [np.broadcast_to(np.asarray(fn(X[:, 0], X[:, 1], X[:, 2]), dtype=np.float64), (len(X),)) for fn in funcs]
        return np.stack(cols, axis=1)

    return f


def from_array_file(path) -> Profile:
    """Br sampled at points: a .npy or .csv array with columns x, y, z, Brx, Bry, Brz (m, T); every particle
    takes the value of the nearest sample. A CSV may start with a header line."""
    from scipy.spatial import cKDTree

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"magnetisation file '{path}' not found")
    suffix = path.suffix.lower()
    if suffix not in (".npy", ".csv", ".txt"):
        raise ValueError(f"magnetisation file '{path}' is a '{suffix or 'no suffix'}' file; give a .csv (or .npy) "
                         f"array with columns x, y, z, Brx, Bry, Brz (m, T)")
    if suffix == ".npy":
        try:
            data = np.load(path, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise ValueError(f"magnetisation file '{path}' is not a numpy array file ({exc})") from None
    else:
        try:
            data = np.loadtxt(path, delimiter=",", ndmin=2)
        except ValueError:
            try:
                data = np.loadtxt(path, delimiter=",", ndmin=2, skiprows=1)
            except ValueError as exc:
                raise ValueError(f"magnetisation file '{path}' is not a CSV of numbers x, y, z, Brx, Bry, Brz after "
                                 f"an optional header line ({str(exc).splitlines()[0][:120]})") from None
    data = np.asarray(data, dtype=np.float64)
    if data.ndim != 2 or data.shape[1] != 6 or len(data) == 0:
        raise ValueError(f"magnetisation file '{path}' must have 6 columns x,y,z,Brx,Bry,Brz, got shape {data.shape}")
    if not np.all(np.isfinite(data)):
        raise ValueError(f"magnetisation file '{path}' holds non-finite values")
    tree = cKDTree(data[:, :3])

    def f(X):
        _, idx = tree.query(np.asarray(X, dtype=np.float64))
        return data[idx, 3:]

    return f


def evaluate(profile: Profile, positions: np.ndarray) -> np.ndarray:
    """Br (N, 3) of ``profile`` at ``positions`` (N, 2 or 3; 2D positions get z = 0), checked finite."""
    X = np.asarray(positions, dtype=np.float64)
    if X.shape[1] == 2:
        X = np.concatenate([X, np.zeros((len(X), 1))], axis=1)
    Br = np.asarray(profile(X), dtype=np.float64)
    if Br.shape != (len(X), 3):
        raise ValueError(f"a magnetisation profile must return an array of shape (N, 3), got {Br.shape}")
    if not np.all(np.isfinite(Br)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(Br), axis=1))[0])
        raise ValueError(f"magnetisation is not finite at x = {X[bad].tolist()} m")
    return Br
