"""Magnet-path planning for a planar magnetic continuum robot (seed 004 sec II-C).

Pseudo-rigid-body (PRB) model. The robot, clamped at its base, is a chain of n rigid links of length l in the
x-y plane, joined by torsional springs. Joint j sits at arc length j l (joint 0 at the clamp) and the absolute
link angles are phi_j = phi_base + theta_0 + ... + theta_j. The joint stiffnesses come from the bending stiffness
EI of the material: a joint carries the compliance of the rod around it, l / EI for an inner joint and half of
it, l / (2 EI), for the clamp joint, so

    k_0 = 2 EI / l,    k_j = EI / l  (j >= 1).

With these the joints of a rod under a uniform bending moment lie exactly on a circle (the links are the chords
of the arc), which is the discretisation the targets use too. The tip half-link beyond the last joint is stiff;
its share of the bending is lost, which is small where the bending moment vanishes (free tip). Links may
optionally stretch (axial springs EA / l, the moment then carried by the material as m = F Br V0 / mu0).

Magnetic load. Link j carries the moment m_j = Br_j V_j / mu0, fixed in the link frame (the magnetisation
profile), spread over three Gauss points of the link. In a field B with gradient G (G_ik = dB_i/dx_k) a point
moment m at x receives the torque tau = m x B and the force f = G^T m (seed 000 eqs 15-16, as in the MPM
engine), so the total energy is

    U(theta) = 1/2 sum k_j theta_j^2 - sum_points m(theta) . B(x(theta))

and its gradient (the equilibrium equations) is

    dU/dtheta_j = k_j theta_j - sum_{points beyond joint j} [tau_z + ((x - J_j) x f)_z].

Equilibria are found from the previous configuration by pseudo-transient continuation of the gradient flow
(:meth:`PlanarPRB.equilibrium`): the overdamped path a damped robot takes, ending in the minimum it settles in.

Planning. A plan has K steps; at step k the first n_k links are everted and should take the target link angles
of that step (:class:`GrowthTarget`: follow-the-leader growth into an arc, or straight growth and then bending).
The external permanent magnet (EPM) is a point dipole of fixed |m| (seed 004 eq 14). Step by step, starting from
the previous step's equilibrium with the new links added straight (eversion), the pose is optimised by least
squares over

- the link-angle error of the equilibrium against the target (weight `shape`, RMS over links, per rad),
- the tip (last-link) angle error (weight `tip`, per rad),
- the out-of-plane field B_z at the links relative to the field scale (weight `out_of_plane`; seed 004 keeps
  H_z small for the Hall sensors),
- the pose change from the previous step (weight `smoothness`),
- the way there: the already everted links at the start and middle of the magnet's move, against the previous
  target blended into the new one (weight `path`; for follow-the-leader growth the body should not move),
- a stiffness margin: the smallest eigenvalue of the energy Hessian below `stability_margin` EI / l
  (weight `stability`), and the tip displacement when EI is `stiffness_uncertainty` lower (weight
  `robustness`): plans close to a fold of the equilibrium path cannot be followed by a real robot (or by the
  MPM replay, whose strip is a few per cent softer in bending than the Euler-Bernoulli PRB),
- a barrier keeping the magnet at least `min_distance` from every joint,

with the pose parametrised by its distance, azimuth and elevation from the robot base and, unless fixed, the
moment direction. With ``design_profile`` the magnetisation directions of the links everted in a step are
optimised with that step's pose and then kept (the seed's optimisation "computes both the magnetic profile and
the field sequence"). Every cost evaluation solves the PRB equilibrium, so a pose is judged by the shape it
really produces; the chosen pose is then re-checked along the magnet's actual path (:meth:`MagnetPlanner.follow`)
and a path that snaps through is rejected. The first step starts from the best of the axial EPM poses
(:func:`magsoro.fields.epm.epm_pose`, seed 004 eqs 15-16) giving `field_scale` in several in-plane directions at
the robot; a later step starts from the previous pose, then from the pose extrapolated from the last two, and
falls back to that multi-start if both miss the tip angle by more than the tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from magsoro.constants import MU0
from magsoro.fields.dipole import Dipole, dipole_field_force

_GAUSS_X = np.array([0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6)])
_GAUSS_W = np.array([5.0, 8.0, 5.0]) / 18.0


def plane_strain_modulus(shear_modulus: float, bulk_modulus: float) -> float:
    """E / (1 - nu^2) (Pa) of an isotropic solid with shear modulus G and bulk modulus K (Pa): the bending
    modulus of a strip in plane strain, as the 2D MPM engine models it."""
    G, K = float(shear_modulus), float(bulk_modulus)
    E = 9.0 * K * G / (3.0 * K + G)
    nu = (3.0 * K - 2.0 * G) / (2.0 * (3.0 * K + G))
    return E / (1.0 - nu * nu)


def strip_bending_stiffness(shear_modulus: float, bulk_modulus: float, thickness: float, depth: float) -> float:
    """EI (N m^2) of a plane-strain strip of in-plane ``thickness`` and out-of-plane ``depth`` (m)."""
    return plane_strain_modulus(shear_modulus, bulk_modulus) * thickness**3 * depth / 12.0


def tube_bending_stiffness(shear_modulus: float, inner_radius: float, outer_radius: float) -> float:
    """EI (N m^2) of an incompressible tube (E = 3 G) with radii A < B (m): 3 G pi (B^4 - A^4) / 4."""
    return 3.0 * shear_modulus * math.pi * (outer_radius**4 - inner_radius**4) / 4.0


@dataclass
class PlanarPRB:
    """Pseudo-rigid-body model of a planar magnetic robot clamped at ``base_position`` along ``base_angle``.

    link_length : l, m. bending_stiffness : EI, N m^2. link_moments : (n, 2) moment of each link in its own frame
    (x along the link towards the tip, y to its left), A m^2. base_position : (2,) m. base_angle : rad.
    plane_z : z of the robot plane for the field, m. axial_stiffness : EA (N) to let each link stretch along its
    axis (a prismatic spring of stiffness EA / l in series with the rigid link), or None for inextensible links.
    lateral_contraction : c in lambda_lateral = 1 - c e for a link strain e (-); with extensible links the
    magnetisation is carried by the material (m = F Br V0 / mu0, as in the MPM engine), so a link's moment
    grows by (1 + e) along the link and by (1 - c e) across it.

    A configuration q holds the joint angles theta (n,) (rad) and, when extensible, the link strains e (n,)
    after them: q = [theta, e], link j then being l (1 + e_j) long.
    """

    link_length: float
    bending_stiffness: float
    link_moments: np.ndarray
    base_position: np.ndarray = field(default_factory=lambda: np.zeros(2))
    base_angle: float = 0.0
    plane_z: float = 0.0
    axial_stiffness: float | None = None
    lateral_contraction: float = 0.0

    def __post_init__(self):
        self.link_moments = np.asarray(self.link_moments, dtype=float).reshape(-1, 2)
        self.base_position = np.asarray(self.base_position, dtype=float).reshape(2)
        if not (self.link_length > 0 and self.bending_stiffness > 0):
            raise ValueError("link_length and bending_stiffness must be > 0")
        if self.axial_stiffness is not None and not self.axial_stiffness > 0:
            raise ValueError("axial_stiffness must be > 0 N (or None)")

    @classmethod
    def strip(cls, length: float, n_links: int, thickness: float, depth: float, shear_modulus: float,
              bulk_modulus: float, remanence: float, magnetisation_angles=None, base_position=(0.0, 0.0),
              base_angle: float = 0.0, plane_z: float = 0.0, extensible: bool = False) -> "PlanarPRB":
        """PRB of a plane-strain strip (the 2D MPM body): EI from :func:`strip_bending_stiffness`, link moments
        Br V / mu0 (``remanence`` Br in T, one value or one per link) along ``magnetisation_angles`` (rad in the
        link frame, default 0 = axial) and, if ``extensible``, EA with the plane-strain modulus."""
        ell = length / n_links
        angles = np.zeros(n_links) if magnetisation_angles is None else np.asarray(magnetisation_angles, dtype=float)
        if angles.shape != (n_links,):
            raise ValueError(f"need {n_links} magnetisation angles, got {angles.shape}")
        br = np.broadcast_to(np.asarray(remanence, dtype=float), (n_links,))
        m = br * ell * thickness * depth / MU0
        moments = m[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        EA = plane_strain_modulus(shear_modulus, bulk_modulus) * thickness * depth if extensible else None
        # plane strain: a strip stretched by e along its axis narrows by nu / (1 - nu) e in the plane
        nu = (3.0 * bulk_modulus - 2.0 * shear_modulus) / (2.0 * (3.0 * bulk_modulus + shear_modulus))
        return cls(ell, strip_bending_stiffness(shear_modulus, bulk_modulus, thickness, depth), moments,
                   np.asarray(base_position, dtype=float), base_angle, plane_z, EA, nu / (1.0 - nu))

    @property
    def n_links(self) -> int:
        return len(self.link_moments)

    @property
    def extensible(self) -> bool:
        return self.axial_stiffness is not None

    def joint_stiffness(self, n: int | None = None) -> np.ndarray:
        """k_j (N m / rad) of the first ``n`` joints: 2 EI / l at the clamp, EI / l elsewhere."""
        n = self.n_links if n is None else n
        k = np.full(n, self.bending_stiffness / self.link_length)
        k[0] *= 2.0
        return k

    # -- configurations ------------------------------------------------------------------------------------
    def links_of(self, q) -> int:
        """Number of everted links of configuration q."""
        return len(q) // 2 if self.extensible else len(q)

    def split(self, q):
        """(theta (n,), strains e (n,)) of configuration q (zero strains when inextensible)."""
        q = np.asarray(q, dtype=float)
        n = self.links_of(q)
        return (q[:n], q[n:]) if self.extensible else (q, np.zeros(n))

    def straight(self, n: int) -> np.ndarray:
        """The unloaded straight configuration of n links."""
        return np.zeros(2 * n if self.extensible else n)

    def grow(self, q, n: int) -> np.ndarray:
        """Configuration q with links added up to n, each new one straight and unstrained (eversion)."""
        theta, e = self.split(q)
        add = n - len(theta)
        if add < 0:
            raise ValueError(f"cannot grow {len(theta)} links to {n}")
        theta = np.concatenate([theta, np.zeros(add)])
        return np.concatenate([theta, np.concatenate([e, np.zeros(add)])]) if self.extensible else theta

    def configuration(self, phi) -> np.ndarray:
        """Unstrained configuration with absolute link angles ``phi`` (rad)."""
        phi = np.asarray(phi, dtype=float)
        theta = np.diff(np.concatenate([[self.base_angle], phi]))
        return np.concatenate([theta, np.zeros(len(theta))]) if self.extensible else theta

    # -- kinematics ----------------------------------------------------------------------------------------
    def angles(self, q) -> np.ndarray:
        """Absolute link angles phi (rad) of configuration q."""
        return self.base_angle + np.cumsum(self.split(q)[0])

    def joints(self, q) -> np.ndarray:
        """Joint positions (n + 1, 2) in m, from the clamp to the tip, of configuration q."""
        theta, e = self.split(q)
        phi = self.base_angle + np.cumsum(theta)
        steps = (self.link_length * (1.0 + e))[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        return np.vstack([self.base_position, self.base_position + np.cumsum(steps, axis=0)])

    def load_points(self, q):
        """Gauss points of the links (P, 3) in m (z = plane_z), their moments (P, 3) in A m^2 and link index (P,)."""
        theta, e = self.split(q)
        n = len(theta)
        phi = self.base_angle + np.cumsum(theta)
        J = self.joints(q)
        c, s = np.cos(phi), np.sin(phi)
        u = np.stack([c, s], axis=1)
        nrm = np.stack([-s, c], axis=1)
        ell = self.link_length * (1.0 + e)
        x = J[:n, None, :] + (ell[:, None, None] * _GAUSS_X[None, :, None]) * u[:, None, :]
        mb = self.link_moments[:n]
        m_world = mb[:, 0:1] * u + mb[:, 1:2] * nrm
        m = m_world[:, None, :] * _GAUSS_W[None, :, None]
        P = n * len(_GAUSS_X)
        pts = np.zeros((P, 3))
        pts[:, :2] = x.reshape(P, 2)
        pts[:, 2] = self.plane_z
        mom = np.zeros((P, 3))
        mom[:, :2] = m.reshape(P, 2)
        return pts, mom, np.repeat(np.arange(n), len(_GAUSS_X))

    # -- energy and equilibrium -----------------------------------------------------------------------------
    @staticmethod
    def _field_terms(source, pts, mom, t):
        """B (P, 3) and f = G^T m (P, 3) at the load points; a closed form for a plain point dipole."""
        if type(source) is Dipole:
            return dipole_field_force(pts, mom, source.moment, source.position)
        B = source.B(pts, t)
        G = source.grad_B(pts, t)
        return B, np.einsum("pik,pi->pk", G, mom)

    def energy_gradient(self, q, source, t: float = 0.0):
        """U (J) and dU/dq for configuration q in the field of ``source`` (any
        :class:`~magsoro.fields.base.FieldSource`) at time t: joint moments (N m) and, when extensible, the
        derivatives with respect to the link strains (J).

        dU/dtheta_j = k_j theta_j - sum_{points beyond joint j} [tau_z + ((x - J_j) x f)_z],
        dU/de_j = EA l e_j - l u_j . (sum of f on the links beyond link j + sum of xi f on link j)
                  - (dm_j/de_j) . B,
        with xi the position of a point along its link as a fraction of the link length.
        """
        theta, e = self.split(q)
        n = len(theta)
        ell0 = self.link_length
        k = np.full(n, self.bending_stiffness / ell0)
        k[0] *= 2.0
        # kinematics inline (this runs thousands of times per planned step)
        phi = self.base_angle + np.cumsum(theta)
        c, s = np.cos(phi), np.sin(phi)
        ell = ell0 * (1.0 + e)
        jx = self.base_position[0] + np.concatenate([[0.0], np.cumsum(ell * c)])[:n]
        jy = self.base_position[1] + np.concatenate([[0.0], np.cumsum(ell * s)])[:n]
        q_pts = len(_GAUSS_X)
        pts = np.empty((n, q_pts, 3))
        pts[:, :, 0] = jx[:, None] + (ell * c)[:, None] * _GAUSS_X[None, :]
        pts[:, :, 1] = jy[:, None] + (ell * s)[:, None] * _GAUSS_X[None, :]
        pts[:, :, 2] = self.plane_z
        mb0 = self.link_moments[:n]
        if self.extensible:  # moments carried by the material (m = F Br V0 / mu0)
            mb = mb0 * np.stack([1.0 + e, 1.0 - self.lateral_contraction * e], axis=1)
        else:
            mb = mb0
        mom = np.zeros((n, q_pts, 3))
        mom[:, :, 0] = ((mb[:, 0] * c - mb[:, 1] * s)[:, None]) * _GAUSS_W[None, :]
        mom[:, :, 1] = ((mb[:, 0] * s + mb[:, 1] * c)[:, None]) * _GAUSS_W[None, :]
        pts = pts.reshape(n * q_pts, 3)
        mom = mom.reshape(n * q_pts, 3)
        B, f = self._field_terms(source, pts, mom, t)
        U = 0.5 * float(k @ (theta * theta)) - float(np.sum(mom * B))
        per = np.empty((n * q_pts, 4))
        per[:, 0] = mom[:, 0] * B[:, 1] - mom[:, 1] * B[:, 0]  # torque m x B
        per[:, 1] = pts[:, 0] * f[:, 1] - pts[:, 1] * f[:, 0]  # moment of the force about the origin
        per[:, 2:] = f[:, :2]
        link_sums = per.reshape(n, q_pts, 4).sum(axis=1)
        # sums over all links beyond each joint
        T, C, Fx, Fy = np.cumsum(link_sums[::-1], axis=0)[::-1].T
        grad_theta = k * theta - (T + C - (jx * Fy - jy * Fx))
        if not self.extensible:
            return U, grad_theta
        EAl = self.axial_stiffness * ell0
        U += 0.5 * EAl * float(e @ e)
        beyond_x = Fx - link_sums[:, 2]  # forces on the links strictly beyond link j
        beyond_y = Fy - link_sums[:, 3]
        own = (f[:, :2].reshape(n, q_pts, 2) * _GAUSS_X[None, :, None]).sum(axis=1)
        grad_e = EAl * e - ell0 * (c * (beyond_x + own[:, 0]) + s * (beyond_y + own[:, 1]))
        # the moment's own change with the strain: d(-m.B)/de = -(dm/de).B at the link's points
        Bl = (B[:, :2].reshape(n, q_pts, 2) * _GAUSS_W[None, :, None]).sum(axis=1)
        dm_x = mb0[:, 0] * c + self.lateral_contraction * mb0[:, 1] * s
        dm_y = mb0[:, 0] * s - self.lateral_contraction * mb0[:, 1] * c
        grad_e -= dm_x * Bl[:, 0] + dm_y * Bl[:, 1]
        return U, np.concatenate([grad_theta, grad_e])

    def equilibrium(self, source, theta0, t: float = 0.0, tol: float = 1e-11, max_iter: int = 400,
                    hessian=None) -> np.ndarray:
        """Configuration (joint angles, rad, and strains) of the equilibrium reached from ``theta0``.

        Pseudo-transient continuation (Kelley & Keyes 1998): implicit steps of the gradient flow
        d theta / d tau = -dU/dtheta, (H + I / dtau) step = -g, with dtau growing as the imbalance falls
        (switched evolution relaxation), so the iteration first follows the overdamped path from ``theta0``
        (the minimum a damped robot settles in, not just any stationary point near it) and ends with Newton
        steps. H is a finite-difference Hessian of the analytic gradient with its eigenvalues taken by magnitude
        (every step descends); a step that raises U is retried with a smaller dtau.

        ``tol``: largest generalised-force imbalance relative to EI / l at convergence. ``hessian``: a Hessian
        (units EI / l) from a nearby solve; given one, the start is taken as close and dtau starts large. It is
        rebuilt whenever convergence slows. The Hessian last used is left in ``self.last_hessian``.
        """
        x = np.array(theta0, dtype=float)
        n = len(x)
        scale = self.bending_stiffness / self.link_length

        def fun(y):
            U, g = self.energy_gradient(y, source, t)
            return U / scale, g / scale

        def fd_hessian(y, g0):
            H = np.empty((n, n))
            for i in range(n):
                z = y.copy()
                z[i] += 1e-7
                H[:, i] = (fun(z)[1] - g0) / 1e-7
            return 0.5 * (H + H.T)

        U, g = fun(x)
        fresh = hessian is None or np.shape(hessian) != (n, n)
        H = fd_hessian(x, g) if fresh else np.asarray(hessian, dtype=float)
        x_h = x.copy()  # where H was built
        # dtau in units of l / EI: 0.2 is a fifth of the relaxation time of a joint spring
        dtau = 0.2 if fresh else 1e6
        for _ in range(max_iter):
            gnorm = np.linalg.norm(g)
            if np.max(np.abs(g)) < tol:
                break
            w, V = np.linalg.eigh(H)
            w = np.maximum(np.abs(w), 1e-6 * max(1.0, np.max(np.abs(w))))
            step = -V @ ((V.T @ g) / (w + 1.0 / dtau))
            big = np.max(np.abs(step))
            if big > 0.25:  # a quarter radian per joint at most per step: the flow is strongly nonlinear
                step *= 0.25 / big
            U_new, g_new = fun(x + step)
            gnew = np.linalg.norm(g_new)
            # accept a step that lowers U, or, near the minimum where U drowns in rounding, halves the imbalance
            if U_new <= U + 1e-12 * (1.0 + abs(U)) or gnew < 0.5 * gnorm:
                x, U, g = x + step, U_new, g_new
                # switched evolution relaxation, with at least geometric growth so the Newton phase is reached
                dtau = min(1e12, dtau * max(1.5, min(10.0, gnorm / max(gnew, 1e-300))))
                # rebuild H where it has gone stale: after a sizeable move, or when Newton steps converge slowly
                if np.max(np.abs(x - x_h)) > 0.05 or (dtau > 1e3 and gnew > 0.1 * gnorm):
                    H, fresh, x_h = fd_hessian(x, g), True, x.copy()
                else:
                    fresh = False
            else:
                if not fresh:
                    H, fresh, x_h = fd_hessian(x, g), True, x.copy()
                dtau *= 0.25
                if dtau < 1e-12:
                    break
        self.last_hessian = H
        return x

    def tip(self, theta) -> np.ndarray:
        """Tip position (2,) in m."""
        return self.joints(theta)[-1]


# ------------------------------------------------------------------------------------------- targets
def arc_link_angles(n: int, link_length: float, curvature: float, base_angle: float = 0.0) -> np.ndarray:
    """Absolute chord angles (rad) of the first n links of a constant-curvature arc (1/m) from the base."""
    return base_angle + curvature * (np.arange(n) + 0.5) * link_length


@dataclass
class GrowthTarget:
    """A follow-the-leader plan: at step k the first ``links[k]`` links should lie at ``angles[k]`` (rad)."""

    links: list[int]
    angles: list[np.ndarray]

    @classmethod
    def arc(cls, robot: PlanarPRB, tip_angle: float, initial_links: int = 2, links_per_step: int = 1) -> "GrowthTarget":
        """Follow-the-leader growth into a constant-curvature arc whose tip tangent ends at ``tip_angle`` (rad)
        from the base direction (pi: retroflexion), one step per ``links_per_step`` links everted: at every
        step the everted links lie on the final arc."""
        n = robot.n_links
        kappa = tip_angle / (n * robot.link_length)
        links = list(range(initial_links, n + 1, links_per_step))
        if links[-1] != n:
            links.append(n)
        angles = [arc_link_angles(m, robot.link_length, kappa, robot.base_angle) for m in links]
        return cls(links, angles)

    @classmethod
    def grow_then_bend(cls, robot: PlanarPRB, tip_angle: float, initial_links: int = 2, links_per_step: int = 1,
                       bend_steps: int = 3) -> "GrowthTarget":
        """Retroflexion after insertion: the robot everts straight (follow-the-leader along a line), then, fully
        everted, curls into constant-curvature arcs whose tip tangent reaches ``tip_angle`` (rad) in
        ``bend_steps`` equal increments."""
        n = robot.n_links
        grow = list(range(initial_links, n + 1, links_per_step))
        if grow[-1] != n:
            grow.append(n)
        links = grow + [n] * bend_steps
        angles = [np.full(m, robot.base_angle) for m in grow]
        for k in range(1, bend_steps + 1):
            kappa = tip_angle * k / bend_steps / (n * robot.link_length)
            angles.append(arc_link_angles(n, robot.link_length, kappa, robot.base_angle))
        return cls(links, angles)


# ------------------------------------------------------------------------------------------- planning
@dataclass
class PlanStep:
    """One step of a plan: everted links, magnet pose (m, A m^2), equilibrium and its errors (angles in rad,
    field in T, distance in m)."""

    links: int
    position: np.ndarray
    moment: np.ndarray
    theta: np.ndarray
    target: np.ndarray
    tip_angle_error: float
    shape_rms_error: float
    max_out_of_plane_field: float
    min_distance: float  # smallest magnet-to-joint distance, m
    evaluations: int
    path_jump: bool = False
    stiffness_margin: float = float("nan")


@dataclass
class Plan:
    """The planned steps, the robot they were planned for (with its final magnetisation profile) and the
    magnetisation angles (rad, link frame) of that profile."""

    robot: PlanarPRB
    steps: list[PlanStep]
    magnetisation_angles: np.ndarray
    start_position: np.ndarray | None = None
    start_moment: np.ndarray | None = None

    @property
    def tip_angle_errors(self) -> np.ndarray:
        return np.array([s.tip_angle_error for s in self.steps])

    def tip_positions(self) -> np.ndarray:
        """PRB tip positions (K, 2) in m."""
        return np.array([self.robot.tip(s.theta) for s in self.steps])

    def keyframes(self, step_duration: float, move_fraction: float = 0.5):
        """:class:`~magsoro.actuation.epm_path.KeyframedDipole` of the plan: step k spans [k T, (k + 1) T); the
        magnet moves from pose k - 1 (for k = 0: from its approach pose, far away) to pose k during the first
        ``move_fraction`` of the step and then holds, while the step's new links appear at its start."""
        from magsoro.actuation.epm_path import KeyframedDipole

        T = float(step_duration)
        if not 0 < move_fraction < 1:
            raise ValueError(f"move_fraction must lie in (0, 1), got {move_fraction}")
        first = self.steps[0]
        p0 = first.position if self.start_position is None else self.start_position
        m0 = first.moment if self.start_moment is None else self.start_moment
        times, pos, mom = [0.0], [p0], [m0]
        for k, step in enumerate(self.steps):
            if k > 0:
                times.append(k * T)
                pos.append(self.steps[k - 1].position)
                mom.append(self.steps[k - 1].moment)
            times.append(k * T + move_fraction * T)
            pos.append(step.position)
            mom.append(step.moment)
        times.append(len(self.steps) * T)
        pos.append(self.steps[-1].position)
        mom.append(self.steps[-1].moment)
        return KeyframedDipole(times, pos, mom)


@dataclass
class PlanWeights:
    """Weights of the per-step cost (see the module docstring); ``stability_margin`` is the smallest eigenvalue
    of the energy Hessian (units EI / l) below which the ``stability`` term starts to act; ``path`` weighs the
    link-angle error of the links everted before the step at the start and the middle of the magnet's move
    (follow-the-leader: the body should not move while the tip grows); ``robustness`` weighs how far the tip
    moves (relative to the robot length) when the bending stiffness is ``stiffness_uncertainty`` lower than
    modelled: plans near a fold of the equilibrium path, which no real robot (or the MPM replay) follows
    reliably, cost more."""

    shape: float = 1.0
    tip: float = 3.0
    out_of_plane: float = 0.3
    smoothness: float = 0.3
    profile: float = 0.1
    stability: float = 1.0
    stability_margin: float = 0.5
    path: float = 1.0
    robustness: float = 1.0
    stiffness_uncertainty: float = 0.1


class MagnetPlanner:
    """Time-stepping optimisation of the EPM pose sequence for a :class:`GrowthTarget`.

    robot : :class:`PlanarPRB` (its ``link_moments`` give |m| per link and, unless designed, the profile).
    moment : |m| of the magnet, A m^2. field_scale : typical field at the robot, T.
    min_distance : smallest magnet-to-link distance, m. max_distance : largest magnet distance from the base, m.
    fixed_direction : keep the moment along this 3-vector (only the position moves), default free.
    design_profile : choose the magnetisation direction of each link when it everts, together with that
        step's pose (the seed's optimisation "computes both the magnetic profile and the field sequence");
        links keep the direction chosen for them afterwards. Default False: the robot's profile is used as is.
    tolerance : tip-angle error (rad) above which a step is retried from the multi-start.
    approach_factor : the magnet comes to its first pose from ``approach_factor`` times as far along the same
        line (the field ramps up as it approaches) instead of appearing there; 1 applies the first field at once.
    starts : number of in-plane field directions of the multi-start (first step, and any step whose warm start
        and extrapolated start miss the tip angle by more than ``tolerance``).
    """

    def __init__(self, robot: PlanarPRB, moment: float, field_scale: float = 0.02, min_distance: float = 0.08,
                 max_distance: float = 0.5, fixed_direction=None, weights: PlanWeights | None = None,
                 design_profile: bool = False, tolerance: float = math.radians(5.0), approach_factor: float = 3.0,
                 starts: int = 12):
        self.robot = robot
        self.moment = float(moment)
        self.field_scale = float(field_scale)
        self.min_distance = float(min_distance)
        self.max_distance = float(max_distance)
        self.fixed = None if fixed_direction is None else np.asarray(fixed_direction, float) / np.linalg.norm(fixed_direction)
        self.weights = weights or PlanWeights()
        self.design_profile = bool(design_profile)
        self.tolerance = tolerance
        if not approach_factor >= 1:
            raise ValueError(f"approach_factor must be >= 1, got {approach_factor}")
        self.approach_factor = float(approach_factor)
        self.starts = int(starts)
        self.base3 = np.array([*robot.base_position, robot.plane_z])
        self._strength = np.linalg.norm(robot.link_moments, axis=1)
        self._angles = np.arctan2(robot.link_moments[:, 1], robot.link_moments[:, 0])
        self._new = np.zeros(0, dtype=int)  # links whose direction the current step chooses
        self._warm = {}

    @property
    def n_pose(self) -> int:
        return 3 if self.fixed is not None else 5

    # variables: [distance, azimuth, elevation(, moment azimuth, moment elevation)(, new-link angles)]
    def pose(self, v):
        """Magnet position (m) and moment (A m^2) of the variable vector v."""
        d, a, e = v[0], v[1], v[2]
        p = self.base3 + d * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        if self.fixed is not None:
            return p, self.moment * self.fixed
        psi, chi = v[3], v[4]
        return p, self.moment * np.array([np.cos(chi) * np.cos(psi), np.cos(chi) * np.sin(psi), np.sin(chi)])

    def params(self, position, moment):
        """Pose variables of a magnet position (m) and moment (A m^2)."""
        r = np.asarray(position, float) - self.base3
        d = float(np.linalg.norm(r))
        v = [d, math.atan2(r[1], r[0]), math.asin(np.clip(r[2] / d, -1, 1))]
        if self.fixed is None:
            m = np.asarray(moment, float) / np.linalg.norm(moment)
            v += [math.atan2(m[1], m[0]), math.asin(np.clip(m[2], -1, 1))]
        return np.array(v)

    def _set_profile(self, v):
        if self.design_profile and len(self._new):
            self._angles[self._new] = v[self.n_pose:]
        a = self._angles
        self.robot.link_moments = self._strength[:, None] * np.stack([np.cos(a), np.sin(a)], axis=1)

    def _bounds(self, n_new: int):
        lo = [self.min_distance, -np.inf, -0.5 * np.pi + 1e-6]
        hi = [self.max_distance, np.inf, 0.5 * np.pi - 1e-6]
        if self.fixed is None:
            lo += [-np.inf, -0.5 * np.pi]
            hi += [np.inf, 0.5 * np.pi]
        return np.array(lo + [-np.inf] * n_new), np.array(hi + [np.inf] * n_new)

    def residual(self, v, theta, target, v_prev, lowest=None):
        """Residual vector of the step cost for variables ``v`` and equilibrium ``theta`` whose energy Hessian
        has smallest eigenvalue ``lowest`` (units EI / l); also B_z at the load points (T) and the smallest
        magnet-to-joint distance (m)."""
        p, m = self.pose(v)
        src = Dipole(m, p)
        phi = self.robot.angles(theta)
        w = self.weights
        n = self.robot.links_of(theta)
        res = [w.shape * (phi - target) / math.sqrt(n), [w.tip * (phi[-1] - target[-1])]]
        pts, _, _ = self.robot.load_points(theta)
        bz = src.B(pts)[:, 2]
        res.append(w.out_of_plane * bz / self.field_scale / math.sqrt(len(bz)))
        if v_prev is not None:
            pp, mp = self.pose(v_prev)
            res.append(w.smoothness * (p - pp) / np.linalg.norm(pp - self.base3))
            if self.fixed is None:
                res.append(w.smoothness * (m - mp) / self.moment)
        if self.design_profile and len(self._new):
            # a smooth profile: each new link's direction close to that of the link before it (wrapped, per rad)
            a = self._angles[: self._new[-1] + 1]
            d = np.angle(np.exp(1j * np.diff(a[max(0, self._new[0] - 1):])))
            res.append(w.profile * d)
        if lowest is not None:
            # stay away from folds of the equilibrium path, where the robot would snap through
            res.append([w.stability * max(0.0, w.stability_margin - lowest) / w.stability_margin])
        J = self.robot.joints(theta)
        J3 = np.column_stack([J, np.full(len(J), self.robot.plane_z)])
        clearance = float(np.min(np.linalg.norm(J3 - p, axis=1)))
        res.append([10.0 * max(0.0, self.min_distance - clearance) / self.min_distance])
        return np.concatenate([np.atleast_1d(np.asarray(r, float)) for r in res]), bz, clearance

    def _equilibrium_warm(self, v, theta_start, key="end", source=None):
        """Equilibrium under variables v (or under ``source`` with v's profile), started from the last one
        found under the same ``key`` in this search (nearby poses: a Newton step or two) or from
        ``theta_start``; the chosen pose is re-checked along the physical path afterwards."""
        self._set_profile(v)
        if source is None:
            p, m = self.pose(v)
            source = Dipole(m, p)
        cached = self._warm.get(key)
        if cached is not None and len(cached[0]) == len(theta_start):
            start, H = cached
        else:
            start, H = theta_start, None
        theta = self.robot.equilibrium(source, start, hessian=H)
        self._warm[key] = (theta, self.robot.last_hessian)
        return theta

    def _path_residual(self, v, v_prev, theta_start, target, previous_target, n_old):
        """Residual of the way there: angle errors of the links everted before the step at the start and the
        middle of the magnet's move, against the previous target blended linearly into the new one (for
        follow-the-leader growth the two agree on those links: the body should not move while the tip grows)."""
        from magsoro.actuation.epm_path import slerp

        p0, m0 = self.pose(v_prev)
        p1, m1 = self.pose(v)
        out = []
        for s in (0.0, 0.5):
            theta = self._equilibrium_warm(v, theta_start, key=s, source=Dipole(slerp(m0, m1, s), (1 - s) * p0 + s * p1))
            phi = self.robot.angles(theta)[:n_old]
            want = (1 - s) * previous_target[:n_old] + s * target[:n_old]
            out.append(self.weights.path * (phi - want) / math.sqrt(n_old))
        return np.concatenate(out)

    def _robustness_residual(self, v, theta):
        """Tip displacement (per robot length) of the equilibrium near ``theta`` when EI is lower by the
        stiffness uncertainty: the sensitivity of the planned shape to the material's stiffness."""
        w = self.weights
        soft = PlanarPRB(self.robot.link_length, self.robot.bending_stiffness * (1.0 - w.stiffness_uncertainty),
                         self.robot.link_moments, self.robot.base_position, self.robot.base_angle,
                         self.robot.plane_z, self.robot.axial_stiffness, self.robot.lateral_contraction)
        p, m = self.pose(v)
        cached = self._warm.get("soft")
        start, H = (cached if cached is not None and len(cached[0]) == len(theta) else (theta, None))
        q = soft.equilibrium(Dipole(m, p), start, hessian=H)
        self._warm["soft"] = (q, soft.last_hessian)
        length = self.robot.link_length * self.robot.links_of(theta)
        return w.robustness * (soft.tip(q) - self.robot.tip(theta)) / length

    @staticmethod
    def _lowest(H) -> float:
        return float(np.linalg.eigvalsh(H)[0])

    def stiffness_margin(self, v, theta) -> float:
        """Smallest eigenvalue of the energy Hessian (units EI / l) at equilibrium ``theta`` under ``v``: how far
        the robot is from a snap-through (0 at a fold)."""
        self._set_profile(v)
        p, m = self.pose(v)
        self.robot.equilibrium(Dipole(m, p), theta)
        return self._lowest(self.robot.last_hessian)

    def approach(self, v):
        """Variables of the approach pose of ``v``: the same direction and moment, ``approach_factor`` as far."""
        far = np.array(v, dtype=float)
        far[0] *= self.approach_factor
        return far

    def follow(self, v_from, v_to, theta_start, substeps: int = 8):
        """Quasi-static equilibrium path while the magnet moves from pose ``v_from`` to ``v_to`` (position
        linear, moment turning along the great circle, as :class:`~magsoro.actuation.epm_path.KeyframedDipole`
        and the MPM replay move it), starting from ``theta_start``. Returns the final joint angles and whether
        the path jumped (the tip turned by more than 0.5 rad within one substep: a snap-through)."""
        from magsoro.actuation.epm_path import slerp

        self._set_profile(v_to)
        p1, m1 = self.pose(v_to)
        p0, m0 = self.pose(v_from)
        theta = np.asarray(theta_start, dtype=float)
        tip = self.robot.angles(theta)[-1] if len(theta) else 0.0
        jumped = False
        for s in np.linspace(0.0, 1.0, substeps + 1)[1:]:
            theta = self.robot.equilibrium(Dipole(slerp(m0, m1, s), (1 - s) * p0 + s * p1), theta)
            new_tip = self.robot.angles(theta)[-1]
            jumped |= abs(new_tip - tip) > 0.5
            tip = new_tip
        return theta, jumped

    def _starts(self, theta_start, n_new: int):
        """Axial EPM poses giving ``field_scale`` at the robot's centroid in ``starts`` in-plane directions (seed
        004 eqs 15-16), with the new links' directions at their current values."""
        from magsoro.fields.epm import epm_pose

        J = self.robot.joints(theta_start)
        centre = np.array([*J.mean(axis=0), self.robot.plane_z])
        lo, hi = self._bounds(n_new)
        extra = list(self._angles[self._new]) if self.design_profile else []
        starts = []
        for ang in np.linspace(0.0, 2 * np.pi, self.starts, endpoint=False):
            pose = epm_pose(self.field_scale * np.array([np.cos(ang), np.sin(ang), 0.0]), self.moment, at=centre)
            moment = pose.moment if self.fixed is None else self.moment * self.fixed
            starts.append(np.clip(np.concatenate([self.params(pose.position, moment), extra]), lo, hi))
        return starts

    def _solve_step(self, v0, theta_start, target, v_prev, n_old, previous_target=None):
        """Least-squares variables from ``v0``; returns them, the path-checked equilibrium, its cost, B_z,
        clearance, the evaluations used, whether the path jumped and the stiffness margin."""
        from scipy.optimize import least_squares

        n_new = len(v0) - self.n_pose
        lo, hi = self._bounds(n_new)
        count = [0]
        self._warm = {}
        with_path = v_prev is not None and n_old > 0 and self.weights.path > 0

        def fun(v):
            count[0] += 1
            theta = self._equilibrium_warm(v, theta_start)
            res = self.residual(v, theta, target, v_prev, self._lowest(self.robot.last_hessian))[0]
            if with_path:
                res = np.concatenate([res, self._path_residual(v, v_prev, theta_start, target, previous_target, n_old)])
            if self.weights.robustness > 0:
                res = np.concatenate([res, self._robustness_residual(v, theta)])
            return res

        scale = np.array([0.05, 0.2, 0.2] + ([0.2, 0.2] if self.fixed is None else []) + [0.5] * n_new)
        sol = least_squares(fun, np.clip(v0, lo, hi), bounds=(lo, hi), x_scale=scale, diff_step=1e-6,
                            xtol=1e-8, ftol=1e-8, max_nfev=40)
        start = self.approach(sol.x) if v_prev is None else v_prev
        theta, jumped = self.follow(start, sol.x, theta_start)
        lowest = self.stiffness_margin(sol.x, theta)
        res, bz, clearance = self.residual(sol.x, theta, target, v_prev, lowest)
        self._warm = {}
        if with_path:
            res = np.concatenate([res, self._path_residual(sol.x, v_prev, theta_start, target, previous_target, n_old)])
        if self.weights.robustness > 0:
            res = np.concatenate([res, self._robustness_residual(sol.x, theta)])
        # a path that snaps through is not what the optimiser judged: rank it behind every smooth one
        cost = float(np.sum(res**2)) + (1e3 if jumped else 0.0)
        return sol.x, theta, cost, bz, clearance, count[0], jumped, lowest

    def plan(self, target: GrowthTarget, progress=None) -> Plan:
        """Optimise the poses (and, with ``design_profile``, the new links' magnetisation) step by step;
        ``progress(k, step)`` is called after each step."""
        steps: list[PlanStep] = []
        theta_prev = self.robot.straight(0)
        v_prev = v_prev2 = previous_target = None
        for k, (n, tgt) in enumerate(zip(target.links, target.angles)):
            tgt = np.asarray(tgt, dtype=float)
            theta_start = self.robot.grow(theta_prev, n)
            n_old = self.robot.links_of(theta_prev)
            self._new = np.arange(n_old, n) if self.design_profile else np.zeros(0, dtype=int)
            if self.design_profile and n_old:
                self._angles[self._new] = self._angles[n_old - 1]  # start from the last link's direction
            n_new = len(self._new)
            evals = 0
            if v_prev is None:
                cands = self._starts(theta_start, n_new)
                scores = []
                for v in cands:
                    self._set_profile(v)
                    theta = self.robot.equilibrium(Dipole(*self.pose(v)[::-1]), theta_start)
                    scores.append(np.sum(self.residual(v, theta, tgt, None)[0] ** 2))
                evals += len(cands)
                best = self._solve_step(cands[int(np.argmin(scores))], theta_start, tgt, None, 0)
            else:
                v0 = np.concatenate([v_prev[: self.n_pose], self._angles[self._new]])
                best = self._solve_step(v0, theta_start, tgt, v_prev, n_old, previous_target)
                if (best[6] or abs(self.robot.angles(best[1])[-1] - tgt[-1]) > self.tolerance) and v_prev2 is not None:
                    # second guess: the pose extrapolated from the last two steps (the magnet keeps moving)
                    v1 = np.concatenate([2 * v_prev[: self.n_pose] - v_prev2[: self.n_pose], self._angles[self._new]])
                    trial = self._solve_step(v1, theta_start, tgt, v_prev, n_old, previous_target)
                    evals += trial[5]
                    if trial[2] < best[2]:
                        best = trial
            evals += best[5]
            if best[6] or abs(self.robot.angles(best[1])[-1] - tgt[-1]) > self.tolerance:
                # the warm start lost the target (or the path jumped to another branch): restart from the
                # axial poses and keep the best path-checked result
                for c in self._starts(theta_start, n_new):
                    trial = self._solve_step(c, theta_start, tgt, v_prev, n_old, previous_target)
                    evals += trial[5]
                    if trial[2] < best[2]:
                        best = trial
            v, theta, _, bz, clearance, _, jumped, lowest = best
            self._set_profile(v)
            p, m = self.pose(v)
            phi = self.robot.angles(theta)
            step = PlanStep(n, p, m, theta, tgt, float(abs(phi[-1] - tgt[-1])),
                            float(np.sqrt(np.mean((phi - tgt) ** 2))), float(np.max(np.abs(bz))), clearance, evals,
                            bool(jumped), float(lowest))
            steps.append(step)
            if progress is not None:
                progress(k, step)
            if k == 0:
                start_position, start_moment = self.pose(self.approach(v))
            theta_prev, v_prev2, v_prev, previous_target = theta, v_prev, v, tgt
        return Plan(self.robot, steps, self._angles.copy(), start_position, start_moment)
