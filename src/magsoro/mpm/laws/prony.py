"""Prony tables of viscoelastic materials (the scene key ``prony``) and their closed forms, without Warp: the
scene schema and ``magsoro fit-material`` read them; the engine side is :mod:`magsoro.mpm.laws.viscous`.

A table is [[g_1, tau_1], ..., [g_n, tau_n]], 1 <= n <= 3: g_i > 0 the fraction of the instantaneous shear
modulus that relaxes with time constant tau_i > 0 s, sum g_i < 1 (the long-term fraction g_inf = 1 - sum g_i).
"""

import math

import numpy as np

MAX_PRONY_TERMS = 3
"""Prony terms per material (the engine keeps 1 + MAX_PRONY_TERMS matrices per particle at most)."""


def prony_problem(terms) -> str | None:
    """What is wrong with a ``prony`` table [[g, tau], ...] (one line), or None."""
    if isinstance(terms, (str, bytes)) or not hasattr(terms, "__len__") or not 1 <= len(terms) <= MAX_PRONY_TERMS:
        return f"must be a table [[g, tau], ...] of 1 to {MAX_PRONY_TERMS} rows"
    total = 0.0
    for i, row in enumerate(terms):
        if isinstance(row, (str, bytes)) or not hasattr(row, "__len__") or len(row) != 2:
            return f"row {i} must be two numbers [g, tau], got {row!r}"
        try:
            g, tau = float(row[0]), float(row[1])
        except (TypeError, ValueError):
            return f"row {i} must be two numbers [g, tau], got {row!r}"
        if isinstance(row[0], bool) or isinstance(row[1], bool) or not (math.isfinite(g) and math.isfinite(tau)):
            return f"row {i} must be two finite numbers [g, tau], got {list(row)!r}"
        if not g > 0:
            return f"g must be > 0 (a fraction of the instantaneous shear modulus), got {g!r} in row {i}"
        if not tau > 0:
            return f"tau must be > 0 s, got {tau!r} in row {i}"
        total += g
    if not total < 1.0:
        return f"the g must sum to less than 1 (the long-term fraction 1 - sum g is > 0), got {total!r}"
    return None


def prony_table(terms) -> np.ndarray:
    """(n, 2) float64 table of a valid ``prony`` list; ValueError with :func:`prony_problem`'s line otherwise."""
    problem = prony_problem(terms)
    if problem is not None:
        raise ValueError(f"prony {problem}")
    return np.asarray(terms, dtype=np.float64).reshape(-1, 2)


def relaxation_modulus(terms, t, G0: float = 1.0):
    """Closed form G(t) = G0 (g_inf + sum g_i exp(-t/tau_i)) of a ``prony`` table (small strain)."""
    p = prony_table(terms)
    t = np.asarray(t, dtype=np.float64)
    return G0 * ((1.0 - p[:, 0].sum()) + sum(g * np.exp(-t / tau) for g, tau in p))


def dynamic_moduli(terms, omega, G0: float = 1.0):
    """Closed-form storage and loss moduli (G', G'') at angular frequencies ``omega`` (rad/s)."""
    p = prony_table(terms)
    w = np.asarray(omega, dtype=np.float64)
    storage = (1.0 - p[:, 0].sum()) + sum(g * (w * tau) ** 2 / (1.0 + (w * tau) ** 2) for g, tau in p)
    loss = sum(g * w * tau / (1.0 + (w * tau) ** 2) for g, tau in p)
    return G0 * storage, G0 * loss


def device_tables(terms_per_row):
    """Host (g, tau) tables, one row per Prony material (at least one row), padded to MAX_PRONY_TERMS columns
    (g 0, tau 1 s: a term that never grows), the engine's fixed-length vectors."""
    rows = max(len(terms_per_row), 1)
    g = np.zeros((rows, MAX_PRONY_TERMS))
    tau = np.ones((rows, MAX_PRONY_TERMS))
    for r, terms in enumerate(terms_per_row):
        p = prony_table(terms)
        g[r, : len(p)], tau[r, : len(p)] = p[:, 0], p[:, 1]
    return g, tau
