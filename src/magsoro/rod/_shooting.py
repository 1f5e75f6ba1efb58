"""Non-dimensional Cosserat-rod shooting solver (internal).

Lengths are scaled by the rod length L, moments by E*I1/L and forces by E*I1/L^2, so every unknown of the
shooting problem is O(1)-O(100) whatever the material. The state integrated along the rod is

    y = [p (3), R (3x3, row-major), m (3)]

with R the orientation (columns are the material directors d1, d2, d3) and m the internal moment in the global
frame (seed 003 eq 1). The equilibrium equations (seed 003 eqs 4-5, Rucker & Webster 2011) are

    p' = R v,   R' = R [u]x,   n' = -f,   m' = -p' x n - l,
    u = K_bt^-1 R^T m,   v = e3 (Kirchhoff)  or  v = K_se^-1 R^T n + e3 (extensible, shearable),

with f the distributed force (weight) and l the distributed couple (magnetic, seed 003 eqs 2-3).
In a uniform field the only distributed force is the weight, which does not depend on the configuration, so
n' = -f integrates in closed form, n(s) = F_tip + f (1 - s): the internal force is known and only the base
moment m(0) is unknown. It is found by Newton's method on the free-end residual m(1) - M_tip, integrating with
fixed-step RK4 so that the shooting map is a smooth deterministic function (finite-difference Jacobians are
then accurate to ~1e-7). The nominal shot and its 3 perturbed copies run as one numpy batch.
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


class ConvergenceFailure(Exception):
    pass


class Shooter:
    """Integrates the rod equations on a fixed non-dimensional grid and solves the shooting problem.

    Args:
        nodes: output nodes in [0, 1] (sorted, first 0, last 1); Br may jump only at nodes.
        max_step: largest RK4 step (fraction of L); output intervals are subdivided to respect it.
        magnetic_coefficient: callable sigma -> (k, 3) array, A L^2 Br(sigma L) / (mu0 E I1) in 1/T.
        kbt_inv: (3,) inverse bending/torsion stiffness in units of E I1.
        kse_inv: (3,) inverse shear/extension stiffness in units of E I1 / L^2, or None (Kirchhoff rod).
        base_position: (3,) p(0) / L.  base_rotation: (3, 3) R(0).
    """

    #: largest distance (units of L, and per director component) between the predicted and the converged
    #: tip state accepted in one continuation step
    max_tip_deviation = 0.1
    #: Newton iterations allowed per continuation step before the step is halved
    max_newton = 8

    def __init__(self, nodes, max_step, magnetic_coefficient, kbt_inv, kse_inv, base_position, base_rotation):
        nodes = np.asarray(nodes, dtype=np.float64)
        sub = np.maximum(1, np.ceil(np.diff(nodes) / max_step - 1e-9).astype(int))
        steps = [np.linspace(a, b, k + 1)[:-1] for a, b, k in zip(nodes[:-1], nodes[1:], sub)]
        self.grid = np.concatenate(steps + [nodes[-1:]])
        self.output_index = np.concatenate([[0], np.cumsum(sub)])
        self.nodes = nodes
        h = np.diff(self.grid)
        self.h = h
        # Br is sampled just inside each step so that a segment boundary at a node is resolved exactly
        # (piecewise-constant profiles are integrated without the O(h) error of straddling a jump).
        eps = 1e-9 * h
        stage_s = np.stack([self.grid[:-1] + eps, self.grid[:-1] + 0.5 * h, self.grid[1:] - eps], axis=1)
        self.stage_s = stage_s
        self.b_stage = np.asarray(magnetic_coefficient(stage_s.ravel()), dtype=np.float64).reshape(len(h), 3, 3)
        self.magnetised = bool(np.any(self.b_stage != 0.0))
        self.kbt_inv = np.asarray(kbt_inv, dtype=np.float64)
        self.kse_inv = None if kse_inv is None else np.asarray(kse_inv, dtype=np.float64)
        self.p0 = np.asarray(base_position, dtype=np.float64)
        self.R0 = np.asarray(base_rotation, dtype=np.float64)

    # --- integration -------------------------------------------------------------------------------------
    # The right-hand side is written for speed with tiny batches (numpy call overhead dominates): the moment
    # balance m' = n x p' + B x (R b) is linear in R for the Kirchhoff rod (p' = R e3), so per integration
    # stage it is one product R_flat @ C with C (9, 3) built once per shot; R' = R [u]x is one batched matmul.
    _HAT_INDEX = np.array([3, 2, 1, 2, 3, 0, 1, 0, 3])
    _HAT_SIGN = np.array([0.0, -1.0, 1.0, 1.0, 0.0, -1.0, -1.0, 1.0, 0.0])

    def _rhs(self, y, C, HnT):
        R = y[:, 3:12].reshape(-1, 3, 3)
        u = self.kbt_inv * (y[:, None, 12:15] @ R)[:, 0, :]  # K_bt^-1 R^T m
        U = np.concatenate([u, np.zeros((u.shape[0], 1))], axis=1)
        dR = (R @ (U[:, self._HAT_INDEX] * self._HAT_SIGN).reshape(-1, 3, 3)).reshape(-1, 9)
        if HnT is None:  # Kirchhoff: p' = d3, and C holds both the force and the magnetic couple terms
            return np.concatenate([y[:, [5, 8, 11]], dR, y[:, 3:12] @ C], axis=1)
        v = self.kse_inv * (HnT[1] @ R)  # K_se^-1 R^T n  (HnT[1] is n, (3,))
        v[:, 2] += 1.0
        dp = (R @ v[:, :, None])[:, :, 0]
        return np.concatenate([dp, dR, dp @ HnT[0] + y[:, 3:12] @ C], axis=1)

    @staticmethod
    def _hat(v):
        """Cross-product matrices of vectors v (..., 3) -> (..., 3, 3)."""
        z = np.zeros(v.shape[:-1])
        return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                         np.stack([v[..., 2], z, -v[..., 0]], -1),
                         np.stack([-v[..., 1], v[..., 0], z], -1)], -2)

    def _stage_operators(self, loads: Loads):
        """Per step and RK4 stage: C (9, 3) with m' = R_flat @ C (+ the force term for extensible rods)."""
        n_stage = loads.internal_force(self.stage_s)  # (steps, 3, 3)
        Hn = self._hat(n_stage)
        HB = self._hat(np.asarray(loads.field, dtype=np.float64))
        # B x (R b) = HB R b: entry (a, l) of R meets HB[i, a] b[l]
        C = np.einsum("ia,stl->stali", HB, self.b_stage)
        if self.kse_inv is None:
            # n x (R e3) = Hn R e3
            C = C + np.einsum("stia,l->stali", Hn, np.array([0.0, 0.0, 1.0]))
            return C.reshape(*C.shape[:2], 9, 3), None
        return C.reshape(*C.shape[:2], 9, 3), (np.swapaxes(Hn, -1, -2), n_stage)

    def integrate(self, M0, loads: Loads, keep: bool = False):
        """Integrate from s=0 to s=1 for each row of base moments M0 (k, 3); returns the tip states (k, 15),
        or with ``keep`` the states (n_nodes, k, 15) at the output nodes."""
        # a diverging trial shot overflows; it then shows up as a non-finite residual, which Newton rejects
        with np.errstate(over="ignore", invalid="ignore"):
            return self._integrate(M0, loads, keep)

    def _integrate(self, M0, loads: Loads, keep: bool):
        k = M0.shape[0]
        y = np.empty((k, 15))
        y[:, 0:3] = self.p0
        y[:, 3:12] = self.R0.ravel()
        y[:, 12:15] = M0
        C, force = self._stage_operators(loads)
        out = [y.copy()] if keep else None
        rhs = self._rhs
        for i, h in enumerate(self.h):
            c = C[i]
            if force is None:
                f0 = f1 = f2 = None
            else:
                f0, f1, f2 = ((force[0][i, j], force[1][i, j]) for j in range(3))
            k1 = rhs(y, c[0], f0)
            k2 = rhs(y + 0.5 * h * k1, c[1], f1)
            k3 = rhs(y + 0.5 * h * k2, c[1], f1)
            k4 = rhs(y + h * k3, c[2], f2)
            y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            if keep:
                out.append(y)
        if keep:
            return np.stack(out)[self.output_index]
        return y

    # --- shooting ----------------------------------------------------------------------------------------
    def newton(self, x0, loads: Loads, tol: float, max_iter: int = 8):
        """Newton's method on the free-end moment residual, in the strict form used inside continuation: a
        step that does not shrink the residual, or Newton corrections that do not contract by half each
        iteration, mean the guess lies outside the region of quadratic convergence, and the continuation step
        is cut instead of wandering (which is also how branch jumps start). One batched shot per iteration:
        the nominal shot and 3 finite-difference shots.
        Returns (x, |r|, iterations, tip state (15,), det of the shooting Jacobian d m(1) / d m(0))."""
        x = np.array(x0, dtype=np.float64)
        prev_rn = prev_dn = None
        for it in range(max_iter + 1):
            delta = 1e-7 * np.maximum(1.0, np.abs(x))
            X = np.repeat(x[None, :], 4, axis=0)
            X[np.arange(1, 4), np.arange(3)] += delta
            tip = self.integrate(X, loads)
            res = tip[:, 12:15] - loads.tip_moment
            r = res[0]
            rn = float(np.linalg.norm(r))
            if not np.isfinite(rn):
                raise ConvergenceFailure("non-finite residual")
            J = ((res[1:] - r) / delta[:, None]).T
            if rn < tol:
                return x, rn, it, tip[0], float(np.linalg.det(J))
            if prev_rn is not None and rn >= prev_rn:
                raise ConvergenceFailure(f"residual grew from {prev_rn:.3g} to {rn:.3g}")
            try:
                dx = np.linalg.solve(J, -r)
            except np.linalg.LinAlgError:
                raise ConvergenceFailure("singular shooting Jacobian (bifurcation point?)") from None
            dn = float(np.linalg.norm(dx))
            if prev_dn is not None and dn > 0.5 * prev_dn and dn > 10 * tol:
                raise ConvergenceFailure(f"Newton corrections do not contract ({prev_dn:.3g} -> {dn:.3g})")
            prev_rn, prev_dn = rn, dn
            x = x + dx
        raise ConvergenceFailure(f"no convergence in {max_iter} Newton iterations (residual {rn:.3g})")

    def continuation(self, x_start, start: Loads, target: Loads, min_step: float = 1e-5):
        """Follow the equilibrium branch through x_start from the ``start`` loads to the ``target`` loads
        (linear path). Returns (x, residual, Newton iterations, continuation steps).

        Steps are accepted only if (i) Newton converges quickly from the predictor, (ii) the tip lands near
        the predicted tip and (iii) the determinant of the shooting Jacobian d m(1)/d m(0) keeps its sign.
        The determinant vanishes exactly at bifurcation and fold points of the equilibrium problem (a
        non-trivial Jacobi field then satisfies the clamped-free boundary conditions), where stability is
        exchanged; a sign change therefore means the step crossed such a point or jumped to another
        (typically unstable) branch, like the straight rod in a field beyond the buckling field.
        """
        x = np.array(x_start, dtype=np.float64)
        _, _, _, tip, det0 = self.newton(x, start, np.inf)  # one shot: tip and Jacobian at the start
        sign0 = np.sign(det0)
        lam, dlam = 0.0, 1.0
        x_prev = tip_prev = lam_prev = None
        iterations = steps = 0
        residual = np.inf
        sign_flips = 0
        while lam < 1.0:
            lam_try = min(1.0, lam + dlam)
            loads = start.lerp(target, lam_try)
            # secant predictor along the branch once two points are known
            if x_prev is None:
                guess, tip_pred = x, tip
            else:
                ratio = (lam_try - lam) / (lam - lam_prev)
                guess, tip_pred = x + (x - x_prev) * ratio, tip + (tip - tip_prev) * ratio
            # intermediate points only have to be close enough to predict the next one
            tol = (1e-10 if lam_try == 1.0 else 1e-6) * max(1.0, np.linalg.norm(guess))
            try:
                x_new, res, its, tip_new, det = self.newton(guess, loads, tol, max_iter=self.max_newton)
                iterations += its
                # a converged step whose tip lands far from the predicted one has probably jumped to another
                # equilibrium branch; the deviation also measures how well the predictor works, so it sets
                # the next step size (it grows like dlam^2 for the secant predictor)
                dev = float(np.abs(tip_new[0:12] - tip_pred[0:12]).max())
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
                    raise ConvergenceFailure(f"continuation stalled at {100 * lam:.3g}% of the load step.{hint}")
        return x, residual, iterations, steps
