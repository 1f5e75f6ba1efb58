"""Magnetic moment of a small sample from forces and torques measured near a large cylindrical magnet
(seed 001 sec IV).

Physics (seed 001 eqs 1, 2, 7-10). The sample is a point dipole of moment m (A m^2) at its centre p (metres).
With the applied flux density B (tesla) of an axially magnetised cylinder and its gradient
G[i, j] = dB_i/dx_j (tesla/metre), both from :class:`magsoro.fields.cylinder.CylinderMagnet` (seed 001 uses the
multipole expansion to n = 17, eqs 3-4),

    F = G^T m            (eq 1, (m . grad) B; G is symmetric in a current-free region, eqs 5-6)
    tau = m x B = -[B]x m  (eq 2)

so [F; tau] = [G^T; -[B]x] m (eq 7) is linear in m. A sample measured in several orientations has one moment
S_m in its own frame, seen in the global frame as R_k S_m for orientation k (eq 10); torque-only data from a
single orientation cannot see the component of m along B, so seed 001 adds a second orientation rotated 90 deg
about the sample's y axis.

The moment follows from weighted nonlinear least squares (scipy ``least_squares``; each residual is divided by
the sensor noise so forces in N and torques in N m weigh by their information). The covariance of m is
``s^2 (J^T J)^-1`` with J the weighted Jacobian and s^2 the reduced chi-square, so the uncertainty reflects the
actual scatter. Magnetisation and remanence are |m|/V and mu0 |m|/V (eqs 8-9).

CSV format of the measurements (header names case-insensitive, one row per measurement):

=========== ============================================================================ =========
column      meaning                                                                      unit
=========== ============================================================================ =========
x, y, z     sample centre in the global frame (the magnet pose is given separately)      m
fx, fy, fz  force on the sample (not needed with torque-only fits)                       N
tx, ty, tz  torque on the sample about its centre                                        N m
orientation optional integer id of the sample orientation (default 0 = identity)         --
repetition  optional integer id of the repeated scan (default: k-th visit of a position) --
=========== ============================================================================ =========
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from magsoro.constants import MU0
from magsoro.characterization.csvfiles import read_columns
from magsoro.characterization.errors import CharacterizationDataError

# ATI Nano17 resolution used as the default noise level (one count). Seed 001 names the sensor (Nano17 Titanium)
# but gives no resolution; these are ATI's published figures for the Nano17 SI-12-0.12 calibration (1/320 N and
# 1/64 N mm). They are assumptions: take the numbers from your own sensor's calibration sheet.
NANO17_FORCE_RESOLUTION = 1.0 / 320.0  # N
NANO17_TORQUE_RESOLUTION = 1.0 / 64.0 * 1e-3  # N m

POSITION_DECIMALS = 6  # positions equal to 1 um are one position when averaging repetitions


# ----------------------------------------------------------------------------------------------------------------
# data


@dataclass(frozen=True)
class ForceTorqueData:
    """Force/torque measurements on a magnetised sample.

    Attributes
    ----------
    position : (N, 3) sample centre, m.
    force : (N, 3) force on the sample, N; NaN where not measured (torque-only data).
    torque : (N, 3) torque on the sample about its centre, N m.
    orientation : (N,) integer orientation id (0 = sample frame equals the global frame).
    repetition : (N,) integer id of the repeated scan.
    source : where the data came from.
    """

    position: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    orientation: np.ndarray
    repetition: np.ndarray
    source: str = "<array>"

    @property
    def has_force(self) -> bool:
        return bool(np.all(np.isfinite(self.force)))

    @classmethod
    def from_arrays(cls, position, force=None, torque=None, orientation=None, repetition=None, source="<array>"):
        """Build a data set from arrays (m, N, N m). ``force`` may be None for torque-only data.

        Repetitions default to the k-th occurrence of each (orientation, position).
        """
        position = np.asarray(position, dtype=np.float64).reshape(-1, 3)
        n = len(position)
        if torque is None:
            raise CharacterizationDataError(f"{source}: torque columns 'tx', 'ty', 'tz' are required")
        torque = np.asarray(torque, dtype=np.float64).reshape(-1, 3)
        force = np.full((n, 3), np.nan) if force is None else np.asarray(force, dtype=np.float64).reshape(-1, 3)
        if len(torque) != n or len(force) != n:
            raise CharacterizationDataError(f"{source}: position, force and torque columns differ in length")
        orientation = np.zeros(n, dtype=int) if orientation is None else _as_int(orientation, "orientation", source)
        if repetition is None:
            repetition = _occurrence_index(orientation, position)
        else:
            repetition = _as_int(repetition, "repetition", source)
        return cls(position, force, torque, orientation, repetition, source)


def _as_int(values, column, source) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64).ravel()
    bad = np.flatnonzero(v != np.round(v))
    if bad.size:
        raise CharacterizationDataError(
            f"{source}: column {column!r} must hold integer ids; row {bad[0] + 1} has {v[bad[0]]:g}"
        )
    return v.astype(int)


def _position_keys(position) -> list[tuple]:
    return [tuple(row) for row in np.round(position, POSITION_DECIMALS)]


def _occurrence_index(orientation, position) -> np.ndarray:
    seen: dict = {}
    out = np.empty(len(orientation), dtype=int)
    for i, key in enumerate(zip(orientation.tolist(), _position_keys(position))):
        out[i] = seen.get(key, 0)
        seen[key] = out[i] + 1
    return out


def read_force_torque_csv(path: str | Path, require_force: bool = True) -> ForceTorqueData:
    """Read a force/torque CSV (columns in the module docstring).

    Raises :class:`CharacterizationDataError` naming the file and column for missing columns or bad values.
    """
    force_cols = ("fx", "fy", "fz")
    required = ("x", "y", "z", "tx", "ty", "tz") + (force_cols if require_force else ())
    optional = ("orientation", "repetition") + (() if require_force else force_cols)
    cols = read_columns(path, required, optional)
    present_force = [c for c in force_cols if c in cols]
    if 0 < len(present_force) < 3:
        missing = [c for c in force_cols if c not in cols]
        raise CharacterizationDataError(f"{path}: force column(s) {', '.join(map(repr, missing))} missing")
    pos = np.stack([cols["x"], cols["y"], cols["z"]], axis=1)
    torque = np.stack([cols["tx"], cols["ty"], cols["tz"]], axis=1)
    force = np.stack([cols[c] for c in force_cols], axis=1) if present_force else None
    return ForceTorqueData.from_arrays(
        pos, force, torque, cols.get("orientation"), cols.get("repetition"), source=str(path)
    )


# ----------------------------------------------------------------------------------------------------------------
# orientations


def rotation_matrix(axis: str | Sequence[float], angle_deg: float) -> np.ndarray:
    """Rotation by ``angle_deg`` degrees about ``axis`` ('x', 'y', 'z' or a 3-vector), right-handed."""
    if isinstance(axis, str):
        try:
            a = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}[axis.lower()]
        except KeyError:
            raise CharacterizationDataError(f"rotation axis must be x, y or z, got {axis!r}") from None
        a = np.array(a)
    else:
        a = np.asarray(axis, dtype=np.float64)
        a = a / np.linalg.norm(a)
    t = np.deg2rad(angle_deg)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * (K @ K)


def parse_orientations(spec: str | None) -> dict[int, np.ndarray]:
    """Parse ``"ID:AXIS:DEG,..."`` (e.g. ``"1:y:90"``) into {id: rotation sample -> global}.

    Orientation 0 is the identity unless given. Seed 001's second orientation is ``1:y:90``.
    """
    out = {0: np.eye(3)}
    if not spec:
        return out
    for item in spec.split(","):
        item = item.strip()
        if not item:
            continue
        parts = item.split(":")
        if len(parts) != 3:
            raise CharacterizationDataError(
                f"--orientations: {item!r} is not ID:AXIS:DEGREES (e.g. 1:y:90 for 90 deg about the sample's y axis)"
            )
        try:
            oid, deg = int(parts[0]), float(parts[2])
        except ValueError:
            raise CharacterizationDataError(
                f"--orientations: {item!r} needs an integer ID and a number of degrees"
            ) from None
        out[oid] = rotation_matrix(parts[1].strip(), deg)
    return out


# ----------------------------------------------------------------------------------------------------------------
# noise filtering of seed 001 sec IV-A-2


def zero_quiet_axes(data: ForceTorqueData, magnet_position=(0.0, 0.0, 0.0), fraction: float = 1.0 / 3.0):
    """Seed 001's first filter: "the difference between each two positions was averaged for each axis of the
    measured F and tau. In case an axis' average was below a third of the maximum average recorded, the axis was
    zeroed."

    Per scan (orientation, repetition) the positions are sorted by distance from the magnet, the signed
    differences between consecutive positions are averaged for each axis, and every axis of F (of tau) whose
    absolute average is below ``fraction`` of the largest one of F (of tau) is set to zero. An axis the magnet
    drives decays steadily with distance, so its differences add up; on an axis that carries only sensor noise
    they cancel. (Averaging absolute differences instead would not separate them: at 31 cm the force signal
    changes by about one Nano17 count per centimetre.) Returns a new :class:`ForceTorqueData` and the boolean
    mask (N, 6) of zeroed entries (F then tau).
    """
    force = data.force.copy()
    torque = data.torque.copy()
    zeroed = np.zeros((len(force), 6), dtype=bool)
    dist = np.linalg.norm(data.position - np.asarray(magnet_position, dtype=np.float64), axis=1)
    for key in sorted(set(zip(data.orientation.tolist(), data.repetition.tolist()))):
        idx = np.flatnonzero((data.orientation == key[0]) & (data.repetition == key[1]))
        if idx.size < 2:
            continue
        idx = idx[np.argsort(dist[idx], kind="stable")]
        for k, arr in enumerate((force, torque)):
            if not np.all(np.isfinite(arr[idx])):
                continue
            step = np.abs(np.mean(np.diff(arr[idx], axis=0), axis=0))
            quiet = step < fraction * step.max()
            arr[np.ix_(idx, np.flatnonzero(quiet))] = 0.0
            zeroed[np.ix_(idx, 3 * k + np.flatnonzero(quiet))] = True
    return ForceTorqueData(data.position, force, torque, data.orientation, data.repetition, data.source), zeroed


@dataclass(frozen=True)
class AveragedData:
    """Measurements averaged over repetitions at each (orientation, position).

    position (M, 3) m; force, torque (M, 3) means (N, N m); force_std, torque_std (M, 3) sample standard
    deviations across repetitions (0 with a single repetition); orientation (M,); count (M,) repetitions;
    use_force, use_torque (M,) whether the point's force / torque enters the fit.
    """

    position: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    force_std: np.ndarray
    torque_std: np.ndarray
    orientation: np.ndarray
    count: np.ndarray
    use_force: np.ndarray
    use_torque: np.ndarray


def average_repetitions(data: ForceTorqueData, max_relative_std: float | None = None) -> AveragedData:
    """Average repeated measurements per (orientation, position); with ``max_relative_std`` apply seed 001's
    second filter: a point's force (torque) is dropped when the norm of its standard deviation across
    repetitions exceeds ``max_relative_std`` (seed: a third) times the norm of its mean force (torque)."""
    keys = list(zip(data.orientation.tolist(), _position_keys(data.position)))
    groups: dict = {}
    for i, k in enumerate(keys):
        groups.setdefault(k, []).append(i)
    rows = list(groups.values())
    M = len(rows)
    pos = np.array([data.position[r].mean(axis=0) for r in rows])
    ori = np.array([data.orientation[r[0]] for r in rows], dtype=int)
    cnt = np.array([len(r) for r in rows])

    def stats(arr):
        mean = np.array([arr[r].mean(axis=0) for r in rows])
        std = np.array([arr[r].std(axis=0, ddof=1) if len(r) > 1 else np.zeros(3) for r in rows])
        return mean, std

    f_mean, f_std = stats(data.force)
    t_mean, t_std = stats(data.torque)
    use_f = np.all(np.isfinite(f_mean), axis=1)
    use_t = np.ones(M, dtype=bool)
    if max_relative_std is not None:
        with np.errstate(invalid="ignore"):
            use_f &= ~(np.linalg.norm(f_std, axis=1) > max_relative_std * np.linalg.norm(f_mean, axis=1))
            use_t &= ~(np.linalg.norm(t_std, axis=1) > max_relative_std * np.linalg.norm(t_mean, axis=1))
    return AveragedData(pos, f_mean, t_mean, f_std, t_std, ori, cnt, use_f, use_t)


# ----------------------------------------------------------------------------------------------------------------
# model and fit


def skew(v) -> np.ndarray:
    """(N, 3, 3) skew matrices [v]x with [v]x w = v x w."""
    v = np.atleast_2d(v)
    z = np.zeros(len(v))
    return np.stack(
        [
            np.stack([z, -v[:, 2], v[:, 1]], -1),
            np.stack([v[:, 2], z, -v[:, 0]], -1),
            np.stack([-v[:, 1], v[:, 0], z], -1),
        ],
        axis=1,
    )


def force_torque_matrices(field_source, positions, rotations) -> tuple[np.ndarray, np.ndarray]:
    """Matrices mapping the sample-frame moment (A m^2) to force (N) and torque (N m), seed 001 eqs 7 and 10.

    ``rotations`` is (N, 3, 3), sample frame -> global frame at each point. Returns (AF, AT), each (N, 3, 3), with
    F = AF @ m_S and tau = AT @ m_S.
    """
    B = field_source.B(positions)
    G = field_source.grad_B(positions)
    AF = np.einsum("nji,njk->nik", G, rotations)  # G^T R
    AT = -np.einsum("nij,njk->nik", skew(B), rotations)  # -[B]x R
    return AF, AT


def predict_force_torque(field_source, positions, moment, rotations=None) -> tuple[np.ndarray, np.ndarray]:
    """Force (N, 3) in N and torque (N, 3) in N m on a point dipole of sample-frame ``moment`` (A m^2) at
    ``positions`` (N, 3) m in the field of ``field_source``; ``rotations`` (N, 3, 3) sample -> global (identity
    when None)."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if rotations is None:
        rotations = np.broadcast_to(np.eye(3), (len(positions), 3, 3))
    AF, AT = force_torque_matrices(field_source, positions, rotations)
    m = np.asarray(moment, dtype=np.float64)
    return AF @ m, AT @ m


@dataclass
class MagnetizationFit:
    """Result of :func:`fit_magnetization` (SI units).

    moment : (3,) fitted moment in the sample frame (orientation 0), A m^2; moment_cov its (3, 3) covariance.
    moment_norm, moment_norm_std : |m| and its standard uncertainty, A m^2.
    direction : unit vector of m; direction_std_deg: standard angular uncertainty of the direction, degrees.
    volume : sample volume given, m^3 (None if not given); then magnetization (|m|/V, A/m, eq 8) and remanence
    (mu0 |m| / V, tesla, eq 9) with their standard uncertainties, else None.
    mape : mean absolute percentage error of model vs data (percent) over the driven components (see
    :func:`_driven_mask`); rms_force (N) and rms_torque (N m) the residual RMS of the fitted components.
    n_force, n_torque : number of force / torque components fitted.
    data : the repetition-averaged (and filtered) measurements that were fitted.
    model_force, model_torque : (M, 3) fitted model at the points of ``data``, N and N m.
    """

    moment: np.ndarray
    moment_cov: np.ndarray
    moment_norm: float
    moment_norm_std: float
    direction: np.ndarray
    direction_std_deg: float
    volume: float | None
    magnetization: float | None
    magnetization_std: float | None
    remanence: float | None
    remanence_std: float | None
    mape: float
    rms_force: float | None
    rms_torque: float
    n_force: int
    n_torque: int
    data: AveragedData | None = None
    model_force: np.ndarray | None = None
    model_torque: np.ndarray | None = None

    def to_json(self) -> dict:
        """Plain-JSON summary (SI units, names as in the attributes)."""

        def f(x):
            return None if x is None else float(x)

        return {
            "moment": [float(v) for v in self.moment],
            "moment_std": [float(v) for v in np.sqrt(np.diag(self.moment_cov))],
            "moment_norm": float(self.moment_norm),
            "moment_norm_std": float(self.moment_norm_std),
            "direction": [float(v) for v in self.direction],
            "direction_std_deg": float(self.direction_std_deg),
            "volume": f(self.volume),
            "magnetization": f(self.magnetization),
            "magnetization_std": f(self.magnetization_std),
            "remanence": f(self.remanence),
            "remanence_std": f(self.remanence_std),
            "mape": float(self.mape),
            "rms_force": f(self.rms_force),
            "rms_torque": float(self.rms_torque),
            "n_force": int(self.n_force),
            "n_torque": int(self.n_torque),
        }


def _axis_rms(values: np.ndarray) -> np.ndarray:
    """RMS of each column over the finite rows, broadcast to the shape of ``values``."""
    v = np.asarray(values, dtype=np.float64)
    ok = np.all(np.isfinite(v), axis=1)
    if not np.any(ok):
        return np.zeros(v.shape)
    return np.broadcast_to(np.sqrt(np.mean(v[ok] ** 2, axis=0)), v.shape).copy()


def _driven_mask(values: np.ndarray, orientation: np.ndarray, fraction: float = 1.0 / 3.0) -> np.ndarray:
    """Boolean (M, 3): components on axes whose per-orientation RMS is >= ``fraction`` of the largest axis RMS of
    that quantity over every orientation. MAPE over the other axes would be a ratio of noise to noise (seed 001
    Figs 5-6 show and score only the driven components); an orientation whose signal is all near zero (moment
    along B) contributes nothing."""
    rms = np.zeros(values.shape)
    for o in np.unique(orientation):
        rows = orientation == o
        rms[rows] = _axis_rms(values[rows])
    top = rms.max() if rms.size else 0.0
    if top == 0:
        return np.zeros(values.shape, dtype=bool)
    return rms >= fraction * top


def fit_magnetization(
    data: ForceTorqueData,
    field_source,
    orientations: Mapping[int, np.ndarray] | None = None,
    torque_only: bool = False,
    volume: float | None = None,
    force_noise: float = NANO17_FORCE_RESOLUTION,
    torque_noise: float = NANO17_TORQUE_RESOLUTION,
    zero_quiet_fraction: float | None = None,
    max_relative_std: float | None = None,
    magnet_position=None,
) -> MagnetizationFit:
    """Fit the sample moment to force/torque data (seed 001 eqs 7 and 10).

    Parameters
    ----------
    data : measurements (m, N, N m).
    field_source : the reference magnet, e.g. ``CylinderMagnet(0.1016, 0.1016, 1.48, axis=(1, 0, 0),
        model="multipole", order=17)``; anything with ``B(points)`` and ``grad_B(points)``.
    orientations : {orientation id: rotation sample -> global}; id 0 defaults to the identity.
    torque_only : fit torques only (seed 001 sec IV-B, needs two orientations for the full vector).
    volume : sample volume, m^3, for magnetisation and remanence.
    force_noise, torque_noise : standard deviation of one force (N) / torque (N m) reading, used as weights.
    zero_quiet_fraction : apply seed 001's axis-zeroing filter with this fraction (a third in the seed).
    max_relative_std : apply seed 001's repetition filter with this ratio (a third in the seed).
    magnet_position : magnet centre (m) for sorting scan positions by distance; defaults to
        ``field_source.position`` when it has one, else the origin.

    Raises :class:`CharacterizationDataError` when the data cannot determine m (too few points, an orientation
    id without a rotation, torque-only data from a single orientation, ...).
    """
    rots = {0: np.eye(3)}
    rots.update(dict(orientations or {}))
    unknown = sorted(set(data.orientation.tolist()) - set(rots))
    if unknown:
        raise CharacterizationDataError(
            f"{data.source}: column 'orientation' uses id(s) {', '.join(map(str, unknown))} with no rotation; "
            "give them with --orientations ID:AXIS:DEG (e.g. 1:y:90)"
        )
    if not torque_only and not data.has_force:
        raise CharacterizationDataError(
            f"{data.source}: force columns 'fx', 'fy', 'fz' are missing or incomplete; fit torques only "
            "(--torque-only) or supply forces"
        )
    if not (force_noise > 0 and torque_noise > 0):
        raise CharacterizationDataError("force and torque noise levels must be > 0")
    if magnet_position is None:
        magnet_position = getattr(field_source, "position", np.zeros(3))
    if zero_quiet_fraction is not None:
        data, _ = zero_quiet_axes(data, magnet_position, zero_quiet_fraction)
    avg = average_repetitions(data, max_relative_std)
    use_f = avg.use_force & (not torque_only)
    use_t = avg.use_torque
    R = np.stack([rots[o] for o in avg.orientation])
    AF, AT = force_torque_matrices(field_source, avg.position, R)

    # stack the weighted linear system; each component is one residual
    A = np.concatenate([AF[use_f].reshape(-1, 3) / force_noise, AT[use_t].reshape(-1, 3) / torque_noise])
    y = np.concatenate([avg.force[use_f].ravel() / force_noise, avg.torque[use_t].ravel() / torque_noise])
    n_f, n_t = 3 * int(use_f.sum()), 3 * int(use_t.sum())
    if len(y) <= 3:
        raise CharacterizationDataError(
            f"{data.source}: only {len(y)} force/torque component(s) left after filtering; 3 moment components "
            "need more measurements"
        )
    sv = np.linalg.svd(A, compute_uv=False)
    if sv[-1] < 1e-9 * sv[0]:
        hint = (
            " torque-only data from one orientation cannot see the moment component along B; measure a second "
            "orientation (seed 001 eq 10, e.g. --orientations 1:y:90)"
            if torque_only or not n_f
            else ""
        )
        raise CharacterizationDataError(f"{data.source}: the measurements do not determine all of m;{hint}")

    # the model is linear in m, so the linear solution is the optimum; least_squares polishes it and returns
    # the Jacobian the covariance is built from (the same route works for nonlinear extensions of the model)
    m0, *_ = np.linalg.lstsq(A, y, rcond=None)
    sol = least_squares(lambda m: A @ m - y, m0, jac=lambda m: A, method="lm")
    m = sol.x
    J = sol.jac
    dof = len(y) - 3
    s2 = float(sol.fun @ sol.fun) / dof if dof > 0 else 1.0
    cov = s2 * np.linalg.inv(J.T @ J)

    norm = float(np.linalg.norm(m))
    u = m / norm
    norm_std = float(np.sqrt(u @ cov @ u))
    # angular uncertainty: spread of m perpendicular to itself, divided by |m|
    P = np.eye(3) - np.outer(u, u)
    dir_std = float(np.degrees(np.sqrt(max(np.trace(P @ cov @ P), 0.0)) / norm))

    F_model = AF @ m
    T_model = AT @ m
    t_mask = _driven_mask(avg.torque, avg.orientation) & use_t[:, None] & (avg.torque != 0)
    masks = [(avg.torque, T_model, t_mask)]
    if not torque_only:
        f_mask = _driven_mask(np.where(use_f[:, None], avg.force, np.nan), avg.orientation)
        f_mask &= use_f[:, None] & (avg.force != 0)
        masks.append((avg.force, F_model, f_mask))
    errs = np.concatenate([np.abs(mod[k] - dat[k]) / np.abs(dat[k]) for dat, mod, k in masks])
    mape_val = float(100 * np.mean(errs)) if errs.size else float("nan")
    rms_t = float(np.sqrt(np.mean((T_model[use_t] - avg.torque[use_t]) ** 2)))
    rms_f = float(np.sqrt(np.mean((F_model[use_f] - avg.force[use_f]) ** 2))) if n_f else None

    if volume is not None:
        if not volume > 0:
            raise CharacterizationDataError(f"sample volume must be > 0 m^3, got {volume}")
        magnetization, magnetization_std = norm / volume, norm_std / volume
        remanence, remanence_std = MU0 * norm / volume, MU0 * norm_std / volume
    else:
        magnetization = magnetization_std = remanence = remanence_std = None
    return MagnetizationFit(
        moment=m,
        moment_cov=cov,
        moment_norm=norm,
        moment_norm_std=norm_std,
        direction=u,
        direction_std_deg=dir_std,
        volume=volume,
        magnetization=magnetization,
        magnetization_std=magnetization_std,
        remanence=remanence,
        remanence_std=remanence_std,
        mape=mape_val,
        rms_force=rms_f,
        rms_torque=rms_t,
        n_force=n_f,
        n_torque=n_t,
        data=avg,
        model_force=F_model,
        model_torque=T_model,
    )
