"""What the engine steps: the Model (what a run does not change), the State (what a step changes), the Control
(what the user drives over time) and the explicit solver's settings.

- :class:`Model`: reference positions, volumes, per-particle material, remanence, body ids, clamp mask, grid
  spacing, domain, precision, device.
- :class:`State`: x, v, C, F, time.
- :class:`Control`: field sources, colliders with their paths.
- :class:`SolverSettings`, :class:`ContactSettings`: damping, walls, time-step factors, contact between bodies.
"""

import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from magsoro.constants import MU0
from magsoro.mpm.colliders import Collider
from magsoro.mpm.kernels import make_kernels
from magsoro.mpm.laws.elastic import LAW_PARAM_COUNT, LAWS, describe_codes
from magsoro.mpm.laws.prony import device_tables, prony_table
from magsoro.mpm.runtime import resolve_device
from magsoro.mpm.settings import (PLANES, ColliderModeName, Formulation, InteractionMode, MagnetizationFollows,
                                  VelocityGradient, plane_stress_modulus)


PRECISIONS = {"float32": (wp.float32, np.float32), "float64": (wp.float64, np.float64)}


#: A pressure load is on a closed cavity when its reference faces sum to at most this fraction of their total area
#: (the lattice's faces close up to round-off): its net force is then taken back every step.
CLOSED_CAVITY = 1e-9


class Model:
    """Particles and settings that stay fixed during a run. Inputs are SI numpy arrays.

    positions (N, dim) m; volumes (N,) m^3 (in 2D: area x depth); density (N,) kg/m^3; shear_modulus and
    bulk_modulus (N,) Pa; remanence (N, 3) T in the reference frame; body (N,) int; clamped (N,) bool.
    material_model (N,) int: 0 Neo-Hookean (default), 1 Mooney-Rivlin, 2 Yeoh, 3 Ogden, 4 polynomial, with
    material_params (N, LAW_PARAM_COUNT = 6), moduli Pa, Ogden exponents dimensionless, unused slots 0:
    (C10, C01, ...), (C10, C20, C30, ...), (mu1, alpha1, mu2, alpha2, mu3, alpha3) or (C10, C01, C20, C11, C02, 0)
    (MaterialLaw.pack); shear_modulus is then the initial shear modulus (2 (C10 + C01), 2 C10 or sum mu_i), used
    for the time step. The laws and their codes: :mod:`magsoro.mpm.laws.elastic`.
    magnetization_follows (N,) int: the map carrying each particle's remanence, 0 F (default, Zhao's law) or 1 the
    rotation R of F = R U (:func:`magsoro.mpm.kernels.stencil.make_magnetization`).
    stimuli: :class:`magsoro.mpm.laws.eigenstrain.Stimulus` laws (a material's stretch following a stimulus in time),
    with stimulus (N,) int the row of each particle's (-1: none); :meth:`update_stimuli` sets the tables the kernels
    read to a time (t = 0 at construction; the solver calls it every step).
    pronies: Prony tables [[g, tau], ...] (viscoelastic materials, :mod:`magsoro.mpm.laws.viscous`), with prony (N,) int
    the row of each particle's (-1: elastic); a particle cannot have both a stimulus and a Prony row.
    plane (2D): "strain" (default, F_zz = 1) or "stress" (zero normal stress, the thickness stretch solved per
    particle), :data:`magsoro.mpm.settings.PLANES`; the kernels are built for it.
    """

    MATERIAL_MODELS = {name: law.code for name, law in LAWS.items()}

    def __init__(
        self,
        positions,
        volumes,
        density,
        shear_modulus,
        bulk_modulus,
        remanence,
        body,
        clamped,
        *,
        dx: float,
        domain_lo,
        domain_hi,
        precision: str = "float32",
        device: str | None = "cpu",
        material_model=None,
        material_params=None,
        contact_group=None,
        stimulus=None,
        stimuli=(),
        magnetization_follows=None,
        prony=None,
        pronies=(),
        pressure_area=None,
        pressure_row=None,
        pressures=(),
        clamp_row=None,
        clamp_paths=(),
        initial_displacement=None,
        initial_deformation=None,
        plane: str = "strain",
    ):
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {sorted(PRECISIONS)}, got {precision!r}")
        self.precision = precision
        self.scalar, self.np_scalar = PRECISIONS[precision]
        self.device = resolve_device(device)
        X = np.asarray(positions, dtype=np.float64)
        self.dim = X.shape[1]
        n = len(X)
        if n == 0:
            raise ValueError("a model needs at least one particle")
        self.n_particles = n
        self.dx = float(dx)
        self.domain_lo = np.asarray(domain_lo, dtype=np.float64).reshape(self.dim)
        self.domain_hi = np.asarray(domain_hi, dtype=np.float64).reshape(self.dim)
        self._init_plane(plane)
        k = make_kernels(self.dim, self.scalar, plane=self.plane)
        self.kernels = k
        self.host = dict(
            positions=X,
            volumes=np.broadcast_to(np.asarray(volumes, dtype=np.float64), (n,)).copy(),
            density=np.broadcast_to(np.asarray(density, dtype=np.float64), (n,)).copy(),
            shear_modulus=np.broadcast_to(np.asarray(shear_modulus, dtype=np.float64), (n,)).copy(),
            bulk_modulus=np.broadcast_to(np.asarray(bulk_modulus, dtype=np.float64), (n,)).copy(),
            remanence=np.broadcast_to(np.asarray(remanence, dtype=np.float64), (n, 3)).copy(),
            body=np.broadcast_to(np.asarray(body, dtype=np.int32), (n,)).copy(),
            clamped=np.broadcast_to(np.asarray(clamped, dtype=bool), (n,)).copy(),
            material_model=np.broadcast_to(np.asarray(0 if material_model is None else material_model, dtype=np.int32), (n,)).copy(),
            magnetization_follows=np.broadcast_to(np.asarray(0 if magnetization_follows is None else magnetization_follows, dtype=np.int32), (n,)).copy(),
            material_params=np.broadcast_to(np.asarray(0.0 if material_params is None else material_params, dtype=np.float64), (n, LAW_PARAM_COUNT)).copy(),
        )
        h = self.host
        h["mass"] = h["volumes"] * h["density"]
        for key in ("volumes", "density", "shear_modulus", "bulk_modulus"):
            if not np.all(h[key] > 0) or not np.all(np.isfinite(h[key])):
                raise ValueError(f"particle {key} must be finite and > 0")
        s, dev = self.np_scalar, self.device
        self.X0 = wp.array(X.astype(s), dtype=k["vec"], device=dev)
        self.vol0 = wp.array(h["volumes"].astype(s), dtype=self.scalar, device=dev)
        # reference radius (x) of each particle: the axisymmetric kernels' R; an axisymmetric particle sits off the axis
        if self.plane == "axisymmetric" and not np.all(X[:, 0] > 0.0):
            raise ValueError("an axisymmetric model's particles must lie at r = x > 0")
        self.radius0 = wp.array(X[:, 0].astype(s), dtype=self.scalar, device=dev)
        self.spacing = self.dx / 2.0  # the particle lattice's spacing (m): the scene builder sets it (dx / particles_per_cell)
        self.mass = wp.array(h["mass"].astype(s), dtype=self.scalar, device=dev)
        self.shear = wp.array(h["shear_modulus"].astype(s), dtype=self.scalar, device=dev)
        self.bulk = wp.array(h["bulk_modulus"].astype(s), dtype=self.scalar, device=dev)
        self.Br = wp.array(h["remanence"].astype(s), dtype=k["v3"], device=dev)
        if not np.all(np.isin(h["material_model"], list(self.MATERIAL_MODELS.values()))):
            raise ValueError(f"material_model must be {describe_codes()}")
        self.material_model = wp.array(h["material_model"], dtype=wp.int32, device=dev)
        if not np.all(np.isin(h["magnetization_follows"], [int(m) for m in MagnetizationFollows])):
            raise ValueError("magnetization_follows must be 0 (F) or 1 (R)")
        self.follows = wp.array(h["magnetization_follows"], dtype=wp.int32, device=dev)
        self.material_params = wp.array(h["material_params"].astype(s), dtype=k["vprm"], device=dev)
        self.body = wp.array(h["body"], dtype=wp.int32, device=dev)
        self._init_clamps(clamp_row, clamp_paths)
        # an initial displacement u (N, dim) m and the F = I + grad u that goes with it (new states start there)
        if initial_displacement is not None:
            h["initial_displacement"] = np.asarray(initial_displacement, dtype=np.float64).reshape(n, self.dim).copy()
        if initial_deformation is not None:
            h["initial_deformation"] = np.asarray(initial_deformation, dtype=np.float64).reshape(n, self.dim, self.dim).copy()
        # contact groups (magsoro.mpm.kernels.contact): bodies that move as one piece share one; default one per body
        group = h["body"] if contact_group is None else np.broadcast_to(np.asarray(contact_group, dtype=np.int32), (n,)).copy()
        if np.any(group < 0):
            raise ValueError("contact_group must be >= 0")
        h["contact_group"] = group
        self.contact_group = wp.array(group, dtype=wp.int32, device=dev)
        self._init_stimuli(stimulus, stimuli)
        self._init_prony(prony, pronies)
        self._init_pressures(pressure_area, pressure_row, pressures)
        self._placeholder_step = self._placeholder_impulse = None

    @property
    def placeholder_step(self) -> wp.array:
        """A one-element Step array (:mod:`magsoro.mpm.kernels.stencil`) that no kernel reads: a struct's step where the
        kernels take dt and the field from their arguments. Always the same array (Warp's tape looks at every array
        of a struct argument)."""
        if self._placeholder_step is None:
            self._placeholder_step = wp.zeros(1, dtype=self.kernels["Step"], device=self.device)
        return self._placeholder_step

    @property
    def placeholder_impulse(self) -> wp.array:
        """A float64 array of 3 that no kernel writes: the collider impulse of a grid update that records none.
        Always the same array, as :attr:`placeholder_step`."""
        if self._placeholder_impulse is None:
            self._placeholder_impulse = wp.zeros(3, dtype=wp.float64, device=self.device)
        return self._placeholder_impulse

    def _init_clamps(self, rows, paths) -> None:
        """Held particles and moving clamps. ``clamp_paths``: per moving clamp its path (times (K,) s increasing,
        displacements (K, dim) m of the clamped region from its reference place, linear between, held outside the
        table); ``clamp_row`` (N,) int the path of each held particle (-1: held in place). The kernels' clamp code
        of a particle (``clamped``): 0 free, 1 held in place, 2 + row on a path; ``clamp_velocity`` (2 + paths,
        dim) is the velocity of each code over the current step (codes 0 and 1: zero), which :meth:`update_clamps`
        sets before every step."""
        n, dim, h, dev = self.n_particles, self.dim, self.host, self.device
        self.clamp_paths = []
        for times, disp in paths:
            times = np.asarray(times, dtype=np.float64).ravel()
            disp = np.asarray(disp, dtype=np.float64).reshape(len(times), dim)
            if len(times) == 0 or np.any(np.diff(times) <= 0) or not np.all(np.isfinite(disp)):
                raise ValueError("a clamp path needs increasing times and finite displacements, one per time")
            self.clamp_paths.append((times, disp))
        rows = np.broadcast_to(np.asarray(-1 if rows is None else rows, dtype=np.int32), (n,)).copy()
        if np.any(rows < -1) or np.any(rows >= len(self.clamp_paths)):
            raise ValueError(f"clamp_row must be -1 (none) or a row of the {len(self.clamp_paths)} clamp paths")
        rows[~h["clamped"]] = -1
        h["clamp_row"] = rows
        h["clamp_code"] = np.where(h["clamped"], np.where(rows >= 0, rows + 2, 1), 0).astype(np.int32)
        self.clamped = wp.array(h["clamp_code"], dtype=wp.int32, device=dev)
        self.clamp_velocity = wp.zeros(2 + len(self.clamp_paths), dtype=self.kernels["vec"], device=dev)
        self._clamp_values = None

    def clamp_displacement(self, row: int, t: float) -> np.ndarray:
        """The displacement (dim,) m of clamp path ``row`` at time ``t`` (linear between its times, held outside)."""
        times, disp = self.clamp_paths[row]
        return np.array([np.interp(t, times, disp[:, a]) for a in range(self.dim)])

    def clamp_positions(self, t: float) -> np.ndarray:
        """The positions (N, dim) m the held particles take at time ``t`` (reference positions plus their clamp's
        displacement); free particles' rows hold their reference positions."""
        X = self.host["positions"].copy()
        for row in range(len(self.clamp_paths)):
            X[self.host["clamp_row"] == row] += self.clamp_displacement(row, t)
        return X

    def update_clamps(self, t: float, dt: float) -> bool:
        """Set the moving clamps' velocities the kernels read for the step from ``t`` to ``t + dt``: the path's
        displacement over the step divided by dt, so that the held particles' positions, summed step by step, land
        on the path. Copies only when a value changed; returns whether it copied."""
        if not self.clamp_paths or not dt > 0:
            return False
        v = np.zeros((2 + len(self.clamp_paths), self.dim))
        for row in range(len(self.clamp_paths)):
            v[2 + row] = (self.clamp_displacement(row, t + dt) - self.clamp_displacement(row, t)) / dt
        key = v.tobytes()
        if key == self._clamp_values:
            return False
        self.clamp_velocity.assign(v.astype(self.np_scalar))
        self._clamp_values = key
        return True

    def _init_pressures(self, area, rows, pressures) -> None:
        """Pressure loads (:func:`magsoro.scene.build.pressure_faces`): per particle its reference face area vector
        (m^2, outward from the body into the cavity; in 2D times the depth) and its pressure's row (-1: none), and
        the device table of the pressures (Pa) at the current time, which :meth:`update_pressures` sets."""
        n, dim, k, dev, s = self.n_particles, self.dim, self.kernels, self.device, self.np_scalar
        self.pressures = tuple((float(v), float(r)) for v, r in pressures)
        rows = np.broadcast_to(np.asarray(-1 if rows is None else rows, dtype=np.int32), (n,)).copy()
        area = np.zeros((n, dim)) if area is None else np.asarray(area, dtype=np.float64).reshape(n, dim)
        if np.any(rows < -1) or np.any(rows >= len(self.pressures)):
            raise ValueError(f"pressure_row must be -1 (none) or a row of the {len(self.pressures)} pressures")
        for v, r in self.pressures:
            if not (math.isfinite(v) and math.isfinite(r) and r >= 0):
                raise ValueError("a pressure needs a finite value (Pa) and a finite ramp >= 0 (s)")
        self.host["pressure_row"], self.host["pressure_area"] = rows, area
        self.pressure_row = wp.array(rows, dtype=wp.int32, device=dev)
        self.pressure_area = wp.array(area.astype(s), dtype=k["vec"], device=dev)
        self.pressure_value = wp.zeros(max(len(self.pressures), 1), dtype=self.scalar, device=dev)
        # closed cavities (the reference faces sum to zero): each face's share of the load's net force, which the
        # scatter takes back (pressure_net, summed before it) so the load exerts no net force
        share = np.zeros(n)
        self.closed_pressures = []
        for row in range(len(self.pressures)):
            mine = rows == row
            size = np.linalg.norm(area[mine], axis=1)
            # an axisymmetric cavity's ring faces do not sum to zero in r (the hoop stress carries their pull)
            if (self.plane != "axisymmetric" and size.sum() > 0.0
                    and np.linalg.norm(area[mine].sum(axis=0)) <= CLOSED_CAVITY * size.sum()):
                share[mine] = size / size.sum()
                self.closed_pressures.append(row)
        self.host["pressure_share"] = share
        self.pressure_share = wp.array(share.astype(s), dtype=self.scalar, device=dev)
        self.pressure_net = wp.zeros(max(len(self.pressures), 1), dtype=k["vec"], device=dev)
        self._pressure_values = None
        self.update_pressures(0.0)

    def pressures_at(self, t: float) -> tuple[float, ...]:
        """Each pressure load's value (Pa) at time ``t`` (s): linear from 0 over its ramp, then held."""
        return tuple(v if r <= 0.0 or t >= r else v * max(t, 0.0) / r for v, r in self.pressures)

    def update_pressures(self, t: float) -> bool:
        """Set the pressure table the kernels read to time ``t``; copies only when a value changed. Returns whether
        it copied."""
        if not self.pressures:
            return False
        values = self.pressures_at(t)
        if values == self._pressure_values:
            return False
        self.pressure_value.assign(np.asarray(values, dtype=self.np_scalar))
        self._pressure_values = values
        return True

    @property
    def pressure_ramps(self) -> bool:
        """Whether a pressure changes in time (the host sets it at every step)."""
        return any(r > 0.0 for _, r in self.pressures)

    def _init_prony(self, prony, pronies) -> None:
        """Per-particle Prony rows and the device tables of g and tau per row (:mod:`magsoro.mpm.laws.viscous`)."""
        n, dev, h = self.n_particles, self.device, self.host
        self.prony = tuple(prony_table(p) for p in pronies)
        rows = np.broadcast_to(np.asarray(-1 if prony is None else prony, dtype=np.int32), (n,)).copy()
        if np.any(rows < -1) or np.any(rows >= len(self.prony)):
            raise ValueError(f"prony must be -1 (none) or a row of the {len(self.prony)} Prony tables")
        if np.any((rows >= 0) & (h["stimulus"] >= 0)):
            raise ValueError("a particle cannot have both a Prony series and a stimulus eigenstrain")
        h["prony"] = rows
        used = sorted(set(rows[rows >= 0].tolist()))
        self.prony_terms = max((len(self.prony[r]) for r in used), default=0)
        g, tau = device_tables(self.prony)
        s, v3 = self.np_scalar, self.kernels["v3"]
        self.prony_row = wp.array(rows, dtype=wp.int32, device=dev)
        self.prony_g = wp.array(g.astype(s), dtype=v3, device=dev)
        self.prony_tau = wp.array(tau.astype(s), dtype=v3, device=dev)
        # the internal stresses' type: dim x dim, 3 x 3 in plane stress (magsoro.mpm.laws.viscous)
        self.H_type = self.kernels["m3"] if self.plane == "stress" else self.kernels["mat"]
        self.empty_H = wp.zeros((0, 1), dtype=self.H_type, device=dev)
        if self.prony_terms == 0:
            self.prony = ()  # tables no particle uses: the kernels skip the viscous part

    @property
    def viscous(self) -> bool:
        """Whether some particle has a Prony series (its state carries the internal stresses H)."""
        return self.prony_terms > 0

    def _init_stimuli(self, stimulus, stimuli) -> None:
        """Per-particle stimulus rows, the device tables of F_s^-1 and f det F_s per stimulus (at t = 0), and the
        stiffening bound of the time step per particle."""
        n, dim, k, dev, s = self.n_particles, self.dim, self.kernels, self.device, self.np_scalar
        h = self.host
        self.stimuli = tuple(stimuli)
        rows = np.broadcast_to(np.asarray(-1 if stimulus is None else stimulus, dtype=np.int32), (n,)).copy()
        if np.any(rows < -1) or np.any(rows >= len(self.stimuli)):
            raise ValueError(f"stimulus must be -1 (none) or a row of the {len(self.stimuli)} stimuli")
        for st in self.stimuli:
            if st.direction is not None and st.direction.size != dim:
                raise ValueError(f"a stimulus direction needs {dim} components in a {dim}D model, got {st.direction.size}")
        h["stimulus"] = rows
        self.stimulus = wp.array(rows, dtype=wp.int32, device=dev)
        m = max(len(self.stimuli), 1)
        self.stretch_inv = wp.array(np.broadcast_to(np.eye(dim), (m, dim, dim)).astype(s), dtype=k["mat"], device=dev)
        self.stretch_scale = wp.ones(m, dtype=self.scalar, device=dev)
        self.stretch_hoop_inv = wp.ones(m, dtype=self.scalar, device=dev)
        ring = self.plane == "axisymmetric"  # the eigenstretch acts round the ring too (F_s is 3 x 3)
        # squared wave speed factor of each particle's stimulus over its reachable range (1: none)
        bound = np.array([st.stiffening(dim, ring=ring) for st in self.stimuli] + [1.0])
        h["stiffening"] = bound[rows]
        self._stimulus_values = None  # (lambda, f) per stimulus as last uploaded
        # on the CPU the tables are written through numpy views of the same memory (a Warp copy costs more)
        self._stimulus_views = ((self.stretch_inv.numpy(), self.stretch_scale.numpy(), self.stretch_hoop_inv.numpy())
                                if wp.get_device(dev).is_cpu else None)
        self.update_stimuli(0.0)

    def update_stimuli(self, t: float) -> bool:
        """Set the stimulus tables the kernels read (F_s^-1 and f det F_s per stimulus) to time ``t`` (s); copies to
        the device only when a stimulus' (lambda, f) changed. Returns whether it copied."""
        if not self.stimuli:
            return False
        values = tuple(st.values(t) for st in self.stimuli)
        if values == self._stimulus_values:
            return False
        ring = self.plane == "axisymmetric"
        inv, scale, hoop = zip(*(st.tensors(lam, f, self.dim, ring=ring) for st, (lam, f) in zip(self.stimuli, values)))
        inv, scale = np.asarray(inv).astype(self.np_scalar), np.asarray(scale).astype(self.np_scalar)
        hoop = np.asarray(hoop).astype(self.np_scalar)
        if self._stimulus_views is not None:
            self._stimulus_views[0][...] = inv
            self._stimulus_views[1][...] = scale
            self._stimulus_views[2][...] = hoop
        else:
            self.stretch_inv.assign(inv)
            self.stretch_scale.assign(scale)
            self.stretch_hoop_inv.assign(hoop)
        self._stimulus_values = values
        return True

    def _init_plane(self, plane) -> None:
        """The 2D idealisation (:data:`magsoro.mpm.settings.PLANES`): "strain" (F_zz = 1) or "stress" (zero normal
        stress); the kernels are built for it."""
        if plane not in PLANES:
            raise ValueError(f"simulation.plane must be one of {list(PLANES)}, got {plane!r}")
        if plane in ("stress", "axisymmetric") and self.dim != 2:
            raise ValueError(f'simulation.plane = "{plane}" needs a 2D model (a 3D body has no plane idealisation)')
        self.plane = plane

    def p_wave_modulus(self) -> np.ndarray:
        """Each particle's P-wave modulus K + 4G/3 (Pa, (N,)): the stiffness scale of the Newton solvers' contact
        penalties and force floor."""
        return self.host["bulk_modulus"] + 4.0 / 3.0 * self.host["shear_modulus"]

    def wave_speed(self, field_magnitude: float = 0.0) -> float:
        """Largest elastic wave speed sqrt((c (K + 4G/3) + |B||Br|/mu0) / rho) over particles, m/s.
        The magnetic term bounds the stiffening a field of magnitude ``field_magnitude`` (T) adds; c bounds that of
        a stimulus, the largest f det F_s it reaches (:meth:`magsoro.mpm.laws.eigenstrain.Stimulus.stiffening`; 1 without)."""
        h = self.host
        br = np.linalg.norm(h["remanence"], axis=1)
        # P-wave modulus: K + 4G/3, in plane stress E / (1 - nu^2) (smaller)
        if self.plane == "stress":
            elastic = plane_stress_modulus(h["shear_modulus"], h["bulk_modulus"])
        else:
            elastic = h["bulk_modulus"] + 4.0 * h["shear_modulus"] / 3.0
        modulus = elastic * h["stiffening"] + field_magnitude * br / MU0
        return float(np.sqrt(np.max(modulus / h["density"])))


@dataclass
class State:
    """Particle state: x (positions, m), v (velocities, m/s), C (affine velocity, 1/s), F (deformation gradient);
    with Prony materials also H (N, 1 + terms), their internal stresses (:mod:`magsoro.mpm.laws.viscous`)."""

    x: wp.array
    v: wp.array
    C: wp.array
    F: wp.array
    time: float = 0.0
    step: int = 0
    H: wp.array | None = None

    def numpy(self) -> dict:
        out = {"x": self.x.numpy(), "v": self.v.numpy(), "C": self.C.numpy(), "F": self.F.numpy()}
        if self.H is not None:
            out["H"] = self.H.numpy()
        return out

    def assign(self, other: "State") -> None:
        wp.copy(self.x, other.x)
        wp.copy(self.v, other.v)
        wp.copy(self.C, other.C)
        wp.copy(self.F, other.F)
        if self.H is not None:
            wp.copy(self.H, other.H)
        self.time, self.step = other.time, other.step


@dataclass
class Control:
    """Time-dependent drives: field sources (see :mod:`magsoro.fields`) and rigid colliders."""

    sources: list = field(default_factory=list)
    colliders: list[Collider] = field(default_factory=list)


@dataclass
class ContactSettings:
    """Contact between contact groups and within one (:mod:`magsoro.mpm.kernels.contact`).

    friction: (G, G) Coulomb coefficients between groups (symmetric; entry (g, g) is group g's self-contact);
    ``STICKY`` (any negative value) makes a pair share one velocity field, i.e. stick and never separate.
    self_contact: split a node into two fields where one group's particles there come from layers more than
    about 2 x ``fold_spread`` cells apart in the reference configuration. fold_spread: in cells. gap: two fields
    of a node touch when their local centroids are less than ``gap`` cells apart (touching flat surfaces give about
    1.3 at 2 particles per cell, a corner passing over a surface more): larger gaps add drag at leading edges."""

    friction: np.ndarray
    self_contact: bool = False
    fold_spread: float = 1.5
    gap: float = 1.5

    STICKY = -1.0

    def __post_init__(self):
        f = np.atleast_2d(np.asarray(self.friction, dtype=np.float64))
        if f.ndim != 2 or f.shape[0] != f.shape[1]:
            raise ValueError(f"contact friction must be a square (groups x groups) table, got shape {f.shape}")
        if not np.all(np.isfinite(f)):
            raise ValueError("contact friction must be finite (negative for sticky)")
        if not np.allclose(f, f.T):
            raise ValueError("contact friction table must be symmetric")
        if not (self.fold_spread > 0 and np.isfinite(self.fold_spread)):
            raise ValueError(f"fold_spread must be finite and > 0 cells, got {self.fold_spread}")
        self.friction = f

    def active(self, groups: int) -> bool:
        """True when some pair of the ``groups`` groups present can separate or slide (else one field does)."""
        f = self.friction[:groups, :groups]
        between = f[~np.eye(groups, dtype=bool)] if groups > 1 else np.zeros(0)
        return bool(np.any(between >= 0) or (self.self_contact and np.any(np.diag(f) >= 0)))


@dataclass
class SolverSettings:
    """Numerical settings. damping c in 1/s (f = -c p); gravity m/s^2 (dim components); walls: domain-boundary
    contact mode; grid_margin: free cells kept around the particles; plane_z: z of the 2D plane for fields;
    velocity_gradient: where the F update takes its velocity gradient from, "remap" (the particles' new affine
    velocities transferred back to the grid, an extra transfer per step) or "grid" (the node velocities of the
    momentum update; cheaper, but nodes with little mass at the free surfaces carry force impulses that make
    stressed bodies creep: docs/engine.md); formulation: "updated" (updated Lagrangian, the grid weights are
    taken at the current positions) or "total" (total Lagrangian: weights, node forces and the velocity gradient
    are taken on the reference configuration, F grows by dt grad_X v, no colliders; a node is held when at least
    half of its mass comes from clamped particles, so a clamp acts at the clamped region's face; see
    docs/engine.md); contact: :class:`ContactSettings` (None: every body moves in one velocity field, sticky);
    threads: CPU threads a step is split over (None: automatic, see :func:`resolve_threads`;
    ignored on CUDA)."""

    damping: float = 0.0
    gravity: tuple = (0.0, 0.0, 0.0)
    walls: ColliderModeName = "slip"
    wall_friction: float = 0.0
    cfl: float = 0.4
    grid_margin: int = 4
    plane_z: float = 0.0
    velocity_gradient: VelocityGradient = "remap"
    formulation: Formulation = "updated"
    formulation_auto: bool = False  # the scene left the formulation to the builder ("auto"), which chose this one
    threads: int | None = None
    contact: ContactSettings | None = None
    magnetic_interaction: InteractionMode = "none"  # "dipole": the bodies' own field acts on them (magsoro.mpm.interaction)
    interaction_every: int = 1  # steps between refreshes of the bodies' field
    depth: float = 1.0  # 2D: the out-of-plane thickness the particle volumes include (m), for the 2D field
    # damping in time ((times, values), linear between, held outside; simulation.damping = { times, values }): None
    # for a constant ``damping``. A profile given as ``damping`` (a table with times and values) is moved here.
    damping_profile: tuple | None = None

    def __post_init__(self):
        d = self.damping
        if not isinstance(d, (int, float)):
            times, values = (d["times"], d["values"]) if isinstance(d, dict) else (d.times, d.values)
            self.damping_profile = (tuple(float(t) for t in times), tuple(float(v) for v in values))
        if self.damping_profile is not None:
            self.damping = self.damping_profile[1][0]
        self.damping = float(self.damping)

    def damping_at(self, t: float) -> float:
        """The damping c (1/s) at time ``t`` (s): ``damping``, or the profile's value there."""
        if self.damping_profile is None:
            return self.damping
        return float(np.interp(t, *self.damping_profile))
