"""Non-dimensional Cosserat-rod multiple-shooting solver (internal).

Lengths are scaled by the rod length L, moments by E*I1/L and forces by E*I1/L^2, so every unknown is O(1)-O(100)
whatever the material. The state integrated along the rod is

    y = [p (3), m (3), R (3x3, row-major)]

with R the orientation (columns are the material directors d1, d2, d3) and m the internal moment in the global
frame (seed 003 eq 1). The equilibrium equations (seed 003 eqs 4-5, Rucker & Webster 2011) are

    p' = R v,   R' = R [u]x,   n' = -f,   m' = -p' x n - l,
    u = K_bt^-1 R^T m,   v = e3 (Kirchhoff)  or  v = K_se^-1 R^T n + e3 (extensible, shearable),

with f the distributed force (weight) and l the distributed couple (magnetic, seed 003 eqs 2-3).

* In a uniform field the only distributed force is the weight, which does not depend on the configuration, so
  n' = -f integrates in closed form, n(s) = F_tip + f (1 - s): only moments, positions and orientations are
  unknown.
* Single shooting from the clamp amplifies an error in m(0) roughly like exp(k s), k^2 the load in units of
  E I1 / L^2, which makes Newton's basin tiny for strong fields. The rod is therefore cut into segments, each
  integrated from its own unknown start state (multiple shooting); Newton drives the mismatches at the cuts
  and the free-end moment to zero. Segments, and the finite-difference copies needed for the Jacobian, are
  integrated side by side as one numpy batch with fixed-step RK4, so the map is smooth and deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Loads:
    """Non-dimensional load set; linear interpolation between two sets is the continuation path."""

    field: np.ndarray  # applied uniform field, T (the magnetic coefficient carries the scaling)
    force_per_length: np.ndarray  # f L^3 / (E I1)
    tip_force: np.ndarray  # F L^2 / (E I1)
    tip_moment: np.ndarray  # M L / (E I1)

    @staticmethod
    def zero() -> "Loads":
        return Loads(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))

    def lerp(self, other: "Loads", t: float) -> "Loads":
        return Loads(*(a + t * (b - a) for a, b in zip(self.astuple(), other.astuple())))

    def astuple(self):
        return (self.field, self.force_per_length, self.tip_force, self.tip_moment)

    def internal_force(self, sigma):
        """n(sigma) (non-dimensional, global frame) at arc lengths sigma in [0, 1]: n(1) = F, n' = -f."""
        sigma = np.asarray(sigma, dtype=np.float64)
        return self.tip_force + np.multiply.outer(1.0 - sigma, self.force_per_length)


@dataclass
class ShootingState:
    """Start states of the shooting segments (non-dimensional): positions p (S, 3), moments m (S, 3),
    orientations R (S, 3, 3). Segment 0 starts at the clamp, so only its moment is unknown."""

    p: np.ndarray
    m: np.ndarray
    R: np.ndarray

    def copy(self) -> "ShootingState":
        return ShootingState(self.p.copy(), self.m.copy(), self.R.copy())


class ConvergenceFailure(Exception):
    pass


def hat(v):
    """Cross-product matrices of vectors v (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=np.float64)
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def exp_rotation(phi):
    """Rotation matrices exp([phi]x) for rotation vectors phi (..., 3) (Rodrigues)."""
    phi = np.asarray(phi, dtype=np.float64)
    angle = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = hat(phi)
    small = angle < 1e-6
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


def log_rotation(R):
    """Rotation vectors of rotation matrices R (..., 3, 3), for angles below pi."""
    R = np.asarray(R, dtype=np.float64)
    w = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    cos = np.clip(0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    angle = np.arccos(cos)[..., None]
    sin = np.linalg.norm(w, axis=-1, keepdims=True)
    scale = np.where(sin < 1e-9, 1.0 + angle**2 / 6.0, angle / np.where(sin < 1e-9, 1.0, sin))
    return w * scale


def rotation_mismatch(Ra, Rb):
    """vee(skew(Ra^T Rb)): zero iff Ra = Rb (for differences below 90 degrees), ~ the rotation vector
    between them when small. Used as the orientation part of the continuity residual."""
    A = np.swapaxes(Ra, -1, -2) @ Rb
    return 0.5 * np.stack([A[..., 2, 1] - A[..., 1, 2], A[..., 0, 2] - A[..., 2, 0], A[..., 1, 0] - A[..., 0, 1]], -1)


class Shooter:
    """Integrates the rod equations on a fixed non-dimensional grid and solves the multiple-shooting problem.

    Args:
        nodes: output nodes in [0, 1] (sorted, first 0, last 1); Br may jump only at nodes.
        max_step: largest RK4 step (fraction of L); output intervals are subdivided to respect it.
        magnetic_coefficient: callable sigma -> (k, 3) array, A L^2 Br(sigma L) / (mu0 E I1) in 1/T.
        kbt_inv: (3,) inverse bending/torsion stiffness in units of E I1.
        kse_inv: (3,) inverse shear/extension stiffness in units of E I1 / L^2, or None (Kirchhoff rod).
        base_position: (3,) p(0) / L.  base_rotation: (3, 3) R(0).
        segments: number of shooting segments (fewer if there are fewer integration steps).
    """

    #: largest distance (units of L, and per director component) between the predicted and the converged
    #: tip state accepted in one continuation step
    max_tip_deviation = 0.1
    #: Newton iterations allowed per continuation step before the step is cut
    max_newton = 8

    def __init__(self, nodes, max_step, magnetic_coefficient, kbt_inv, kse_inv, base_position, base_rotation,
                 segments: int = 8):
        nodes = np.asarray(nodes, dtype=np.float64)
        sub = np.maximum(1, np.ceil(np.diff(nodes) / max_step - 1e-9).astype(int))
        steps = [np.linspace(a, b, k + 1)[:-1] for a, b, k in zip(nodes[:-1], nodes[1:], sub)]
        self.grid = np.concatenate(steps + [nodes[-1:]])
        self.nodes = nodes
        self.output_index = np.concatenate([[0], np.cumsum(sub)])
        h = np.diff(self.grid)
        n_steps = len(h)
        # Br is sampled just inside each step so that a segment boundary at a node is resolved exactly
        # (piecewise-constant profiles are integrated without the O(h) error of straddling a jump).
        eps = 1e-9 * h
        stage_s = np.stack([self.grid[:-1] + eps, self.grid[:-1] + 0.5 * h, self.grid[1:] - eps], axis=1)
        b_stage = np.asarray(magnetic_coefficient(stage_s.ravel()), dtype=np.float64).reshape(n_steps, 3, 3)
        # one padding step of zero length (index n_steps) lets segments of unequal step counts share a batch
        self.h = np.append(h, 0.0)
        self.stage_s = np.concatenate([stage_s, stage_s[-1:]])
        self.b_stage = np.concatenate([b_stage, np.zeros((1, 3, 3))])
        self.b_max = float(np.linalg.norm(b_stage, axis=-1).max()) if n_steps else 0.0
        n_seg = int(max(1, min(segments, n_steps)))
        self.bounds = np.round(np.linspace(0, n_steps, n_seg + 1)).astype(int)  # grid index of each cut
        self.n_seg = n_seg
        width = int(np.diff(self.bounds).max())
        idx = np.full((n_seg, width), n_steps)
        for j in range(n_seg):
            count = self.bounds[j + 1] - self.bounds[j]
            idx[j, :count] = np.arange(self.bounds[j], self.bounds[j + 1])
        self.step_index = idx  # (S, width) global step taken by segment j at its local step i
        self.kbt_inv = np.asarray(kbt_inv, dtype=np.float64)
        self.kse_inv = None if kse_inv is None else np.asarray(kse_inv, dtype=np.float64)
        # [u]x flattened row-major = u @ HAT; with u = K_bt^-1 (R^T m) the stiffness folds into the matrix
        hat_matrix = np.zeros((3, 9))
        for (row, col), (j, sign) in {(0, 1): (2, -1), (0, 2): (1, 1), (1, 0): (2, 1), (1, 2): (0, -1),
                                      (2, 0): (1, -1), (2, 1): (0, 1)}.items():
            hat_matrix[j, 3 * row + col] = sign
        self._hat_kbt = self.kbt_inv[:, None] * hat_matrix
        self.p0 = np.asarray(base_position, dtype=np.float64)
        self.R0 = np.asarray(base_rotation, dtype=np.float64)

    # --- integration -------------------------------------------------------------------------------------
    # Written for speed with small batches (numpy call overhead dominates, not flops):
    # * for the Kirchhoff rod p' = R e3 and m' = n x p' + B x (R b) are linear in R, so per step, stage and
    #   batch row both come from one product R_flat @ C with C (9, 6) assembled once per shot;
    # * R' = R [u]x with u = K_bt^-1 R^T m: [u]x, flattened, is linear in R^T m, (R^T m) @ HAT.
    def _rhs(self, y, C, force):
        R = y[:, 6:15].reshape(-1, 3, 3)
        mR = (y[:, None, 3:6] @ R)[:, 0, :]  # R^T m as a row
        dR = (R @ (mR @ self._hat_kbt).reshape(-1, 3, 3)).reshape(-1, 9)
        lin = (y[:, None, 6:15] @ C)[:, 0, :]
        if force is None:
            return np.concatenate([lin, dR], axis=1)
        # extensible: v = K_se^-1 R^T n + e3, p' = R v, and n x p' joins the magnetic term
        HnT, n = force
        v = self.kse_inv * (n[:, None, :] @ R)[:, 0, :]
        v[:, 2] += 1.0
        dp = (R @ v[:, :, None])[:, :, 0]
        return np.concatenate([dp, (dp[:, None, :] @ HnT)[:, 0, :] + lin, dR], axis=1)

    def _stage_operators(self, loads: Loads):
        """Per global step and RK4 stage: C with [p', m'] = R_flat @ C (Kirchhoff, C (9, 6)) or
        m' = R_flat @ C + n x p' (extensible, C (9, 3), with (Hn^T, n) returned for the force term)."""
        n_stage = loads.internal_force(self.stage_s)  # (steps + 1, 3, 3)
        Hn = hat(n_stage)
        HB = hat(np.asarray(loads.field, dtype=np.float64))
        # B x (R b) = HB R b: entry (a, l) of R meets HB[i, a] b[l]
        C = np.einsum("ia,stl->stali", HB, self.b_stage).reshape(*self.b_stage.shape[:2], 9, 3)
        if self.kse_inv is not None:
            return C, (np.swapaxes(Hn, -1, -2), n_stage)
        e3 = np.array([0.0, 0.0, 1.0])
        # n x (R e3) = Hn R e3
        C = C + np.einsum("stia,l->stali", Hn, e3).reshape(C.shape)
        select_d3 = np.einsum("ia,l->ali", np.eye(3), e3).reshape(9, 3)  # R_flat @ select_d3 = R e3
        return np.concatenate([np.broadcast_to(select_d3, C.shape), C], axis=-1), None

    def integrate(self, seg, y0, loads: Loads, keep: bool = False):
        """Integrate rows y0 (k, 15), row r over shooting segment seg[r]; returns the end states (k, 15), or
        with ``keep`` the states after every local step (width + 1, k, 15)."""
        # a diverging trial shot overflows; it then shows up as a non-finite residual, which Newton rejects
        with np.errstate(over="ignore", invalid="ignore"):
            C, force = self._stage_operators(loads)
            y = np.array(y0, dtype=np.float64)
            out = [y] if keep else None
            for i in range(self.step_index.shape[1]):
                g = self.step_index[seg, i]  # (k,) global step of each row
                h = self.h[g][:, None]
                c = C[g]  # (k, 3 stages, 9, 6)
                f = [None] * 3 if force is None else [(force[0][g, j], force[1][g, j]) for j in range(3)]
                k1 = self._rhs(y, c[:, 0], f[0])
                k2 = self._rhs(y + 0.5 * h * k1, c[:, 1], f[1])
                k3 = self._rhs(y + 0.5 * h * k2, c[:, 1], f[1])
                k4 = self._rhs(y + h * k3, c[:, 2], f[2])
                y = y + (h / 6.0) * (k1 + k4 + 2.0 * (k2 + k3))
                if keep:
                    out.append(y)
            return np.stack(out) if keep else y

    # --- states ------------------------------------------------------------------------------------------
    def straight_state(self) -> ShootingState:
        """The unloaded straight rod: the exact solution for zero loads."""
        s = self.grid[self.bounds[:-1]]
        p = self.p0 + s[:, None] * self.R0[:, 2]  # along d3 of the clamp
        return ShootingState(p, np.zeros((self.n_seg, 3)), np.repeat(self.R0[None], self.n_seg, axis=0))

    @staticmethod
    def _rows(p, m, R):
        return np.concatenate([p, m, R.reshape(-1, 9)], axis=1)

    def trajectory(self, state: ShootingState, loads: Loads) -> np.ndarray:
        """States (n_nodes, 15) at the output nodes, stitched from the segments."""
        traj = self.integrate(np.arange(self.n_seg), self._rows(state.p, state.m, state.R), loads, keep=True)
        g = self.output_index
        seg = np.clip(np.searchsorted(self.bounds, g, side="right") - 1, 0, self.n_seg - 1)
        return traj[g - self.bounds[seg], seg]

    # --- Newton ------------------------------------------------------------------------------------------
    def _residual_blocks(self, ends, starts_p, starts_m, starts_R, loads):
        """Continuity mismatches between segment j's end and segment j+1's start (9 each), then the free-end
        moment residual (3). ``ends`` (S, 15)."""
        R_end = ends[:, 6:15].reshape(-1, 3, 3)
        cont = np.concatenate([ends[:-1, 0:3] - starts_p[1:], ends[:-1, 3:6] - starts_m[1:],
                               rotation_mismatch(starts_R[1:], R_end[:-1])], axis=1)
        return np.concatenate([cont.ravel(), ends[-1, 3:6] - loads.tip_moment])

    def newton(self, state: ShootingState, loads: Loads, tol: float, max_iter: int = 8):
        """Newton's method on the multiple-shooting residual, in the strict form used inside continuation: a
        step that does not shrink the residual, or Newton corrections that do not contract by half, mean the
        guess lies outside the region of quadratic convergence, and the continuation step is cut instead of
        wandering (which is also how branch jumps start). One batched integration per iteration: every segment
        from its start state and from 9 perturbed copies (position, moment, rotation), for the Jacobian.
        Returns (state, |r|, iterations, tip state (15,), det of the Jacobian)."""
        S = self.n_seg
        st = state.copy()
        n_unknown = 3 + 9 * (S - 1)
        seg = np.repeat(np.arange(S), 10)
        prev_rn = prev_dn = None
        rn = np.inf
        for it in range(max_iter + 1):
            delta = 1e-7 * np.maximum(1.0, np.abs(np.concatenate([st.p, st.m], axis=1)))  # (S, 6)
            P = np.repeat(st.p[:, None], 10, axis=1)
            Mm = np.repeat(st.m[:, None], 10, axis=1)
            Rr = np.repeat(st.R[:, None], 10, axis=1)
            for c in range(3):
                P[:, 1 + c, c] += delta[:, c]
                Mm[:, 4 + c, c] += delta[:, 3 + c]
            dphi = 1e-7
            Rr[:, 7:10] = st.R[:, None] @ exp_rotation(dphi * np.eye(3))[None]
            ends = self.integrate(seg, self._rows(P.reshape(-1, 3), Mm.reshape(-1, 3), Rr.reshape(-1, 3, 3)),
                                  loads).reshape(S, 10, 15)
            r = self._residual_blocks(ends[:, 0], st.p, st.m, st.R, loads)
            rn = float(np.linalg.norm(r))
            if not np.isfinite(rn):
                raise ConvergenceFailure("non-finite residual")
            J = self._jacobian(ends, st, delta, dphi, loads, r)
            if rn < tol:
                return st, rn, it, ends[-1, 0], float(np.linalg.det(J))
            if prev_rn is not None and rn >= prev_rn:
                raise ConvergenceFailure(f"residual grew from {prev_rn:.3g} to {rn:.3g}")
            if it == max_iter:
                break
            try:
                dx = np.linalg.solve(J, -r)
            except np.linalg.LinAlgError:
                raise ConvergenceFailure("singular shooting Jacobian (bifurcation point?)") from None
            dn = float(np.linalg.norm(dx))
            if prev_dn is not None and dn > 0.5 * prev_dn and dn > 10 * tol:
                raise ConvergenceFailure(f"Newton corrections do not contract ({prev_dn:.3g} -> {dn:.3g})")
            prev_rn, prev_dn = rn, dn
            st.m[0] += dx[0:3]
            if S > 1:
                upd = dx[3:].reshape(S - 1, 9)
                st.p[1:] += upd[:, 0:3]
                st.m[1:] += upd[:, 3:6]
                st.R[1:] = st.R[1:] @ exp_rotation(upd[:, 6:9])
        raise ConvergenceFailure(f"no convergence in {max_iter} Newton iterations (residual {rn:.3g})")

    def _jacobian(self, ends, st, delta, dphi, loads, r):
        """Block-bidiagonal Jacobian of the residual w.r.t. [m_0, (p_j, m_j, phi_j) for j >= 1]."""
        S = self.n_seg
        n = 3 + 9 * (S - 1)
        J = np.zeros((n, n))
        col0 = lambda j: 0 if j == 0 else 3 + 9 * (j - 1)  # noqa: E731
        steps = np.concatenate([delta, np.full((S, 3), dphi)], axis=1)  # (S, 9)
        R_end = ends[:, :, 6:15].reshape(S, 10, 3, 3)
        # how each segment's end state moves with its own start unknowns
        for j in range(S):
            variants = range(3, 6) if j == 0 else range(9)
            if j < S - 1:
                base = np.concatenate([ends[j, 0, 0:3], ends[j, 0, 3:6], rotation_mismatch(st.R[j + 1], R_end[j, 0])])
                pert = np.concatenate([ends[j, 1:, 0:3], ends[j, 1:, 3:6],
                                       rotation_mismatch(st.R[j + 1][None], R_end[j, 1:])], axis=1)
                rows = slice(9 * j, 9 * j + 9)
            else:
                base, pert, rows = ends[j, 0, 3:6], ends[j, 1:, 3:6], slice(9 * (S - 1), 9 * (S - 1) + 3)
            d = (pert - base) / steps[j][:, None]  # (9, rows)
            for k, v in enumerate(variants):
                J[rows, col0(j) + k] = d[v]
        # how the mismatch at cut j-1 moves with segment j's start unknowns (no integration involved)
        for j in range(1, S):
            rows = slice(9 * (j - 1), 9 * j)
            c = col0(j)
            J[rows.start:rows.start + 3, c:c + 3] = -np.eye(3)
            J[rows.start + 3:rows.start + 6, c + 3:c + 6] = -np.eye(3)
            R_pert = st.R[j][None] @ exp_rotation(dphi * np.eye(3))
            base = rotation_mismatch(st.R[j], R_end[j - 1, 0])
            moved = rotation_mismatch(R_pert, R_end[j - 1, 0][None])
            J[rows.start + 6:rows.stop, c + 6:c + 9] = ((moved - base) / dphi).T
        return J

    # --- continuation ------------------------------------------------------------------------------------
    def _load_size(self, a: Loads, b: Loads | None = None, difference: bool = False) -> float:
        """Size of a load set (or of the change from a to b) in units of E I1 / L^2: the magnetic load
        k^2 = |b|max |B| plus the distributed force, tip force and tip moment."""
        parts = [x - y for x, y in zip(b.astuple(), a.astuple())] if difference else list(a.astuple())
        field, f, F, M = (np.linalg.norm(v) for v in parts)
        return float(self.b_max * field + f + F + M)

    @staticmethod
    def _extrapolate(a: ShootingState, b: ShootingState, ratio: float) -> ShootingState:
        """Secant predictor b + ratio (b - a), with orientations extrapolated on the rotation group."""
        rel = log_rotation(np.swapaxes(a.R, -1, -2) @ b.R)
        return ShootingState(b.p + ratio * (b.p - a.p), b.m + ratio * (b.m - a.m),
                             b.R @ exp_rotation(ratio * rel))

    def continuation(self, state: ShootingState, start: Loads, target: Loads, min_step: float = 1e-5):
        """Follow the equilibrium branch through ``state`` from the ``start`` loads to the ``target`` loads
        (linear path). Returns (state, residual, Newton iterations, continuation steps).

        Steps are accepted only if (i) Newton converges quickly from the predictor, (ii) the tip lands near
        the predicted tip and (iii) the determinant of the shooting Jacobian keeps its sign. The determinant
        vanishes exactly at bifurcation and fold points of the equilibrium problem (a non-trivial Jacobi field
        then satisfies the clamped-free boundary conditions), where stability is exchanged; a sign change
        therefore means the step crossed such a point or jumped to another (typically unstable) branch, like
        the straight rod in a field beyond the buckling field.
        """
        x = state.copy()
        # converge at the start loads (a no-op for an exact start) to get its tip and Jacobian sign
        x, _, iterations, tip, det0 = self.newton(x, start, 1e-9 * max(1.0, np.abs(x.m).max()), self.max_newton)
        sign0 = np.sign(det0)
        lam, dlam = 0.0, 1.0
        x_prev = tip_prev = lam_prev = None
        steps = 0
        # The determinant test sees only an odd number of crossings per step. Along a straight, compressed
        # rod the critical loads (k L)^2 = ((2j - 1) pi / 2)^2 are spaced by about 2 pi k L, so capping the load
        # change per step at 2 + pi sqrt(load) (in units of E I1 / L^2) lets at most one crossing fit in a step.
        load_rate = self._load_size(start, target, difference=True)
        residual = np.inf
        sign_flips = 0
        sel = [0, 1, 2, *range(6, 15)]  # tip position and orientation
        while lam < 1.0:
            cap = (2.0 + np.pi * np.sqrt(self._load_size(start.lerp(target, lam)))) / max(load_rate, 1e-300)
            dlam = min(dlam, cap)
            lam_try = min(1.0, lam + dlam)
            loads = start.lerp(target, lam_try)
            if x_prev is None:
                guess, tip_pred = x, tip
            else:
                ratio = (lam_try - lam) / (lam - lam_prev)
                guess, tip_pred = self._extrapolate(x_prev, x, ratio), tip + (tip - tip_prev) * ratio
            # intermediate points only have to be close enough to predict the next one
            tol = (1e-10 if lam_try == 1.0 else 1e-6) * max(1.0, np.abs(guess.m).max())
            try:
                x_new, res, its, tip_new, det = self.newton(guess, loads, tol, max_iter=self.max_newton)
                iterations += its
                # a converged step whose tip lands far from the predicted one has probably jumped to another
                # equilibrium branch; the deviation also measures how well the predictor works, so it sets
                # the next step size (it grows like dlam^2 for the secant predictor)
                dev = float(np.abs(tip_new - tip_pred)[sel].max())
                if sign0 != 0 and np.sign(det) != sign0:
                    sign_flips += 1
                    dev = np.inf
            except ConvergenceFailure:
                dev = np.inf
            if dev <= self.max_tip_deviation:
                x_prev, tip_prev, lam_prev = x, tip, lam
                x, tip, lam, residual = x_new, tip_new, lam_try, res
                steps += 1
                dlam = dlam * float(np.clip(0.9 * np.sqrt(self.max_tip_deviation / max(dev, 1e-12)), 0.5, 3.0))
            else:
                shrink = 0.5 if not np.isfinite(dev) else np.clip(0.9 * np.sqrt(self.max_tip_deviation / dev), 0.1, 0.5)
                dlam *= float(shrink)
                if dlam < min_step:
                    hint = (" The equilibrium branch reaches a bifurcation or fold point there (the shooting "
                            "Jacobian changes sign): past it the rod snaps or buckles. If the field opposes the "
                            "magnetisation, give a small transverse perturbation field to choose the side to "
                            "which the rod buckles." if sign_flips else "")
                    here = np.round(start.lerp(target, lam).field, 9).tolist()
                    raise ConvergenceFailure(
                        f"continuation stalled {100 * lam:.3g}% of the way, at field {here} T.{hint}")
        return x, residual, iterations, steps
