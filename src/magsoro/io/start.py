"""A run's final state as the start of another run (``magsoro run --from RUN_DIR``, ``[initial] from``).

final.npz (:meth:`magsoro.io.recorder.RunWriter.finish`) holds, besides the particle arrays of
:meth:`magsoro.simulation.Simulation.particles` (x, v, F, body, clamped and derived fields), what a run needs to
continue from it (:meth:`magsoro.simulation.Simulation.restart_arrays`): the affine velocities C, the Prony internal
stresses H (viscoelastic materials), the reference positions, the body names, the precision, the state's step count
and the particle speed the next time step is bounded by. :func:`read_start` reads it and checks it against the
bodies of the run that starts from it; every refusal is one line naming the file and what differs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from magsoro.errors import SceneError

#: reference positions of the two runs may differ by this fraction of the grid spacing (rounding; anything more is
#: another lattice: a body moved, resized or filled at another spacing)
REFERENCE_TOLERANCE = 1e-6
#: keys without which a file is not a state to start from
REQUIRED = ("x", "v", "F", "body", "time")


def start_file(path, key: str = "--from") -> Path:
    """The final.npz that ``path`` names: the file itself, or final.npz in the run folder ``path``. A folder with
    only last_good.npz (a failed run) is refused, naming it: that state is the one before a failure."""
    p = Path(path)
    if p.is_dir():
        if (p / "final.npz").is_file():
            return p / "final.npz"
        if (p / "last_good.npz").is_file():
            raise SceneError(f"{key}: {p} holds no final.npz, only last_good.npz (the run failed); name that file "
                             f"to start from the last good state before the failure")
        raise SceneError(f"{key}: {p} holds no final.npz (not a finished magsoro run)")
    if not p.is_file():
        raise SceneError(f"{key}: {p} not found")
    return p


def read_start(path, model, body_names, key: str = "--from") -> tuple[dict, list[str]]:
    """The state of ``path`` (a final.npz, or a run folder holding one) checked against ``model`` (its particles,
    bodies, reference positions, clamps, precision, Prony terms) and ``body_names``: (arrays, notes). Raises
    SceneError in one line naming the file and the first thing that differs."""
    p = start_file(path, key)
    where = f"{key}: {p}"
    try:
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as exc:  # not an npz, truncated, or holding objects
        raise SceneError(f"{where}: cannot be read as a state ({type(exc).__name__}: {exc})") from None
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise SceneError(f"{where}: holds no {', '.join(missing)} (not a magsoro final.npz)")
    notes = []
    n, dim = model.n_particles, model.dim
    x = data["x"]
    if x.ndim != 2 or x.shape[0] != n:
        raise SceneError(f"{where}: has {x.shape[0] if x.ndim else 0} particles, the scene's bodies {n}: the bodies differ")
    if x.shape[1] != dim:
        raise SceneError(f"{where}: is a {x.shape[1]}D state, the scene is {dim}D")
    names = [str(v) for v in data["body_names"]] if "body_names" in data else None
    if names is not None and names != list(body_names):
        raise SceneError(f"{where}: its bodies are {names}, the scene's {list(body_names)}")
    host = model.host
    if not np.array_equal(np.asarray(data["body"]), np.asarray(host["body"])):
        bad = int(np.count_nonzero(np.asarray(data["body"]) != np.asarray(host["body"])))
        raise SceneError(f"{where}: {bad} of {n} particles belong to another body than in the scene (bodies listed "
                         f"in another order, or other shapes)")
    if "clamped" in data and not np.array_equal(np.asarray(data["clamped"]) != 0, np.asarray(host["clamped"]) != 0):
        bad = int(np.count_nonzero((np.asarray(data["clamped"]) != 0) != (np.asarray(host["clamped"]) != 0)))
        raise SceneError(f"{where}: {bad} particles are clamped in one run and free in the other (the [[clamps]] differ)")
    if "reference_positions" in data:
        X = np.asarray(data["reference_positions"], dtype=np.float64)[:, :dim]
        gap = float(np.max(np.abs(X - np.asarray(host["positions"], dtype=np.float64)[:, :dim]), initial=0.0))
        if not gap <= REFERENCE_TOLERANCE * model.dx:
            raise SceneError(f"{where}: the particles' reference positions differ from the scene's by up to {gap:.3g} m "
                             f"(more than rounding, {REFERENCE_TOLERANCE:g} of dx): the bodies' shapes, places or "
                             f"simulation.dx differ")
    else:
        notes.append(f"{p} holds no reference positions (written by an older magsoro): the bodies were matched by "
                     f"particle count and body ids only")
    precision = str(data["precision"]) if "precision" in data else str(x.dtype)
    if precision != model.precision:
        if precision == "float64":
            raise SceneError(f"{where}: the state is float64 and this run float32, which would round it: set "
                             f"simulation.precision = 'float64'")
        notes.append(f"the state of {p} (float32) starts a float64 run: its values are widened exactly, their "
                     f"float32 rounding stays")
    F = data["F"]
    if F.shape != (n, dim, dim):
        raise SceneError(f"{where}: F has shape {F.shape}, expected {(n, dim, dim)}")
    if "C" not in data:
        data["C"] = np.zeros((n, dim, dim))
        notes.append(f"{p} holds no affine velocities C (written by an older magsoro): they start at zero")
    H = data.get("H")
    if model.viscous:
        terms = 1 + model.prony_terms
        if H is None:
            raise SceneError(f"{where}: holds no Prony internal stresses H, but the scene's materials have Prony terms "
                             f"(the materials differ)")
        if H.shape[:2] != (n, terms):
            raise SceneError(f"{where}: its Prony internal stresses have {H.shape[1]} columns, the scene's materials "
                             f"{terms} (1 + the Prony terms: the materials differ)")
        side = 3 if model.plane == "stress" else dim
        if H.shape[2:] != (side, side):
            raise SceneError(f"{where}: its Prony internal stresses are {tuple(H.shape[2:])} matrices, the scene's "
                             f"({side}, {side}) (simulation.plane differs: plane stress carries the thickness "
                             f"direction)")
    elif H is not None:
        raise SceneError(f"{where}: holds Prony internal stresses H, but the scene's materials have no Prony terms "
                         f"(the materials differ)")
    for k in ("x", "v", "F", "C") + (("H",) if H is not None else ()):
        if not np.all(np.isfinite(data[k])):
            raise SceneError(f"{where}: {k} holds values that are not finite")
    return data, notes
