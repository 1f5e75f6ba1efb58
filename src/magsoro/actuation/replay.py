"""Replay of a magnet-path plan by the MPM engine (2D plane strain or 3D), growth included.

The planned robot is a strip clamped at its base. Each PRB link becomes one body of the scene (a rectangle, or in
3D a box of the strip's thickness and depth, with its own remanence: the magnetisation profile), behind the base
sits an unmagnetised stub whose rear part is clamped. The bodies share the MPM grid, so they act as one continuous
strip.

In 3D the robot is a free beam of section thickness x depth centred on the plan's plane z = plane_z, and it feels
the magnet's whole field: the out-of-plane component B_z, which the planar PRB and the 2D replay leave out, turns a
link's in-plane moment out of the plane (torque m x B), and the field's gradient pulls it towards the magnet. The
3D replay measures what that does to the planned shape (``out_of_plane``), and what a frictionless floor under the
robot with gravity (``floor = True``) leaves of it.

Growth. The engine's Model is fixed during a run, so eversion is replayed step by step: step k runs its own
Simulation holding the links everted at step k. When a step ends, the next Simulation receives the state of the
particles it shares with the last one (they come first, in the same order, because the bodies are listed from
the base and the lattice is the same), and the particles of the new links are placed as a rigid, unstrained
continuation of the tip: x = x_c + R (X - X_c), F = R, with (R, x_c) the best rigid fit (Procrustes) of the
current last link to its reference. This is what eversion does: new material appears at the tip, stress-free,
aligned with it.

The magnet follows the plan's :class:`~magsoro.actuation.epm_path.KeyframedDipole` (a source appended to
``sim.control.sources``), the same keyframes the PRB check follows. The tip is measured the same way in both
models: the MPM tip is the reference tip point (s = L_k on the centre line) mapped by the rigid fit of the last
link, the PRB tip is the end of the last link.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from magsoro.constants import MU0
from magsoro.errors import SimulationError
from magsoro.mpm.timestep import cfl_time_step
from magsoro.actuation.planning import Plan, PlanarPRB, plane_strain_modulus

#: gravity of the 3D replay's floor variant, m/s^2
GRAVITY = 9.81


@dataclass
class StripSpec:
    """The plane-strain strip the plan is replayed on (SI): in-plane ``thickness`` and out-of-plane ``depth``
    (m), ``shear_modulus`` and ``bulk_modulus`` (Pa), ``density`` (kg/m^3). The remanence of each link follows
    from the plan's link moments, Br = mu0 m / V."""

    thickness: float
    depth: float
    shear_modulus: float
    bulk_modulus: float
    density: float

    def first_period(self, length: float) -> float:
        """First bending period (s) of the clamped strip of ``length`` (m), Euler-Bernoulli."""
        EI = plane_strain_modulus(self.shear_modulus, self.bulk_modulus) * self.thickness**3 * self.depth / 12.0
        mu = self.density * self.thickness * self.depth
        omega = 1.875104**2 * math.sqrt(EI / (mu * length**4))
        return 2.0 * math.pi / omega


@dataclass
class ReplayResult:
    """Tip paths of the replay (times in s, positions in m).

    times, tip_mpm, tip_prb : samples of the whole replay; tip_prb is the quasi-static PRB equilibrium under the
    same keyframed magnet at those times. step_end_mpm, step_end_prb : (K, 2) tips at the end of each step
    (the settled states the plan specifies). wall_time : s; steps : MPM steps taken; particles : at the end.
    In 3D (``dim`` 3) tip_mpm, step_end_mpm and the MPM joints have three components and the PRB's two are
    compared in the plane (the PRB lies in z = ``plane_z``).
    """

    times: np.ndarray
    tip_mpm: np.ndarray
    tip_prb: np.ndarray
    step_end_mpm: np.ndarray
    step_end_prb: np.ndarray
    step_end_joints_mpm: list
    step_end_joints_prb: list
    step_duration: float
    wall_time: float
    steps: int
    particles: int
    dt: float
    dim: int = 2
    plane_z: float = 0.0

    def _lift(self, a: np.ndarray) -> np.ndarray:
        """PRB points (..., 2) in the MPM's space: z = plane_z added in 3D."""
        if self.dim == 2:
            return a
        return np.concatenate([a, np.full(a.shape[:-1] + (1,), self.plane_z)], axis=-1)

    @property
    def step_end_errors(self) -> np.ndarray:
        """|tip_MPM - tip_PRB| (m) at the end of each step (in 3D the distance in space, out of the plane included)."""
        return np.linalg.norm(self.step_end_mpm - self._lift(self.step_end_prb), axis=1)

    @property
    def step_end_in_plane_errors(self) -> np.ndarray:
        """|tip_MPM - tip_PRB| (m) at the end of each step in the robot's plane (x, y)."""
        return np.linalg.norm(self.step_end_mpm[:, :2] - self.step_end_prb, axis=1)

    @property
    def path_errors(self) -> np.ndarray:
        """|tip_MPM - tip_PRB| (m) at every sample, moves included (the MPM lags the quasi-static PRB while the
        magnet moves)."""
        return np.linalg.norm(self.tip_mpm - self._lift(self.tip_prb), axis=1)

    @property
    def out_of_plane(self) -> np.ndarray:
        """z_tip - plane_z (m) at every sample (zero in 2D)."""
        if self.dim == 2:
            return np.zeros(len(self.tip_mpm))
        return self.tip_mpm[:, 2] - self.plane_z


def _rigid_fit(X, x):
    """Rotation R (dim x dim) and centroids (X_c, x_c) of the best rigid map X -> x (Kabsch)."""
    Xc, xc = X.mean(axis=0), x.mean(axis=0)
    H = (X - Xc).T @ (x - xc)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    D = np.ones(X.shape[1])
    D[-1] = d
    R = Vt.T @ np.diag(D) @ U.T
    return R, Xc, xc


def _check_multiple(value, h, what):
    k = value / h
    if abs(k - round(k)) > 1e-6 * max(1.0, k):
        raise ValueError(f"{what} ({value:g} m) must be a multiple of dx / particles_per_cell = {h:g} m so that the "
                         "particle lattice splits exactly at link ends")


def beam_robot(prb: PlanarPRB, strip: StripSpec) -> PlanarPRB:
    """The PRB of the 3D replay's body: the same links with the bending (and axial) stiffness of a free beam,
    Young's modulus E in place of the plane-strain E / (1 - nu^2) the plan's strip carries (1 - nu^2 = 0.88 at
    nu = 0.35: the 3D beam is that much softer)."""
    import dataclasses

    G, K = strip.shear_modulus, strip.bulk_modulus
    ratio = (9.0 * K * G / (3.0 * K + G)) / plane_strain_modulus(G, K)
    axial = None if prb.axial_stiffness is None else prb.axial_stiffness * ratio
    return dataclasses.replace(prb, bending_stiffness=prb.bending_stiffness * ratio, axial_stiffness=axial)


def planar_pair(source, plane_z: float = 0.0):
    """The field a planar model sees, as a 3D source: the keyframed dipole ``source`` and its mirror image in the
    plane z = plane_z (moment (m_x, m_y, -m_z) at (x, y, 2 plane_z - z)), each with half the moment. On the plane
    the pair's B is the magnet's (B_x, B_y, 0), its in-plane gradients the magnet's, and d(B_x, B_y)/dz = 0; it is
    symmetric about the plane. A :class:`~magsoro.fields.base.FieldSum` of two keyframed dipoles."""
    from magsoro.actuation.epm_path import KeyframedDipole
    from magsoro.fields.base import FieldSum

    flip = np.array([1.0, 1.0, -1.0])
    mirror = source.positions * flip + [0.0, 0.0, 2.0 * plane_z]
    return FieldSum([KeyframedDipole(source.times, source.positions, 0.5 * source.moments),
                     KeyframedDipole(source.times, mirror, 0.5 * source.moments * flip)])


def prb_path(plan: Plan, robot: PlanarPRB, step_duration: float, move_fraction: float = 0.5,
             samples_per_step: int = 10):
    """The PRB ``robot``'s quasi-static equilibria under the plan's keyframed magnet, grown at each step's start
    and followed sample by sample as the replay samples: (times (K s,), link angles at each sample, and at each
    step's end)."""
    T = float(step_duration)
    source = plan.keyframes(T, move_fraction)
    theta = robot.straight(0)
    times, thetas, ends = [], [], []
    for k, step in enumerate(plan.steps):
        theta = robot.grow(theta, step.links)
        for j in range(1, samples_per_step + 1):
            tj = k * T + T * j / samples_per_step
            theta = robot.equilibrium(source.dipole_at(tj), theta)
            times.append(tj)
            thetas.append(theta)
        ends.append(theta)
    return np.array(times), thetas, ends


def link_remanence(prb: PlanarPRB, strip: StripSpec) -> np.ndarray:
    """Remanence (n, 3) in T of each link in the reference frame (the strip along +x): mu0 m / (l t depth)."""
    br = np.zeros((prb.n_links, 3))
    br[:, :2] = MU0 * prb.link_moments / (prb.link_length * strip.thickness * strip.depth)
    return br


def _scene(prb: PlanarPRB, strip: StripSpec, n_links: int, dx: float, ppc: int, domain, damping: float,
           dt: float, dim: int = 2, floor: bool = False) -> dict:
    ell, t = prb.link_length, strip.thickness
    remanence = link_remanence(prb, strip)
    bx, by = prb.base_position
    mat = {"density": strip.density, "shear_modulus": strip.shear_modulus, "bulk_modulus": strip.bulk_modulus}
    stub = 4 * dx
    if dim == 2:
        def shape(cx, cy, length, width):
            return {"type": "rectangle", "center": [cx, cy], "size": [length, width]}
    else:  # a box of the strip's section, centred on the plan's plane
        def shape(cx, cy, length, width):
            return {"type": "box", "center": [cx, cy, prb.plane_z], "size": [length, width, width / t * strip.depth]}
    bodies = [{"name": "stub", "shape": shape(bx - 0.5 * stub, by, stub, t), "material": mat}]
    for j in range(n_links):
        br = remanence[j]
        bodies.append({"name": f"link{j}", "shape": shape(bx + (j + 0.5) * ell, by, ell, t),
                       "material": mat, "magnetization": [float(v) for v in br]})
    sim = {"dim": dim, "dx": dx, "particles_per_cell": ppc, "domain_lo": list(domain[0]), "domain_hi": list(domain[1]),
           "duration": 1.0, "dt": dt, "damping": damping}
    if dim == 2:
        sim.update(depth=strip.depth, plane_z=prb.plane_z)
    scene = {
        "name": f"plan replay, {n_links} links",
        "simulation": sim,
        "bodies": bodies,
        # the rear of the stub is held; its nodes reach to the base point x = bx, where the PRB clamp sits
        "clamps": [{"region": shape(bx - 2.5 * dx, by, 3 * dx, 2 * t), "body": "stub"}],
        "contact": {"bonded": "touching"},  # the stub and the links are one strip, glued end to end
        "output": {"particles": False},
    }
    if floor:  # a frictionless floor under the strip's lower face, with gravity
        sim["gravity"] = [0.0, 0.0, -GRAVITY]
        scene["colliders"] = [{"type": "half_space", "point": [bx, by, prb.plane_z - 0.5 * strip.depth],
                               "normal": [0.0, 0.0, 1.0], "mode": "slip"}]
    return scene


def replay(plan: Plan, strip: StripSpec, dx: float, step_duration: float | None = None, move_fraction: float = 0.5,
           damping_ratio: float = 1.0, particles_per_cell: int = 2, cfl: float = 0.4, samples_per_step: int = 10,
           progress=None, on_sample=None, dim: int = 2, floor: bool = False,
           out_of_plane_room: float | None = None, check_robot: PlanarPRB | None = None,
           record=None, planar_field: bool = False) -> ReplayResult:
    """Run the plan's magnet keyframes on the MPM strip, one Simulation per growth step (see module docstring).

    dx : grid spacing (m); the link length and the thickness (and in 3D the depth) must be multiples of
    dx / particles_per_cell.
    step_duration : simulated time per plan step (s); default the first bending period of the full strip.
    damping_ratio : grid damping c = 2 zeta omega_1(L_k) of the links everted at each step.
    dim : 2 (plane strain, the planar field) or 3 (a free beam in the whole 3D field).
    floor : 3D only: a frictionless floor under the strip and gravity (9.81 m/s^2, -z).
    out_of_plane_room : 3D only: room (m) above and below the strip for its out-of-plane motion; default half
    the robot's final length (below the floor when there is one: none).
    planar_field : 3D only: the MPM robot feels the field the planar PRB sees instead of the magnet's: the magnet
    and its mirror image in the plan's plane (moment (m_x, m_y, -m_z) at (x, y, 2 plane_z - z)), each of half the
    moment. On the plane that pair has the magnet's in-plane field and gradients and no B_z, and it is symmetric
    about the plane, so a free robot stays in it: the 3D body against its PRB, the out-of-plane field removed.
    check_robot : the PRB the MPM is compared with (tip_prb, and the step ends as its equilibria at the end of each
    step); default the plan's robot, whose step ends are the planned shapes. For the 3D body,
    :func:`beam_robot` is the like-for-like PRB.
    progress(k, sim) : called after each step; on_sample(t, tip_mpm, tip_prb) after each sample; record(sim) after
    each sample too (e.g. an animation's frames; the particle count grows with the links).
    """
    import time

    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    prb = plan.robot
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    if floor and dim != 3:
        raise ValueError("floor needs dim = 3 (the floor lies under the strip, out of the 2D plane)")
    if planar_field and dim != 3:
        raise ValueError("planar_field needs dim = 3 (the 2D replay sees the in-plane field only anyway)")
    if abs(prb.base_angle) > 1e-12:
        raise ValueError("the MPM replay builds the strip along +x: plan with base_angle = 0")
    h = dx / particles_per_cell
    _check_multiple(prb.link_length, h, "link length")
    _check_multiple(strip.thickness, h, "thickness")
    if dim == 3:
        _check_multiple(strip.depth, h, "depth")
    ell, t = prb.link_length, strip.thickness
    n_final = plan.steps[-1].links
    L = n_final * ell
    T = step_duration if step_duration is not None else strip.first_period(L)
    source = plan.keyframes(T, move_fraction)
    mpm_source = source
    if planar_field:
        mpm_source = planar_pair(source, prb.plane_z)

    # domain: everything the PRB plan visits plus the stub, with room for the dynamics; aligned with the base
    # so the lattice splits at the link ends
    # (the bodies are built straight, in the reference configuration, so that must fit as well)
    pts = np.vstack([prb.joints(s.theta) for s in plan.steps]
                    + [prb.base_position - [5 * dx, 0.0], prb.base_position + [L, 0.0]])
    margin = t + 12 * dx
    bx, by = prb.base_position
    lo = np.floor((pts.min(axis=0) - margin - [bx, by]) / dx) * dx + [bx, by]
    hi = np.ceil((pts.max(axis=0) + margin - [bx, by]) / dx) * dx + [bx, by]
    lo[1] = by - dx * math.ceil((by - lo[1]) / dx)
    if dim == 3:  # z: the section and the room for out-of-plane motion, the lattice split at the plane
        room = 0.5 * L if out_of_plane_room is None else float(out_of_plane_room)
        half = 0.5 * strip.depth
        below = half + (4 * dx if floor else room + 4 * dx)
        above = half + room + 4 * dx
        z0 = prb.plane_z - half  # the strip's lower face lies on a lattice plane
        lo = np.append(lo, z0 - dx * math.ceil((below - half) / dx))
        hi = np.append(hi, z0 + dx * math.ceil((above + half) / dx))

    # time step: CFL with the elastic and magnetic wave speed over the whole plan
    from magsoro.fields.dipole import Dipole

    B_max = 0.0
    for s in plan.steps:
        p3, _, _ = prb.load_points(s.theta)
        B_max = max(B_max, float(np.max(np.linalg.norm(Dipole(s.moment, s.position).B(p3), axis=1))))
    br_max = float(np.max(np.linalg.norm(link_remanence(prb, strip), axis=1)))
    c = math.sqrt((strip.bulk_modulus + 4.0 * strip.shear_modulus / 3.0 + 2.0 * B_max * br_max / MU0) / strip.density)
    dt = cfl_time_step(cfl, dx, c)

    times, tip_mpm, tip_prb, end_mpm, end_prb, joints_mpm, joints_prb = [], [], [], [], [], [], []
    prev = None  # (state arrays, last-link indices, reference positions) of the previous step
    wall0 = time.perf_counter()
    total_steps = 0
    ref = prb if check_robot is None else check_robot
    _, ref_thetas, ref_ends = prb_path(plan, ref, T, move_fraction, samples_per_step)
    for k, step in enumerate(plan.steps):
        n = step.links
        Lk = n * ell
        damping = 2.0 * damping_ratio * 2.0 * math.pi / strip.first_period(Lk)
        sim = Simulation(parse_scene(_scene(prb, strip, n, dx, particles_per_cell, (lo, hi), damping, dt, dim, floor),
                                     source=f"replay step {k}"))
        sim.control.sources.append(mpm_source)
        X = sim.model.host["positions"]
        if prev is not None:
            s_old, idx_last, X_old = prev
            m_old = len(X_old)
            if not np.allclose(X[:m_old], X_old):
                raise RuntimeError("growth step changed the particles of the everted links")
            R, Xc, xc = _rigid_fit(X_old[idx_last], s_old["x"][idx_last])
            new = np.arange(m_old, len(X))
            x = np.empty_like(X)
            x[:m_old] = s_old["x"]
            x[new] = xc + (X[new] - Xc) @ R.T
            v = np.zeros_like(X)
            v[:m_old] = s_old["v"]
            C = np.zeros((len(X), dim, dim))
            C[:m_old] = s_old["C"]
            F = np.tile(R, (len(X), 1, 1))
            F[:m_old] = s_old["F"]
            st = sim.state
            scal = sim.model.np_scalar
            st.x.assign(x.astype(scal))
            st.v.assign(v.astype(scal))
            st.C.assign(C.astype(scal))
            st.F.assign(F.astype(scal))
        sim.state.time = k * T
        body = sim.model.host["body"]
        idx_last = np.flatnonzero(body == n)  # body 0 is the stub, link j is body j + 1
        on_plane = [prb.plane_z] if dim == 3 else []
        tip_ref = np.array([bx + Lk, by] + on_plane)

        def tip_now():
            x = sim.state.x.numpy().astype(np.float64)
            R, Xc, xc = _rigid_fit(X[idx_last], x[idx_last])
            return xc + R @ (tip_ref - Xc)

        for j in range(1, samples_per_step + 1):
            tj = k * T + T * j / samples_per_step
            try:
                sim.advance_to(tj)
            except SimulationError as exc:
                raise SimulationError(f"plan step {k} ({n} links) of the replay: {exc}", exc.step, exc.time) from None
            times.append(tj)
            tip_mpm.append(tip_now())
            tip_prb.append(ref.tip(ref_thetas[k * samples_per_step + j - 1]))
            if on_sample is not None:
                on_sample(tj, tip_mpm[-1], tip_prb[-1])
            if record is not None:
                record(sim)
        total_steps += sim.steps
        end_mpm.append(tip_mpm[-1])
        theta_end = step.theta if check_robot is None else ref_ends[k]
        end_prb.append(ref.tip(theta_end))
        # MPM joints: the reference link ends mapped by each link's rigid fit (base of each link, then the tip)
        x_now = sim.state.x.numpy().astype(np.float64)
        joints = []
        for j in range(n):
            idx = np.flatnonzero(body == j + 1)
            R, Xc, xc = _rigid_fit(X[idx], x_now[idx])
            joints.append(xc + R @ (np.array([bx + j * ell, by] + on_plane) - Xc))
        joints.append(tip_mpm[-1])
        joints_mpm.append(np.array(joints))
        joints_prb.append(ref.joints(theta_end))
        s_np = sim.state.numpy()
        prev = ({key: s_np[key].astype(np.float64) for key in ("x", "v", "C", "F")}, idx_last, X.copy())
        if progress is not None:
            progress(k, sim)
    return ReplayResult(np.array(times), np.array(tip_mpm), np.array(tip_prb), np.array(end_mpm), np.array(end_prb),
                        joints_mpm, joints_prb, T, time.perf_counter() - wall0, total_steps, len(X), dt, dim,
                        float(prb.plane_z))

