"""Static Cosserat rod clamped at s = 0, loaded by a uniform magnetic field, gravity and a tip wrench.

Formulation of Till et al. (2019) and Rucker & Webster (2011) as used in seed 003 (eqs 1-5): state
y = (R, p, n, m), equilibrium n' + f = 0 and m' + p' x n + l = 0, with the magnetic couple per unit length
l = A (R Br / mu0) x B (uniform field, so no magnetic force). Linear constitutive law
m = R K_bt u, n = R K_se (v - e3). The default rod is the Kirchhoff limit (inextensible, unshearable: v = e3).

The boundary value problem (clamped at s = 0, prescribed tip wrench at s = L) is solved by multiple shooting
with fixed-step RK4 and Newton's method, inside an adaptive continuation on the loads that follows one
equilibrium branch (see ``_shooting.py`` for the numerics and docs/rod.md for the validation).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field as dc_field

import numpy as np

from magsoro.constants import MU0
from magsoro.errors import SceneError, SimulationError
from magsoro.rod._shooting import ConvergenceFailure, Loads, Shooter, ShootingState
from magsoro.rod.magnetisation import Magnetisation, _vec3
from magsoro.rod.section import CrossSection, _positive

#: Default clamp orientation: tangent d3 along +x, width (d1) along +y, thickness (d2) along +z, so a strip
#: clamped horizontally sags under gravity (-z) and bends in its soft direction.
DEFAULT_BASE_ROTATION = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

#: Largest RK4 step as a fraction of L. 1/100 keeps the integration error of the tip position near 1e-7 L for
#: a magnetic cantilever whose tip turns by 90 degrees (checked against the elastica in tests/test_rod.py).
DEFAULT_MAX_STEP = 1.0 / 100.0


@dataclass
class RodSolution:
    """An equilibrium of the rod. All arrays in SI, sampled at the output nodes.

    Attributes:
        s: (N,) arc length from the clamp, m (uniform nodes plus magnetisation segment ends).
        positions: (N, 3) centreline p(s), m.
        rotations: (N, 3, 3) orientation R(s); columns are the material directors d1, d2, d3.
        internal_force: (N, 3) n(s), N, global frame: force the part beyond s exerts on the part before s.
        internal_moment: (N, 3) m(s), N m, global frame: moment the part beyond s exerts on the part before s.
        field: (3,) applied uniform field B, T.
        residual: norm of the shooting residual (mismatches at the shooting cuts and at the free end) in the
            rod's own units (lengths / L, moments / (E I1 / L)); below 1e-10 times the largest moment.
        iterations: Newton iterations used (all continuation steps together).
    """

    s: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    internal_force: np.ndarray
    internal_moment: np.ndarray
    field: np.ndarray
    residual: float
    iterations: int
    _state: ShootingState = dc_field(repr=False, default=None)  # non-dimensional shooting unknowns
    _loads: Loads = dc_field(repr=False, default=None)
    _tangents: np.ndarray = dc_field(repr=False, default=None)

    @property
    def tip_position(self) -> np.ndarray:
        """p(L), m."""
        return self.positions[-1].copy()

    @property
    def tangents(self) -> np.ndarray:
        """(N, 3) unit tangent of the centreline, p'/|p'| (equals d3 for the Kirchhoff rod)."""
        return self._tangents.copy()

    @property
    def clamp_force(self) -> np.ndarray:
        """Force the clamp exerts on the rod, N: -n(0) (it balances the weight and the tip force)."""
        return -self.internal_force[0]

    @property
    def clamp_moment(self) -> np.ndarray:
        """Moment the clamp exerts on the rod about the clamp point p(0), N m: -m(0)."""
        return -self.internal_moment[0]


class Rod:
    """A magnetic Cosserat rod clamped at s = 0 and free at s = L.

    Args:
        length: L, m.
        cross_section: :class:`CrossSection` (``CrossSection.rectangle(width, thickness)`` or
            ``CrossSection.circle(diameter)``, m).
        youngs_modulus: E, Pa.
        shear_modulus: G, Pa (default E / 3, incompressible elastomer).
        magnetisation: remanence Br(s) in the material frame, T: a list of :class:`MagnetSegment` /
            ``(start, end, (Br1, Br2, Br3))`` with start, end in m; a callable ``s -> (3,)``; or one 3-vector for
            a uniformly magnetised rod. Default: unmagnetised. Component 3 is along the rod axis.
        density: rho, kg/m^3, of the rod material (its weight rho A g acts per unit length); 0 disables gravity.
        gravity: g, m/s^2, 3-vector.
        tip_force: F, N, dead load applied at s = L (global frame).
        tip_moment: M, N m, couple applied at s = L (global frame).
        base_position: p(0), m.
        base_rotation: R(0), 3x3 rotation whose columns are d1 (width), d2 (thickness), d3 (tangent) in the
            global frame; default :data:`DEFAULT_BASE_ROTATION` (rod along +x, thickness along z).
        extensible: False (default) for the Kirchhoff rod (inextensible, unshearable); True adds extension
            (stiffness E A) and shear (kappa G A, kappa the section's Timoshenko coefficient).
        n_nodes: number of uniformly spaced output nodes (the segment ends are added to them).
        max_step: largest integration step, m (default L / 100).
    """

    def __init__(self, length: float, cross_section: CrossSection, youngs_modulus: float,
                 shear_modulus: float | None = None, magnetisation=None, density: float = 0.0,
                 gravity=(0.0, 0.0, -9.81), tip_force=(0.0, 0.0, 0.0), tip_moment=(0.0, 0.0, 0.0),
                 base_position=(0.0, 0.0, 0.0), base_rotation=None, extensible: bool = False,
                 n_nodes: int = 101, max_step: float | None = None):
        self.length = _positive(length, "length", "m")
        if not isinstance(cross_section, CrossSection):
            raise SceneError(f"cross_section: expected a CrossSection, got {type(cross_section).__name__}")
        self.cross_section = cross_section
        self.youngs_modulus = _positive(youngs_modulus, "youngs_modulus", "Pa")
        self.shear_modulus = (self.youngs_modulus / 3.0 if shear_modulus is None
                              else _positive(shear_modulus, "shear_modulus", "Pa"))
        self.magnetisation = (magnetisation if isinstance(magnetisation, Magnetisation)
                              else Magnetisation(magnetisation, self.length))
        density = float(density)
        if not (density >= 0 and np.isfinite(density)):
            raise SceneError(f"density: must be >= 0 kg/m^3, got {density!r}")
        self.density = density
        self.gravity = _vec3(gravity, "gravity")
        self.tip_force = _vec3(tip_force, "tip_force")
        self.tip_moment = _vec3(tip_moment, "tip_moment")
        self.base_position = _vec3(base_position, "base_position")
        R0 = DEFAULT_BASE_ROTATION if base_rotation is None else np.asarray(base_rotation, dtype=np.float64)
        if R0.shape != (3, 3) or not np.allclose(R0.T @ R0, np.eye(3), atol=1e-9) or np.linalg.det(R0) < 0:
            raise SceneError("base_rotation: must be a proper 3x3 rotation matrix (orthonormal, det +1)")
        self.base_rotation = R0
        self.extensible = bool(extensible)
        if int(n_nodes) != n_nodes or n_nodes < 2:
            raise SceneError(f"n_nodes: must be an integer >= 2, got {n_nodes!r}")
        self.n_nodes = int(n_nodes)
        self.max_step = self.length * DEFAULT_MAX_STEP if max_step is None else _positive(max_step, "max_step", "m")
        self._shooter = self._build_shooter()

    # --- derived stiffness -------------------------------------------------------------------------------
    @property
    def bending_stiffness(self) -> np.ndarray:
        """(E I1, E I2, G J), N m^2: stiffness about d1, d2 and in torsion about d3."""
        i1, i2 = self.cross_section.second_moment
        return np.array([self.youngs_modulus * i1, self.youngs_modulus * i2,
                         self.shear_modulus * self.cross_section.torsion_constant])

    @property
    def shear_stiffness(self) -> np.ndarray:
        """(kappa G A, kappa G A, E A), N: shear along d1, d2 and extension along d3."""
        a, k = self.cross_section.area, self.cross_section.shear_coefficient
        return np.array([k * self.shear_modulus * a, k * self.shear_modulus * a, self.youngs_modulus * a])

    def _build_shooter(self) -> Shooter:
        L = self.length
        self._ei = float(self.bending_stiffness[0])
        uniform = np.linspace(0.0, 1.0, self.n_nodes)
        breaks = [b / L for b in self.magnetisation.breakpoints() if 0.0 < b < L]
        nodes = np.unique(np.concatenate([uniform, breaks]))
        # drop nodes closer than 1e-9 L to a neighbour (round-off duplicates of segment ends)
        keep = np.concatenate([[True], np.diff(nodes) > 1e-9])
        nodes = nodes[keep]
        nodes[-1] = 1.0
        coef = self.cross_section.area * L**2 / (MU0 * self._ei)
        mag = self.magnetisation
        kse_inv = self._ei / (L**2 * self.shear_stiffness) if self.extensible else None
        return Shooter(nodes, self.max_step / L, lambda sig: coef * mag(np.asarray(sig) * L),
                       self._ei / self.bending_stiffness, kse_inv, self.base_position / L, self.base_rotation)

    def _loads(self, field) -> Loads:
        L, ei = self.length, self._ei
        f = self.density * self.cross_section.area * self.gravity
        return Loads(_vec3(field, "field").copy(), f * L**3 / ei, self.tip_force * L**2 / ei, self.tip_moment * L / ei)

    # --- solving -----------------------------------------------------------------------------------------
    def solve(self, field=(0.0, 0.0, 0.0), initial_guess: RodSolution | None = None,
              perturbation=None) -> RodSolution:
        """Static equilibrium under the uniform field ``field`` (T, 3-vector).

        The loads are ramped from those of ``initial_guess`` (or from the unloaded straight rod) to the wanted
        ones with adaptive continuation, so the answer lies on the branch connected to the start.
        ``perturbation`` (T, 3-vector) is added to the field on the way and removed at the end: it breaks the
        symmetry of a field antiparallel to the magnetisation, where the straight rod is an equilibrium
        whether stable or not, and selects the side to which the rod buckles.
        Raises :class:`magsoro.SimulationError` if no equilibrium is found.
        """
        if initial_guess is None:
            x0, start = self._shooter.straight_state(), Loads.zero()
        else:
            if initial_guess._state is None or initial_guess._state.m.shape[0] != self._shooter.n_seg:
                raise SceneError("initial_guess: not a solution of this rod")
            x0, start = initial_guess._state, initial_guess._loads
        target = self._loads(field)
        waypoints = [target]
        if perturbation is not None:
            waypoints.insert(0, self._loads(target.field + _vec3(perturbation, "perturbation")))
        x, iterations = x0, 0
        for goal in waypoints:
            try:
                x, residual, its, _ = self._shooter.continuation(x, start, goal)
            except ConvergenceFailure as exc:
                raise SimulationError(
                    f"rod: could not follow the equilibrium to field {np.round(goal.field, 9).tolist()} T: {exc}"
                ) from None
            iterations += its
            start = goal
        return self._solution(x, target, residual, iterations)

    def sweep(self, fields: Iterable, initial_guess: RodSolution | None = None,
              perturbation=None) -> list[RodSolution]:
        """Quasi-static sweep: solve for each field (T, sequence of 3-vectors) in order, starting each solve
        from the previous equilibrium, so the sequence follows one branch (as a slowly varied field would).
        ``perturbation`` is passed to every step (see :meth:`solve`)."""
        out, guess = [], initial_guess
        for b in fields:
            guess = self.solve(b, initial_guess=guess, perturbation=perturbation)
            out.append(guess)
        return out

    def _solution(self, x, loads: Loads, residual: float, iterations: int) -> RodSolution:
        sh = self._shooter
        traj = sh.trajectory(x, loads)  # (N, 15): p, m, R
        L, ei = self.length, self._ei
        # RK4 keeps R orthonormal only to its truncation error (~1e-8 for strongly bent rods); hand out the
        # nearest rotation (polar factor) so users can rely on R^T R = I
        U, _, Vt = np.linalg.svd(traj[:, 6:15].reshape(-1, 3, 3))
        rot = U @ Vt
        n = loads.internal_force(sh.nodes)
        if self.extensible:
            v = (ei / (L**2 * self.shear_stiffness)) * np.einsum("kji,kj->ki", rot, n)
            v[:, 2] += 1.0
            tangent = np.einsum("kij,kj->ki", rot, v)
        else:
            tangent = rot[:, :, 2].copy()
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        return RodSolution(
            s=sh.nodes * L,
            positions=traj[:, 0:3] * L,
            rotations=rot,
            internal_force=n * ei / L**2,
            internal_moment=traj[:, 3:6] * ei / L,
            field=loads.field.copy(),
            residual=float(residual),
            iterations=int(iterations),
            _state=x.copy(),
            _loads=loads,
            _tangents=tangent,
        )


def solve(rod: Rod, field=(0.0, 0.0, 0.0), initial_guess: RodSolution | None = None,
          perturbation=None) -> RodSolution:
    """Functional form of :meth:`Rod.solve`."""
    return rod.solve(field, initial_guess=initial_guess, perturbation=perturbation)


def sweep(rod: Rod, fields: Iterable, initial_guess: RodSolution | None = None,
          perturbation=None) -> list[RodSolution]:
    """Functional form of :meth:`Rod.sweep`."""
    return rod.sweep(fields, initial_guess=initial_guess, perturbation=perturbation)
