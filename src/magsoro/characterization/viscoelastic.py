"""Prony (generalised Maxwell) series fitted to stress-relaxation or frequency-sweep data.

The normalised form the engine's finite-strain viscoelasticity reads (material key ``prony``)::

    G(t)   = G0 (g_inf + sum_i g_i exp(-t / tau_i))                       relaxation shear modulus, Pa
    G'(w)  = G0 (g_inf + sum_i g_i w^2 tau_i^2 / (1 + w^2 tau_i^2))       storage modulus, Pa
    G''(w) = G0 sum_i g_i w tau_i / (1 + w^2 tau_i^2)                     loss modulus, Pa

with w = 2 pi f (rad/s), G0 the instantaneous shear modulus (Pa), g_i > 0 dimensionless fractions of G0,
g_inf = 1 - sum_i g_i > 0 and tau_i > 0 relaxation times (s); at most :data:`MAX_PRONY_TERMS` terms. An
incompressible material's uniaxial modulus E = 3 G has the same normalised series.

Usage::

    from magsoro.characterization.viscoelastic import read_relaxation_csv, fit_prony
    fit = fit_prony(read_relaxation_csv("relax.csv"), n_terms=3)
    fit.g, fit.tau, fit.shear_modulus, fit.g_inf, fit.rms_error      # -, s, Pa, -, %
    fit.prony                                                        # [[g1, tau1], ...]: the material key

Method (docs/characterization.md): every combination of ``n_terms`` relaxation times from a log-spaced grid over
the data's range is scored by a nonnegative linear least-squares fit of the moduli (``scipy.optimize.nnls``);
the best few are refined together with their moduli by bounded nonlinear least squares on log tau
(``scipy.optimize.least_squares``), and the best of all is kept. Residuals are relative, (model - data) / data,
and each point is weighted by its share of the log-time (log-frequency) axis, so every decade counts as much as
any other whatever the logging rate.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from magsoro.characterization.csvfiles import read_columns
from magsoro.characterization.errors import CharacterizationDataError
from magsoro.mpm.laws.prony import MAX_PRONY_TERMS, prony_problem

# g_inf is kept at least this large: the engine needs sum g_i < 1 (a solid), and a Prony fit on a finite window
# cannot tell g_inf = 0 from a tiny positive one
G_INF_MIN = 1e-6
# a term whose g_i falls below this, or that changes a relaxation record by less than this (of G0), is dropped: the
# data do not support it
G_MIN = 1e-6
# terms whose relaxation times are closer than this factor are one term
_MERGE_RATIO = 1.05
# grid of candidate relaxation times: points per decade, extension beyond the data's range, at most this many
_GRID_PER_DECADE = 2.0
_GRID_EXTEND = math.sqrt(10.0)
_GRID_MAX = 25
# refined relaxation times stay within the data's range widened by this factor each side
_TAU_BOUND_FACTOR = 10.0
# grid starts refined by least squares; above _LARGE_DATA values only the best one (each refinement of 10^5
# values takes seconds, and the best grid start is almost always in the winning basin)
_N_REFINED = 4
_LARGE_DATA = 20_000

RELAXATION_COLUMNS = ("shear_modulus", "tensile_modulus", "stress")
SWEEP_PAIRS = (("storage_modulus", "loss_modulus"), ("tensile_storage_modulus", "tensile_loss_modulus"))


# ----------------------------------------------------------------------------------------------------------------
# the law


def prony_relaxation(time, shear_modulus: float, g, tau) -> np.ndarray:
    """G(t) in Pa at ``time`` (s) of the series (``shear_modulus`` = G0 in Pa, ``g`` fractions, ``tau`` in s)."""
    t = np.asarray(time, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    terms = np.exp(-t[..., None] / tau) @ g if g.size else np.zeros_like(t)
    return shear_modulus * (1.0 - g.sum() + terms)


def prony_storage_loss(frequency, shear_modulus: float, g, tau) -> tuple[np.ndarray, np.ndarray]:
    """(G', G'') in Pa at ``frequency`` (Hz) of the series (G0 in Pa, ``g`` fractions, ``tau`` in s)."""
    w = 2.0 * np.pi * np.asarray(frequency, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    u = w[..., None] * np.asarray(tau, dtype=np.float64)
    storage = shear_modulus * (1.0 - g.sum() + (u**2 / (1.0 + u**2)) @ g)
    loss = shear_modulus * ((u / (1.0 + u**2)) @ g)
    return storage, loss


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def check_prony(value, where: str, error=CharacterizationDataError) -> list[tuple[float, float]]:
    """Validate a ``prony`` value (as read from TOML) with the engine's rules (:func:`magsoro.mpm.laws.prony.prony_problem`)
    and return it as [(g_i, tau_i), ...] floats.

    ``where`` starts every message (e.g. ``"mat.toml: key 'prony'"``); ``error`` is the exception class raised.
    Allowed: an array of 1..3 pairs [g, tau] of finite numbers with g > 0, tau > 0 (s) and sum of g < 1.
    """
    problem = prony_problem(value) if isinstance(value, (list, tuple)) else "must be a table [[g, tau], ...]"
    if problem is not None:
        raise error(f"{where}: {problem} (e.g. prony = [[0.3, 0.01], [0.2, 1.0]], [g_i, tau_i in s] pairs)")
    return [(float(g), float(tau)) for g, tau in value]


# ----------------------------------------------------------------------------------------------------------------
# data


@dataclass
class RelaxationData:
    """A stress-relaxation record at a held strain, as the shear relaxation modulus G(t).

    Attributes
    ----------
    time : (N,) s, > 0, strictly increasing (time since the strain was applied).
    shear_modulus : (N,) G(t), Pa, > 0.
    column : the column the modulus came from ('shear_modulus', 'tensile_modulus' = 3 G, 'stress' with 'strain').
    source : the file (or description) the data came from.
    """

    time: np.ndarray
    shear_modulus: np.ndarray
    column: str = "shear_modulus"
    source: str = "<array>"

    @property
    def n_values(self) -> int:
        return int(self.time.size)

    @classmethod
    def from_arrays(cls, time, shear_modulus, source: str = "<array>") -> "RelaxationData":
        """Build and check a record from arrays (time in s, G(t) in Pa)."""
        time = np.asarray(time, dtype=np.float64).ravel()
        modulus = np.asarray(shear_modulus, dtype=np.float64).ravel()
        if time.shape != modulus.shape:
            raise CharacterizationDataError(
                f"{source}: columns 'time' and 'shear_modulus' differ in length ({time.size} vs {modulus.size})"
            )
        where = [f"row {i + 1}" for i in range(time.size)]
        _check_finite(source, "time", time, where)
        _check_finite(source, "shear_modulus", modulus, where)
        _check_axis(source, "time", time, where, "s")
        _check_positive(source, "shear_modulus", modulus, where, "Pa")
        return cls(time, modulus, "shear_modulus", source)


@dataclass
class FrequencySweepData:
    """A dynamic (small-amplitude oscillatory) frequency sweep as shear storage and loss moduli.

    Attributes
    ----------
    frequency : (N,) Hz, > 0, increasing (a file may list them in any order without repeats; they are sorted).
    storage_modulus, loss_modulus : (N,) G'(f) and G''(f), Pa, > 0.
    column : 'storage_modulus' (shear G', G'') or 'tensile_storage_modulus' (E', E'' = 3 G', 3 G'').
    source : the file (or description) the data came from.
    """

    frequency: np.ndarray
    storage_modulus: np.ndarray
    loss_modulus: np.ndarray
    column: str = "storage_modulus"
    source: str = "<array>"

    @property
    def n_values(self) -> int:
        return int(2 * self.frequency.size)

    @classmethod
    def from_arrays(cls, frequency, storage_modulus, loss_modulus, source: str = "<array>") -> "FrequencySweepData":
        """Build and check a sweep from arrays (frequency in Hz, G' and G'' in Pa)."""
        f = np.asarray(frequency, dtype=np.float64).ravel()
        gs = np.asarray(storage_modulus, dtype=np.float64).ravel()
        gl = np.asarray(loss_modulus, dtype=np.float64).ravel()
        if not f.shape == gs.shape == gl.shape:
            raise CharacterizationDataError(
                f"{source}: columns 'frequency', 'storage_modulus' and 'loss_modulus' differ in length "
                f"({f.size}, {gs.size}, {gl.size})"
            )
        where = [f"row {i + 1}" for i in range(f.size)]
        return _make_sweep(source, f, gs, gl, where, ("storage_modulus", "loss_modulus"), 1.0)


def _check_finite(source, column, values, where) -> None:
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        i = bad[0]
        raise CharacterizationDataError(f"{source}: column {column!r} on {where[i]} is not finite ({values[i]!r})")


def _check_positive(source, column, values, where, unit) -> None:
    bad = np.flatnonzero(~(values > 0))
    if bad.size:
        i = bad[0]
        raise CharacterizationDataError(
            f"{source}: column {column!r} on {where[i]} is {values[i]:g} {unit}; it must be > 0 {unit}"
        )


def _check_axis(source, column, values, where, unit) -> None:
    """Positive and strictly increasing (time)."""
    _check_positive(source, column, values, where, unit)
    drop = np.flatnonzero(np.diff(values) <= 0)
    if drop.size:
        j = drop[0] + 1
        raise CharacterizationDataError(
            f"{source}: column {column!r} is not strictly increasing on {where[j]} ({values[j]:g} {unit} after "
            f"{values[j - 1]:g} {unit}); give each time once, in order"
        )


def read_relaxation_csv(path: str | Path) -> RelaxationData:
    """Read a stress-relaxation CSV file (one held strain).

    Columns: ``time`` (s since the strain was applied, > 0, strictly increasing) and exactly one of

    - ``shear_modulus``: G(t), Pa;
    - ``tensile_modulus``: uniaxial relaxation modulus E(t), Pa; G = E / 3 (incompressible);
    - ``stress``: nominal stress, Pa, with ``strain``: the held engineering strain (> 0, dimensionless);
      G(t) = stress / (lam - lam^-2), lam = 1 + strain (incompressible Neo-Hookean; E/3 at small strain).

    Raises :class:`CharacterizationDataError` naming the file, the column and the line.
    """
    path = Path(path)
    cols = read_columns(path, ("time",), optional=(*RELAXATION_COLUMNS, "strain"))
    source = str(path)
    present = [c for c in RELAXATION_COLUMNS if c in cols]
    allowed = (
        "'shear_modulus' (G(t), Pa), 'tensile_modulus' (E(t), Pa) or 'stress' (nominal, Pa) with 'strain' "
        "(held engineering strain)"
    )
    if not present:
        raise CharacterizationDataError(f"{source}: no modulus column next to 'time'; give one of {allowed}")
    if len(present) > 1:
        raise CharacterizationDataError(
            f"{source}: columns {' and '.join(repr(c) for c in present)} both present; give only one of {allowed}"
        )
    column = present[0]
    where = [f"line {n}" for n in cols["_line"]]
    time, value = cols["time"], cols[column]
    _check_axis(source, "time", time, where, "s")
    _check_positive(source, column, value, where, "Pa")
    if column == "shear_modulus":
        modulus = value
    elif column == "tensile_modulus":
        modulus = value / 3.0
    else:
        if "strain" not in cols:
            raise CharacterizationDataError(
                f"{source}: column 'stress' needs a column 'strain' (the held engineering strain, > 0) to give a "
                "modulus; or give 'shear_modulus' or 'tensile_modulus' instead"
            )
        strain = cols["strain"]
        _check_positive(source, "strain", strain, where, "(dimensionless)")
        stretch = 1.0 + strain
        modulus = value / (stretch - stretch**-2)
    return RelaxationData(time, modulus, column, source)


def read_frequency_sweep_csv(path: str | Path) -> FrequencySweepData:
    """Read a frequency-sweep CSV file.

    Columns: ``frequency`` (Hz, > 0, each once, any order) and either ``storage_modulus`` and ``loss_modulus``
    (shear G', G'', Pa) or ``tensile_storage_modulus`` and ``tensile_loss_modulus`` (E', E'', Pa; G = E / 3),
    all > 0.

    Raises :class:`CharacterizationDataError` naming the file, the column and the line.
    """
    path = Path(path)
    cols = read_columns(path, ("frequency",), optional=tuple(c for pair in SWEEP_PAIRS for c in pair))
    source = str(path)
    allowed = "'storage_modulus' and 'loss_modulus' (shear, Pa) or 'tensile_storage_modulus' and " \
              "'tensile_loss_modulus' (Pa)"
    complete = [pair for pair in SWEEP_PAIRS if all(c in cols for c in pair)]
    if len(complete) != 1:
        partial = [c for pair in SWEEP_PAIRS for c in pair if c in cols]
        found = f" (found {', '.join(repr(c) for c in partial)})" if partial else ""
        what = "both pairs present" if len(complete) > 1 else "no complete pair of modulus columns"
        raise CharacterizationDataError(f"{source}: {what}{found}; give {allowed} next to 'frequency'")
    pair = complete[0]
    where = [f"line {n}" for n in cols["_line"]]
    factor = 3.0 if pair[0].startswith("tensile") else 1.0
    return _make_sweep(source, cols["frequency"], cols[pair[0]], cols[pair[1]], where, pair, factor)


def _make_sweep(source, f, storage, loss, where, pair, factor) -> FrequencySweepData:
    for name, v in (("frequency", f), (pair[0], storage), (pair[1], loss)):
        _check_finite(source, name, v, where)
    _check_positive(source, "frequency", f, where, "Hz")
    _check_positive(source, pair[0], storage, where, "Pa")
    _check_positive(source, pair[1], loss, where, "Pa")
    order = np.argsort(f, kind="stable")
    fs = f[order]
    dup = np.flatnonzero(np.diff(fs) == 0)
    if dup.size:
        a, b = sorted((order[dup[0]], order[dup[0] + 1]))
        raise CharacterizationDataError(
            f"{source}: column 'frequency' repeats {fs[dup[0]]:g} Hz on {where[a]} and {where[b]}; give each "
            "frequency once (average repeated measurements first)"
        )
    return FrequencySweepData(fs, storage[order] / factor, loss[order] / factor, pair[0], source)


# ----------------------------------------------------------------------------------------------------------------
# fit


@dataclass
class PronyFit:
    """A fitted Prony series.

    Attributes
    ----------
    g : fractions g_i of the instantaneous shear modulus (dimensionless), by increasing tau.
    tau : relaxation times tau_i, s.
    shear_modulus : G0, the instantaneous shear modulus, Pa (G(t -> 0), G'(f -> inf)).
    g_inf : 1 - sum g_i, the fraction left at equilibrium.
    rms_error : relative RMS error model vs data over all fitted values, percent (unweighted).
    mape : mean absolute percentage error over all fitted values, percent.
    n_terms_requested : the number of terms asked for; fewer remain when the data do not support them (notes).
    method : 'nnls' (the best grid start was not improved) or 'nnls + least_squares'.
    notes : remarks on the fit (dropped or merged terms, relaxation times at the edge of the data's range).
    data : the :class:`RelaxationData` or :class:`FrequencySweepData` fitted.
    """

    g: tuple[float, ...]
    tau: tuple[float, ...]
    shear_modulus: float
    g_inf: float
    rms_error: float
    mape: float
    n_terms_requested: int
    method: str
    data: RelaxationData | FrequencySweepData
    notes: list[str] = field(default_factory=list)

    @property
    def n_terms(self) -> int:
        return len(self.g)

    @property
    def long_term_shear_modulus(self) -> float:
        """G_inf = G0 g_inf, Pa."""
        return self.shear_modulus * self.g_inf

    @property
    def prony(self) -> list[list[float]]:
        """The material key's value: [[g_1, tau_1], ...]."""
        return [[float(g), float(t)] for g, t in zip(self.g, self.tau)]

    @property
    def kind(self) -> str:
        return "relaxation" if isinstance(self.data, RelaxationData) else "frequency-sweep"

    def relaxation_modulus(self, time) -> np.ndarray:
        """G(t), Pa, at ``time`` in s."""
        return prony_relaxation(time, self.shear_modulus, self.g, self.tau)

    def storage_loss(self, frequency) -> tuple[np.ndarray, np.ndarray]:
        """(G', G''), Pa, at ``frequency`` in Hz."""
        return prony_storage_loss(frequency, self.shear_modulus, self.g, self.tau)

    def to_json(self) -> dict:
        d = self.data
        axis = d.time if isinstance(d, RelaxationData) else d.frequency
        return {
            "kind": self.kind,
            "source": d.source,
            "column": d.column,
            "n_points": int(axis.size),
            "range": [float(axis[0]), float(axis[-1])],
            "n_terms": self.n_terms,
            "g": [float(x) for x in self.g],
            "tau": [float(x) for x in self.tau],
            "prony": self.prony,
            "shear_modulus": float(self.shear_modulus),
            "g_inf": float(self.g_inf),
            "long_term_shear_modulus": float(self.long_term_shear_modulus),
            "rms_error": float(self.rms_error),
            "mape": float(self.mape),
            "method": self.method,
            "notes": list(self.notes),
        }


def _log_axis_weights(x: np.ndarray) -> np.ndarray:
    """sqrt of each point's share of the log axis (x sorted, > 0): equal for log-spaced points."""
    if x.size < 3:
        return np.ones_like(x)
    lx = np.log(x)
    d = np.empty_like(lx)
    d[1:-1] = 0.5 * (lx[2:] - lx[:-2])
    d[0] = lx[1] - lx[0]
    d[-1] = lx[-1] - lx[-2]
    d = np.maximum(d, 1e-12 * max(float(lx[-1] - lx[0]), 1e-300))
    return np.sqrt(d / d.mean())


class _Problem:
    """The fit as basis functions of log tau: model values = B(log tau) @ c with c = [c_inf, c_1..c_N] in units
    of ``scale`` Pa; residual = weight * (model / data - 1)."""

    def __init__(self, data):
        if isinstance(data, RelaxationData):
            self.relaxation = True
            self.x = data.time
            self.y = data.shear_modulus.copy()
            self.tau_range = (float(data.time[0]), float(data.time[-1]))
            self.weight = _log_axis_weights(data.time)
        else:
            self.relaxation = False
            self.x = 2.0 * np.pi * data.frequency
            self.y = np.concatenate([data.storage_modulus, data.loss_modulus])
            self.tau_range = (float(1.0 / self.x[-1]), float(1.0 / self.x[0]))
            w = _log_axis_weights(self.x)
            self.weight = np.concatenate([w, w])
        self.scale = float(np.max(self.y))
        self.y = self.y / self.scale
        self.rw = self.weight / self.y  # multiplies model values into weighted relative residuals

    def basis(self, log_tau) -> np.ndarray:
        tau = np.exp(np.asarray(log_tau, dtype=np.float64))
        if self.relaxation:
            terms = np.exp(-self.x[:, None] / tau)
            return np.hstack([np.ones((self.x.size, 1)), terms])
        u = self.x[:, None] * tau
        storage = np.hstack([np.ones((self.x.size, 1)), u**2 / (1.0 + u**2)])
        loss = np.hstack([np.zeros((self.x.size, 1)), u / (1.0 + u**2)])
        return np.vstack([storage, loss])

    def basis_dlogtau(self, log_tau) -> np.ndarray:
        """d basis / d log tau_i for the N term columns."""
        tau = np.exp(np.asarray(log_tau, dtype=np.float64))
        if self.relaxation:
            s = self.x[:, None] / tau
            return np.exp(-s) * s
        u = self.x[:, None] * tau
        den = (1.0 + u**2) ** 2
        return np.vstack([2.0 * u**2 / den, u * (1.0 - u**2) / den])

    def residual(self, params, n):
        c = params[n:]
        return self.rw * (self.basis(params[:n]) @ c) - self.weight

    def jacobian(self, params, n):
        c = params[n:]
        jac = np.empty((self.y.size, 2 * n + 1))
        jac[:, :n] = self.rw[:, None] * self.basis_dlogtau(params[:n]) * c[1:]
        jac[:, n:] = self.rw[:, None] * self.basis(params[:n])
        return jac


def _grid_search(prob: _Problem, n: int, keep: int):
    """Score every n-combination of grid relaxation times by NNLS; return the best ``keep`` as
    (cost, log_tau, c) with cost = 0.5 * sum of squared weighted residuals."""
    from scipy.linalg import LinAlgError, cholesky, solve_triangular
    from scipy.optimize import nnls

    lo, hi = prob.tau_range
    lo, hi = lo / _GRID_EXTEND, hi * _GRID_EXTEND
    decades = math.log10(hi / lo)
    m = int(min(_GRID_MAX, max(n, math.ceil(_GRID_PER_DECADE * decades) + 1)))
    grid = np.linspace(math.log(lo), math.log(hi), m)
    # the NNLS of each combination works on the (n+1) x (n+1) normal equations of the weighted basis, so its cost
    # does not grow with the number of data points: ||M c - b||^2 = ||R c - d||^2 + b.b - d.d with R^T R = M^T M
    mat = prob.rw[:, None] * prob.basis(grid)
    gram = mat.T @ mat
    rhs = mat.T @ prob.weight
    bb = float(prob.weight @ prob.weight)
    scored = []
    for combo in itertools.combinations(range(m), n):
        idx = [0, *(k + 1 for k in combo)]
        try:
            r = cholesky(gram[np.ix_(idx, idx)], lower=False)
        except LinAlgError:
            continue
        d = solve_triangular(r, rhs[idx], trans="T", lower=False)
        c, rnorm = nnls(r, d)
        scored.append((0.5 * (rnorm**2 + bb - float(d @ d)), grid[list(combo)], c))
    scored.sort(key=lambda s: s[0])
    return scored[:keep]


def _refine(prob: _Problem, log_tau, c):
    from scipy.optimize import least_squares

    n = len(log_tau)
    lo, hi = prob.tau_range
    lo_b, hi_b = math.log(lo / _TAU_BOUND_FACTOR), math.log(hi * _TAU_BOUND_FACTOR)
    c = np.array(c, dtype=np.float64)
    # a term with a zero modulus has no gradient in its tau: give every term a small share to move from
    c[1:] = np.maximum(c[1:], 1e-3 * max(float(c.sum()), 1e-12))
    c[0] = max(c[0], 10 * G_INF_MIN)
    x0 = np.concatenate([np.clip(log_tau, lo_b + 1e-9, hi_b - 1e-9), c])
    lower = np.concatenate([np.full(n, lo_b), [G_INF_MIN], np.zeros(n)])
    upper = np.concatenate([np.full(n, hi_b), np.full(n + 1, np.inf)])
    res = least_squares(
        prob.residual, x0, jac=prob.jacobian, bounds=(lower, upper), args=(n,), method="trf", x_scale="jac",
        xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=400 * (2 * n + 1),
    )
    return float(res.cost), res.x[:n], res.x[n:]


def fit_prony(data: RelaxationData | FrequencySweepData, n_terms: int = 3) -> PronyFit:
    """Fit ``n_terms`` (1..3) Prony terms and G0 to a relaxation record or a frequency sweep.

    Raises :class:`CharacterizationDataError` for a bad ``n_terms`` or fewer measured values than the 2 n + 1
    parameters (G0, g_i, tau_i; a sweep gives two values per frequency).
    """
    if isinstance(n_terms, bool) or not isinstance(n_terms, (int, np.integer)) or not 1 <= n_terms <= MAX_PRONY_TERMS:
        raise CharacterizationDataError(f"the number of Prony terms must be 1 to {MAX_PRONY_TERMS}, got {n_terms!r}")
    if not isinstance(data, (RelaxationData, FrequencySweepData)):
        raise CharacterizationDataError(f"fit_prony needs RelaxationData or FrequencySweepData, got {type(data).__name__}")
    n = int(n_terms)
    n_params = 2 * n + 1
    if data.n_values < n_params:
        if isinstance(data, RelaxationData):
            have = f"{data.time.size} rows"
        else:
            have = f"{data.frequency.size} rows ({data.n_values} values: G' and G'' per frequency)"
        raise CharacterizationDataError(
            f"{data.source}: {have}, but {n} Prony term(s) have {n_params} parameters (G0, g_i, tau_i); give at "
            f"least {n_params} values or fewer terms"
        )
    prob = _Problem(data)
    starts = _grid_search(prob, n, _N_REFINED if prob.y.size <= _LARGE_DATA else 1)
    if not starts:
        raise CharacterizationDataError(f"{data.source}: no start of the Prony fit could be solved")
    best_cost, best_tau, best_c = starts[0]
    method = "nnls"
    for _, log_tau, c in starts:
        try:
            cost, lt, cc = _refine(prob, log_tau, c)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if np.all(np.isfinite(cc)) and cost < best_cost:
            best_cost, best_tau, best_c, method = cost, lt, cc, "nnls + least_squares"
    return _make_fit(prob, data, n, np.exp(best_tau), np.asarray(best_c), method)


def _make_fit(prob: _Problem, data, n_requested: int, tau, c, method: str) -> PronyFit:
    notes = []
    order = np.argsort(tau)
    tau, moduli = list(tau[order]), list(c[1:][order] * prob.scale)
    g_inf_mod = max(float(c[0]), G_INF_MIN) * prob.scale
    # merge terms whose relaxation times coincide (the data held fewer distinguishable terms)
    merged_tau, merged_mod = [], []
    for t, m in zip(tau, moduli):
        if merged_tau and t / merged_tau[-1] < _MERGE_RATIO:
            total = merged_mod[-1] + m
            w = m / total if total > 0 else 0.5
            merged_tau[-1] = math.exp((1 - w) * math.log(merged_tau[-1]) + w * math.log(t))
            merged_mod[-1] = total
            notes.append("two terms with nearly equal tau were merged into one")
        else:
            merged_tau.append(t)
            merged_mod.append(m)
    total = g_inf_mod + sum(merged_mod)
    lo, hi = prob.tau_range
    if isinstance(data, RelaxationData):
        # what a term changes over the record, m (exp(-lo/tau) - exp(-hi/tau)): a term that relaxed before the first
        # sample (or after the last) leaves the data unchanged however large its g; it is not supported either
        seen = [m * (math.exp(-lo / t) - math.exp(-hi / t)) for m, t in zip(merged_mod, merged_tau)]
    else:
        seen = merged_mod
    kept = [(m, t) for m, t, v in zip(merged_mod, merged_tau, seen) if m / total >= G_MIN and v / total >= G_MIN]
    if len(kept) < len(merged_mod):
        notes.append(f"{len(merged_mod) - len(kept)} term(s) with g < {G_MIN:g}, or changing the record by less than "
                     f"{G_MIN:g} of G0, dropped: the data do not support them")
    if not kept:
        raise CharacterizationDataError(
            f"{data.source}: the data show no relaxation a Prony term could fit (every g_i is 0); check the column"
        )
    g0 = g_inf_mod + sum(m for m, _ in kept)  # a dropped term held < G_MIN of G0
    g = tuple(float(m / g0) for m, _ in kept)
    taus = tuple(float(t) for _, t in kept)
    g_inf = 1.0 - sum(g)
    for i, t in enumerate(taus, start=1):
        if not lo <= t <= hi:
            notes.append(f"tau_{i} = {t:.3g} s lies outside the range the data resolve ({lo:.3g} .. {hi:.3g} s): "
                         "poorly determined")
    if isinstance(data, RelaxationData):
        model = prony_relaxation(data.time, g0, g, taus)
        measured = data.shear_modulus
    else:
        storage, loss = prony_storage_loss(data.frequency, g0, g, taus)
        model = np.concatenate([storage, loss])
        measured = np.concatenate([data.storage_modulus, data.loss_modulus])
    rel = (model - measured) / measured
    return PronyFit(
        g=g, tau=taus, shear_modulus=float(g0), g_inf=float(g_inf),
        rms_error=float(100.0 * np.sqrt(np.mean(rel**2))), mape=float(100.0 * np.mean(np.abs(rel))),
        n_terms_requested=n_requested, method=method, data=data, notes=list(dict.fromkeys(notes)),
    )


# ----------------------------------------------------------------------------------------------------------------
# figure


def plot_prony_fit(fit: PronyFit, path: str | Path, title: str | None = None) -> Path:
    """Data (markers) and the fitted series (line) on a log time or log frequency axis, with the relative error
    below. Moduli in kPa. Returns the path written."""
    from magsoro.characterization.plotting import _pyplot

    plt = _pyplot()
    fig, (ax, axr) = plt.subplots(
        2, 1, figsize=(6.4, 5.6), dpi=150, sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    d = fit.data
    label = f"Prony, {fit.n_terms} term(s) (RMS {fit.rms_error:.2f} %)"
    if isinstance(d, RelaxationData):
        x = d.time
        fine = np.geomspace(x[0], x[-1], 400)
        ax.plot(x, d.shear_modulus / 1e3, "o", ms=3, mfc="none", color="0.5", label="data")
        ax.plot(fine, fit.relaxation_modulus(fine) / 1e3, "-", lw=1.6, color="tab:blue", label=label)
        ylabel = "G(t) [kPa]" if d.column == "shear_modulus" else f"G(t) [kPa] (from '{d.column}')"
        ax.set_ylabel(ylabel)
        axr.plot(x, 100 * (fit.relaxation_modulus(x) / d.shear_modulus - 1), ".", ms=3, color="tab:blue")
        axr.set_xlabel("time [s]")
        for t in fit.tau:
            ax.axvline(t, color="tab:blue", lw=0.6, ls=":")
    else:
        x = d.frequency
        fine = np.geomspace(x[0], x[-1], 400)
        fs, fl = fit.storage_loss(fine)
        ms, ml = fit.storage_loss(x)
        ax.loglog(x, d.storage_modulus / 1e3, "o", ms=3, mfc="none", color="tab:blue", label="G' data")
        ax.loglog(x, d.loss_modulus / 1e3, "s", ms=3, mfc="none", color="tab:red", label="G'' data")
        ax.loglog(fine, fs / 1e3, "-", lw=1.6, color="tab:blue", label=f"G' {label}")
        ax.loglog(fine, fl / 1e3, "-", lw=1.6, color="tab:red", label="G'' Prony")
        ax.set_ylabel("modulus [kPa]" if d.column == "storage_modulus" else "shear modulus [kPa] (E/3)")
        axr.plot(x, 100 * (ms / d.storage_modulus - 1), ".", ms=3, color="tab:blue")
        axr.plot(x, 100 * (ml / d.loss_modulus - 1), ".", ms=3, color="tab:red")
        axr.set_xlabel("frequency [Hz]")
    ax.set_xscale("log")
    axr.set_xscale("log")
    axr.axhline(0.0, color="0.3", lw=0.8)
    axr.set_ylabel("error [%]")
    text = f"G0 = {fit.shear_modulus / 1e3:.4g} kPa, g_inf = {fit.g_inf:.3f}\n" + "\n".join(
        f"g{i} = {g:.3f}, tau{i} = {t:.3g} s" for i, (g, t) in enumerate(zip(fit.g, fit.tau), start=1)
    )
    # the fitted numbers as the legend's title: loc="best" keeps both off the data
    legend = ax.legend(fontsize=7, title=text, title_fontsize=7, loc="best")
    legend.get_title().set_family("monospace")
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3, which="both")
    axr.grid(alpha=0.3, which="both")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
