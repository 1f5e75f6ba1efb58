"""Hyperelastic model fitting to uniaxial tensile data (seed 001 sec III).

Seed 001 fits a linear model and the Neo-Hookean, Mooney-Rivlin, Yeoh, Ogden (3 terms) and polynomial
(5 coefficients) hyperelastic models to uniaxial tensile curves of NdFeB-loaded silicones by nonlinear least
squares and compares them by the mean absolute percentage error (MAPE, Table II). This module does the same with
``scipy.optimize.least_squares``.

Conventions (all incompressible, uniaxial tension, stretch ``lam = 1 + strain``):

- ``strain`` is engineering strain (dimensionless), ``stress`` nominal (first Piola-Kirchhoff) stress in Pa, i.e.
  force over the undeformed cross-section, which is what a tensile machine reports.
- For a strain energy W(I1, I2) the uniaxial nominal stress is
  ``P = 2 (lam - lam^-2) (dW/dI1 + dW/dI2 / lam)`` with ``I1 = lam^2 + 2/lam`` and ``I2 = 2 lam + 1/lam^2``.
- Model forms and their initial (small-strain) shear modulus ``mu0``:

  ============== ============================================================== ==========================
  linear         P = E * strain                                                 E / 3 (incompressible)
  neo-hookean    W = C10 (I1-3)                                                 2 C10
  mooney-rivlin  W = C10 (I1-3) + C01 (I2-3)                                    2 (C10 + C01)
  yeoh           W = C10 (I1-3) + C20 (I1-3)^2 + C30 (I1-3)^3                   2 C10
  ogden3         W = sum_i 2 mu_i / alpha_i^2 (lam1^a_i + lam2^a_i + lam3^a_i - 3)  mu1 + mu2 + mu3
  polynomial5    W = sum_{i+j<=2} Cij (I1-3)^i (I2-3)^j  (C10 C01 C20 C11 C02)    2 (C10 + C01)
  ============== ============================================================== ==========================

  The Ogden form is the one Abaqus uses, so that ``mu_i`` are in Pa and their sum is the shear modulus; the
  5-coefficient polynomial is the second-order polynomial in (I1-3, I2-3), which has exactly five coefficients.
- MAPE = 100 * mean(|P_model - P_data| / P_data) over the fitted points with P_data > 0 (seed 001 Table II).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares, nnls

from magsoro.characterization.csvfiles import read_columns
from magsoro.characterization.errors import CharacterizationDataError

MODEL_NAMES = ("linear", "neo-hookean", "mooney-rivlin", "yeoh", "ogden3", "polynomial5")
"""Model names, spelled as on the command line and in the JSON output."""


# ----------------------------------------------------------------------------------------------------------------
# data


@dataclass(frozen=True)
class TensileData:
    """Uniaxial tensile measurements, possibly from several specimens.

    Attributes
    ----------
    strain : (N,) engineering strain, dimensionless, >= 0 and increasing within each specimen.
    stress : (N,) nominal stress, Pa, >= 0.
    specimen : (N,) specimen label of each point (str).
    sources : the files (or descriptions) the data came from.
    """

    strain: np.ndarray
    stress: np.ndarray
    specimen: np.ndarray
    sources: tuple[str, ...]

    @property
    def specimens(self) -> list[str]:
        """Specimen labels in order of first appearance."""
        return list(dict.fromkeys(self.specimen.tolist()))

    def select(self, max_strain: float | None) -> "TensileData":
        """The points with strain <= ``max_strain`` (all points when None)."""
        if max_strain is None:
            return self
        keep = self.strain <= max_strain
        return TensileData(self.strain[keep], self.stress[keep], self.specimen[keep], self.sources)

    @classmethod
    def from_arrays(cls, strain, stress, specimen=None, source: str = "<array>") -> "TensileData":
        """Build and check a data set from arrays (strain dimensionless, stress in Pa).

        Raises :class:`CharacterizationDataError` for negative or non-monotonic strain and for negative stress.
        """
        strain = np.asarray(strain, dtype=np.float64).ravel()
        stress = np.asarray(stress, dtype=np.float64).ravel()
        if strain.shape != stress.shape:
            raise CharacterizationDataError(
                f"{source}: columns 'strain' and 'stress' differ in length ({strain.size} vs {stress.size})"
            )
        if specimen is None:
            specimen = np.full(strain.shape, "1", dtype=object)
        specimen = np.asarray(specimen, dtype=object).ravel()
        rows = [f"row {i + 1}" for i in range(strain.size)]
        _check_tensile(source, strain, stress, specimen, rows)
        return cls(strain, stress, specimen, (source,))

    @classmethod
    def concatenate(cls, parts: Sequence["TensileData"]) -> "TensileData":
        """Join data sets (e.g. one file per specimen)."""
        return cls(
            np.concatenate([p.strain for p in parts]),
            np.concatenate([p.stress for p in parts]),
            np.concatenate([p.specimen for p in parts]),
            tuple(s for p in parts for s in p.sources),
        )


def _check_tensile(source: str, strain, stress, specimen, where: list[str]) -> None:
    if not np.all(np.isfinite(strain)) or not np.all(np.isfinite(stress)):
        raise CharacterizationDataError(f"{source}: columns 'strain' and 'stress' must hold finite numbers")
    bad = np.flatnonzero(strain < 0)
    if bad.size:
        i = bad[0]
        raise CharacterizationDataError(
            f"{source}: column 'strain' is negative on {where[i]} ({strain[i]:g}); tensile data needs strain >= 0"
        )
    bad = np.flatnonzero(stress < 0)
    if bad.size:
        i = bad[0]
        raise CharacterizationDataError(
            f"{source}: column 'stress' is negative on {where[i]} ({stress[i]:g} Pa); "
            "tensile (nominal) stress must be >= 0 Pa"
        )
    for name in dict.fromkeys(specimen.tolist()):
        idx = np.flatnonzero(specimen == name)
        s = strain[idx]
        drop = np.flatnonzero(np.diff(s) <= 0)
        if drop.size:
            j = idx[drop[0] + 1]
            raise CharacterizationDataError(
                f"{source}: column 'strain' is not strictly increasing for specimen {name!r} on {where[j]} "
                f"({strain[j]:g} after {strain[idx[drop[0]]]:g}); give the loading curve only, one specimen at a "
                "time or with a 'specimen' column"
            )


def read_tensile_csv(paths: str | Path | Sequence[str | Path]) -> TensileData:
    """Read one or several tensile CSV files.

    Each file has a header with columns ``strain`` (engineering, dimensionless) and ``stress`` (nominal, Pa), and
    optionally ``specimen`` (any label). Without a ``specimen`` column a file is one specimen named after the file.
    Specimen labels are prefixed with the file name when several files are read, so they stay distinct.

    Raises :class:`CharacterizationDataError` naming the file and column for missing columns, non-numeric
    values, negative strain or stress, and strain that does not increase within a specimen.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    parts = []
    for path in paths:
        path = Path(path)
        cols = read_columns(path, ("strain", "stress"), optional=("specimen",), labels=("specimen",))
        strain, stress = cols["strain"], cols["stress"]
        if "specimen" in cols:
            spec = cols["specimen"]
            if len(paths) > 1:
                spec = np.array([f"{path.name}:{s}" for s in spec], dtype=object)
        else:
            spec = np.full(strain.shape, path.name, dtype=object)
        where = [f"line {n}" for n in cols["_line"]]
        _check_tensile(str(path), strain, stress, spec, where)
        parts.append(TensileData(strain, stress, spec, (str(path),)))
    return TensileData.concatenate(parts)


# ----------------------------------------------------------------------------------------------------------------
# models


def _invariant_terms(lam):
    """(2 (lam - lam^-2), I1 - 3, I2 - 3) for incompressible uniaxial stretch."""
    return 2.0 * (lam - lam**-2), lam**2 + 2.0 / lam - 3.0, 2.0 * lam + lam**-2 - 3.0


def _basis_linear(lam):
    return (lam - 1.0)[:, None]


def _basis_neo_hookean(lam):
    g, _, _ = _invariant_terms(lam)
    return g[:, None]


def _basis_mooney_rivlin(lam):
    g, _, _ = _invariant_terms(lam)
    return np.stack([g, g / lam], axis=1)


def _basis_yeoh(lam):
    g, a, _ = _invariant_terms(lam)
    return np.stack([g, g * 2.0 * a, g * 3.0 * a**2], axis=1)


def _basis_polynomial5(lam):
    # dW/dI1 = C10 + 2 C20 a + C11 b ; dW/dI2 = C01 + C11 a + 2 C02 b
    g, a, b = _invariant_terms(lam)
    return np.stack([g, g / lam, g * 2.0 * a, g * (b + a / lam), g * 2.0 * b / lam], axis=1)


def ogden_term(alpha, lam):
    """Uniaxial nominal stress per unit mu of one Ogden term, ``(2/alpha) (lam^(alpha-1) - lam^(-alpha/2-1))``.

    Written with expm1 so alpha -> 0 stays accurate (the limit is 3 ln(lam) / lam).
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    lam = np.asarray(lam, dtype=np.float64)
    L = np.log(lam)
    small = np.abs(alpha) < 1e-8
    a = np.where(small, 1.0, alpha)
    val = 2.0 / lam * (np.expm1(a * L) - np.expm1(-0.5 * a * L)) / a
    return np.where(small, 3.0 * L / lam, val)


def _ogden_stress(params, lam):
    p = np.asarray(params, dtype=np.float64)
    return sum(p[2 * i] * ogden_term(p[2 * i + 1], lam) for i in range(len(p) // 2))


@dataclass(frozen=True)
class HyperelasticModel:
    """One uniaxial model form.

    Attributes
    ----------
    name : model name as used on the command line.
    param_names : names of the parameters, in order.
    dimensionless : names of the parameters that are exponents (no unit); all others are in Pa.
    shear_weights : the initial shear modulus is ``sum(w * p)`` over the moduli (for Ogden, the sum of mu_i).
    basis : for models linear in their parameters, ``basis(lam) @ params`` is the nominal stress; None otherwise.
    lower, upper : bounds on each parameter (moduli as multiples of the largest measured stress, so they scale
        with the data; exponents as is).
    """

    name: str
    param_names: tuple[str, ...]
    shear_weights: tuple[float, ...]
    basis: Callable[[np.ndarray], np.ndarray] | None
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    dimensionless: tuple[str, ...] = ()

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def stress(self, params, strain) -> np.ndarray:
        """Nominal stress (Pa) at engineering ``strain`` for parameter vector ``params`` (Pa / dimensionless)."""
        strain = np.asarray(strain, dtype=np.float64)
        lam = 1.0 + strain.reshape(-1)
        if self.basis is not None:
            out = self.basis(lam) @ np.asarray(params, dtype=np.float64)
        else:
            out = _ogden_stress(params, lam)
        return out.reshape(strain.shape)

    def shear_modulus(self, params) -> float:
        """Initial (small-strain) shear modulus, Pa."""
        return float(np.dot(self.shear_weights, np.asarray(params, dtype=np.float64)))


_INF = np.inf
_MU_BOUND = 1e4  # Ogden |mu_i| <= 1e4 x the largest stress: keeps near-equal exponents from cancelling wildly
_ALPHA_BOUND = 20.0  # Ogden exponents of silicones fall well inside +-20; wider only adds ill-conditioning

MODELS: dict[str, HyperelasticModel] = {
    "linear": HyperelasticModel("linear", ("E",), (1.0 / 3.0,), _basis_linear, (0.0,), (_INF,)),
    "neo-hookean": HyperelasticModel("neo-hookean", ("C10",), (2.0,), _basis_neo_hookean, (0.0,), (_INF,)),
    "mooney-rivlin": HyperelasticModel(
        "mooney-rivlin", ("C10", "C01"), (2.0, 2.0), _basis_mooney_rivlin, (-_INF, -_INF), (_INF, _INF)
    ),
    # C10 > 0 and C30 > 0 keep the Yeoh material stable in tension at small and large strain (Yeoh 1993)
    "yeoh": HyperelasticModel(
        "yeoh", ("C10", "C20", "C30"), (2.0, 0.0, 0.0), _basis_yeoh, (0.0, -_INF, 0.0), (_INF, _INF, _INF)
    ),
    # bounds as listed; each start further restricts every term to one sign with mu_i alpha_i >= 0
    "ogden3": HyperelasticModel(
        "ogden3",
        ("mu1", "alpha1", "mu2", "alpha2", "mu3", "alpha3"),
        (1.0, 0.0, 1.0, 0.0, 1.0, 0.0),
        None,
        (-_MU_BOUND, -_ALPHA_BOUND) * 3,
        (_MU_BOUND, _ALPHA_BOUND) * 3,
        dimensionless=("alpha1", "alpha2", "alpha3"),
    ),
    "polynomial5": HyperelasticModel(
        "polynomial5",
        ("C10", "C01", "C20", "C11", "C02"),
        (2.0, 2.0, 0.0, 0.0, 0.0),
        _basis_polynomial5,
        (-_INF,) * 5,
        (_INF,) * 5,
    ),
}


def uniaxial_stress(model: str, params: dict[str, float] | Sequence[float], strain) -> np.ndarray:
    """Nominal uniaxial stress (Pa) of ``model`` at engineering ``strain``.

    ``params`` is a dict keyed by the model's parameter names (moduli in Pa, Ogden exponents dimensionless) or a
    sequence in the order of :attr:`HyperelasticModel.param_names`.
    """
    m = get_model(model)
    if isinstance(params, dict):
        params = [params[k] for k in m.param_names]
    return m.stress(params, strain)


def get_model(name: str) -> HyperelasticModel:
    """The model called ``name`` (one of :data:`MODEL_NAMES`); ValueError listing the names otherwise."""
    try:
        return MODELS[name]
    except KeyError:
        raise CharacterizationDataError(
            f"unknown hyperelastic model {name!r}; choose from {', '.join(MODEL_NAMES)}"
        ) from None


# ----------------------------------------------------------------------------------------------------------------
# fitting


@dataclass
class ModelFit:
    """Result of fitting one model.

    Attributes
    ----------
    model : model name.
    params : fitted parameters by name (moduli in Pa, exponents dimensionless).
    initial_shear_modulus : small-strain shear modulus implied by the fit, Pa.
    mape : mean absolute percentage error over the fitted points with stress > 0, percent.
    n_points : number of points the fit used (strain > 0, and stress > 0 with relative weighting).
    max_strain : largest strain fitted (dimensionless).
    weighting : 'relative' or 'absolute' residuals.
    """

    model: str
    params: dict[str, float]
    initial_shear_modulus: float
    mape: float
    n_points: int
    max_strain: float
    weighting: str

    def stress(self, strain) -> np.ndarray:
        """Fitted nominal stress (Pa) at engineering ``strain``."""
        return uniaxial_stress(self.model, self.params, strain)

    def to_json(self) -> dict:
        """The ``{"params", "initial_shear_modulus", "mape"}`` record of the ``--json`` output."""
        return {
            "params": {k: float(v) for k, v in self.params.items()},
            "initial_shear_modulus": float(self.initial_shear_modulus),
            "mape": float(self.mape),
        }


def mape(model_stress, data_stress) -> float:
    """Mean absolute percentage error (percent) over the points with data_stress > 0 (seed 001 Table II)."""
    model_stress = np.asarray(model_stress, dtype=np.float64)
    data_stress = np.asarray(data_stress, dtype=np.float64)
    ok = data_stress > 0
    if not np.any(ok):
        return float("nan")
    return float(100.0 * np.mean(np.abs(model_stress[ok] - data_stress[ok]) / data_stress[ok]))


def _weights(stress, weighting: str, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """(mask of points used, weight of each used residual) for nondimensional stress."""
    if weighting == "relative":
        # relative residuals: least squares then balances small and large strains the way MAPE does, and is the
        # maximum-likelihood choice when the noise is proportional to the load (load-cell % of reading)
        use = stress > 0
        return use, 1.0 / (stress[use] / scale)
    if weighting == "absolute":
        use = np.ones(stress.shape, dtype=bool)
        return use, np.ones(int(use.sum()))
    raise CharacterizationDataError(f"unknown weighting {weighting!r}; choose 'relative' or 'absolute'")


def _fit_linear_in_params(model: HyperelasticModel, lam, y, w):
    """Bounded linear least squares through scipy's least_squares (exact Jacobian, data already scaled)."""
    A = model.basis(lam) * w[:, None]
    b = y * w
    x0, *_ = np.linalg.lstsq(A, b, rcond=None)
    lo, hi = np.array(model.lower), np.array(model.upper)
    x0 = np.clip(x0, np.where(np.isfinite(lo), lo + 1e-12, lo), np.where(np.isfinite(hi), hi - 1e-12, hi))
    res = least_squares(lambda x: A @ x - b, x0, jac=lambda x: A, bounds=(lo, hi), method="trf", x_scale="jac")
    return res.x


def _ogden_mu_for_alpha(alpha, lam, y, w):
    """Best mu for fixed exponents (the variable-projection inner problem), with mu_i alpha_i >= 0.

    The sign condition is Ogden's sufficient condition for a stable material (each term convex); it also stops
    two nearly equal exponents with opposite-sign, huge mu from mimicking an extra basis function.
    """
    sign = np.where(np.asarray(alpha) < 0, -1.0, 1.0)
    A = np.stack([s * ogden_term(a, lam) for s, a in zip(sign, alpha)], axis=1) * w[:, None]
    b = y * w
    # rescale columns so NNLS sees comparable magnitudes (large-exponent columns can be 1e6 x the others)
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    s_mu, _ = nnls(A / norms, b, maxiter=50 * A.shape[1])
    s_mu = s_mu / norms
    return sign * s_mu, A @ s_mu - b


# Start exponents: every triple of distinct values from this grid is scored by variable projection and the best
# few are refined. Rubber and silicone fits put one exponent near 1-3, one large positive and one negative.
_OGDEN_ALPHA_GRID = (-10.0, -6.0, -4.0, -2.0, -1.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0)
_OGDEN_REFINED_STARTS = 6
_ALPHA_MIN = 0.05  # |alpha| floor: keeps each exponent on the sign side of its start (alpha = 0 is a null term)


def _fit_ogden(model: HyperelasticModel, lam, y, w, n_starts: int = _OGDEN_REFINED_STARTS):
    """Multi-start Ogden fit: variable projection on the exponents from the best grid triples, then a joint
    least-squares polish of (mu, alpha) with mu_i alpha_i >= 0. Returns the parameter vector (nondimensional mu)."""
    scored = []
    for triple in itertools.combinations(_OGDEN_ALPHA_GRID, 3):
        _, r = _ogden_mu_for_alpha(triple, lam, y, w)
        scored.append((float(r @ r), triple))
    scored.sort(key=lambda t: t[0])
    best = None
    for _, triple in scored[:n_starts]:
        a0 = np.array(triple)
        neg = a0 < 0
        a_lo = np.where(neg, -_ALPHA_BOUND, _ALPHA_MIN)
        a_hi = np.where(neg, -_ALPHA_MIN, _ALPHA_BOUND)
        vp = least_squares(
            lambda a: _ogden_mu_for_alpha(a, lam, y, w)[1], a0, bounds=(a_lo, a_hi), method="trf", x_scale=1.0
        )
        mu, _ = _ogden_mu_for_alpha(vp.x, lam, y, w)
        mu_lo = np.where(neg, -_MU_BOUND, 0.0)
        mu_hi = np.where(neg, 0.0, _MU_BOUND)
        lo = np.empty(6)
        hi = np.empty(6)
        x0 = np.empty(6)
        lo[0::2], lo[1::2] = mu_lo, a_lo
        hi[0::2], hi[1::2] = mu_hi, a_hi
        x0[0::2], x0[1::2] = mu, vp.x
        # least_squares needs a strictly feasible start; a term NNLS switched off sits on its bound
        span = hi - lo
        x0 = np.clip(x0, lo + 1e-10 * span, hi - 1e-10 * span)
        full = least_squares(
            lambda p: w * (_ogden_stress(p, lam) - y), x0, bounds=(lo, hi), method="trf", x_scale="jac"
        )
        if best is None or full.cost < best.cost:
            best = full
    x = best.x.copy()
    # terms are interchangeable; report them by increasing exponent so results compare across runs
    order = np.argsort(x[1::2])
    return np.concatenate([[x[2 * i], x[2 * i + 1]] for i in order])


def fit_model(
    data: TensileData,
    model: str,
    max_strain: float | None = None,
    weighting: str = "relative",
) -> ModelFit:
    """Fit one model to ``data`` (points with strain <= ``max_strain``; all when None).

    Parameters
    ----------
    data : the tensile data (strain dimensionless, stress Pa).
    model : one of :data:`MODEL_NAMES`.
    max_strain : largest engineering strain to fit, dimensionless (e.g. 1.0 for the paper's 100 % strain fit).
    weighting : 'relative' (residual divided by the measured stress; default) or 'absolute' (stress residual).

    Raises :class:`CharacterizationDataError` when fewer usable points than parameters remain.
    """
    m = get_model(model)
    if weighting not in ("relative", "absolute"):
        raise CharacterizationDataError(f"unknown weighting {weighting!r}; choose 'relative' or 'absolute'")
    sub = data.select(max_strain)
    # every model gives zero stress at zero strain, so such points carry no information about the parameters
    informative = TensileData(*(a[sub.strain > 0] for a in (sub.strain, sub.stress, sub.specimen)), sub.sources)
    scale = float(np.max(informative.stress)) if informative.stress.size else 0.0
    if scale > 0:
        use, w = _weights(informative.stress, weighting, scale)
    else:
        use, w = np.zeros(informative.stress.shape, dtype=bool), np.zeros(0)
    n_use = int(use.sum())
    if n_use < m.n_params:
        rng = "strain > 0" if max_strain is None else f"0 < strain <= {max_strain:g}"
        cond = ", stress > 0" if weighting == "relative" else ""
        raise CharacterizationDataError(
            f"{', '.join(data.sources)}: columns 'strain'/'stress' give {n_use} usable point(s) ({rng}{cond}) "
            f"but model {m.name!r} has {m.n_params} parameter(s); give more points or a larger --max-strain"
        )
    lam = 1.0 + informative.strain[use]
    y = informative.stress[use] / scale  # nondimensional stress keeps the solver's tolerances meaningful
    if m.basis is not None:
        x = _fit_linear_in_params(m, lam, y, w)
    else:
        x = _fit_ogden(m, lam, y, w)
    params = np.array(x, dtype=np.float64)
    is_modulus = np.array([n not in m.dimensionless for n in m.param_names])
    params[is_modulus] *= scale
    pdict = {n: float(v) for n, v in zip(m.param_names, params)}
    fitted = m.stress(params, sub.strain)
    return ModelFit(
        model=m.name,
        params=pdict,
        initial_shear_modulus=m.shear_modulus(params),
        mape=mape(fitted, sub.stress),
        n_points=n_use,
        max_strain=float(np.max(sub.strain)),
        weighting=weighting,
    )


def fit_models(
    data: TensileData,
    models: Sequence[str] = MODEL_NAMES,
    max_strain: float | None = None,
    weighting: str = "relative",
) -> dict[str, ModelFit]:
    """Fit each of ``models`` to ``data``; returns {model name: :class:`ModelFit`} in the order given."""
    return {name: fit_model(data, name, max_strain=max_strain, weighting=weighting) for name in models}


def youngs_modulus_per_specimen(data: TensileData, max_strain: float = 1.0, weighting: str = "relative"):
    """Young's modulus (Pa) of a linear fit up to ``max_strain`` for each specimen, as seed 001 Table II does
    with 100 % strain. Returns {specimen: E}."""
    out = {}
    for name in data.specimens:
        keep = data.specimen == name
        part = TensileData(data.strain[keep], data.stress[keep], data.specimen[keep], data.sources)
        out[name] = fit_model(part, "linear", max_strain=max_strain, weighting=weighting).params["E"]
    return out


def best_model(fits: dict[str, ModelFit]) -> str:
    """Name of the fit with the lowest MAPE."""
    return min(fits, key=lambda k: (np.nan_to_num(fits[k].mape, nan=np.inf), k))
