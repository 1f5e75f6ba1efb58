"""What a run is checked against before it starts: its memory, its step count and the finiteness of its time step;
and the field and remanence values a scene may not mean.

A scene whose numbers are legal but far out (a density of 1e-30 kg/m^3, a field of 1e30 T, a dx small enough for
10^8 particles) would otherwise build for minutes and end in a MemoryError, or step for ever at steps of 1e-21 s.
Each check names the scene key behind the number; ``magsoro run --allow-large`` (and ``magsoro sweep
--allow-large``) goes ahead past the memory and step limits anyway.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from magsoro.constants import MU0
from magsoro.errors import SceneError

#: explicit steps a run may take without --allow-large: 10^5 to 10^6 is usual; 10^8 is hours on any machine
MAX_STEPS = 1e8
#: host memory per particle of a built, stepping run (model, two states and a window's checkpoint, the grid
#: block and scratch; float64 needs about as much again of some of them), measured on 2D and 3D blocks
BYTES_PER_PARTICLE = {2: 800, 3: 1500}
#: while a body is filled, every candidate lattice site of its bounding box is held as float64 coordinates a few
#: times over (the site grid, the stacked positions, the containment test)
FILL_BYTES_PER_SITE = {2: 3 * 2 * 8, 3: 3 * 3 * 8}
#: the share of the available memory a run may be estimated to take before it is refused
MEMORY_SHARE = 0.9
#: |B| above this (T) is noted: lab electromagnets and permanent magnets near a robot stay well below it
PLAUSIBLE_FIELD_T = 2.0
#: |Br| above this (T) is noted: the strongest sintered NdFeB magnets reach about 1.5 T, an elastomer loaded with
#: their powder far less
PLAUSIBLE_REMANENCE_T = 1.6
ALLOW_FLAG = "--allow-large"


# ------------------------------------------------------------------------------------------------ memory
def available_memory() -> tuple[float, str]:
    """(bytes, where the number comes from) a new run may use: the memory the kernel reports available, lowered
    to what the control group's limit leaves (a container or a Slurm job)."""
    best, where = math.inf, "unknown"
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                best, where = float(line.split()[1]) * 1024.0, "MemAvailable in /proc/meminfo"
                break
    except (OSError, ValueError, IndexError):
        pass
    if not math.isfinite(best):
        try:
            best, where = float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")), "physical memory"
        except (AttributeError, ValueError, OSError):
            pass
    try:
        cg = Path("/sys/fs/cgroup")
        limit = (cg / "memory.max").read_text().strip()
        if limit != "max":
            left = float(limit) - float((cg / "memory.current").read_text().strip())
            if left < best:
                best, where = left, "the control group's memory.max less its memory.current"
    except (OSError, ValueError):
        pass
    return best, where


def estimate_memory(scene) -> tuple[float, float, list[tuple[str, float]]]:
    """(bytes, particles, [(body key, particles)]) a scene is estimated to need once built, from its bodies'
    shapes at the particle spacing, without filling any lattice. A shape that cannot be made is skipped (the build
    reports it)."""
    from magsoro.scene.build import make_shape

    sim = scene.simulation
    dim, h = sim.dim, sim.dx / sim.particles_per_cell
    total, fill_peak, per_body = 0.0, 0.0, []
    for i, b in enumerate(scene.bodies):
        base_dir = b.base_dir if b.base_dir is not None else scene.base_dir
        try:
            shape = make_shape(b.shape, base_dir, dim)
            lo, hi = (np.asarray(v, dtype=np.float64)[:dim] for v in shape.bounds())
            sites = float(np.prod(np.floor((hi - lo) / h) + 1.0))
            try:
                particles = min(sites, float(shape.volume()) / h**dim)
            except (NotImplementedError, ValueError, TypeError):
                particles = sites
        except Exception:  # noqa: BLE001 - the build names a bad shape with its key; the estimate only skips it
            continue
        if not (math.isfinite(particles) and math.isfinite(sites)):
            continue
        per_body.append((b.key or f"bodies[{i}]", particles))
        total += particles
        fill_peak = max(fill_peak, sites * FILL_BYTES_PER_SITE[dim])
    return total * BYTES_PER_PARTICLE[dim] + fill_peak, total, per_body


def check_memory(scene, source: str, allow_large: bool = False) -> None:
    """Refuse (SceneError, one line naming simulation.dx and the largest body) a scene estimated to need more than
    MEMORY_SHARE of the memory available, before anything is allocated; ``allow_large`` skips the check."""
    if allow_large:
        return
    need, particles, per_body = estimate_memory(scene)
    have, where = available_memory()
    if not (need > MEMORY_SHARE * have):
        return
    sim = scene.simulation
    key, most = max(per_body, key=lambda kv: kv[1])
    raise SceneError(
        f"{source}: simulation.dx: about {particles:.3g} particles at the particle spacing "
        f"{sim.dx / sim.particles_per_cell:g} m ({key} {most:.3g}) would need about {need / 1e9:.3g} GB; "
        f"{have / 1e9:.3g} GB are available ({where}) and a run may take {100 * MEMORY_SHARE:.0f} % of it: coarsen "
        f"simulation.dx, check the shapes' sizes and units, or add {ALLOW_FLAG} to try anyway")


# ------------------------------------------------------------------------------------------------- steps
def source_peaks(sim) -> list[float]:
    """Largest |B| (T) each applied field source gives at the bodies' reference positions, in scene order."""
    host = sim.model.host["positions"]
    pts = np.zeros((len(host), 3))
    pts[:, : sim.dim] = host
    if sim.dim == 2:
        pts[:, 2] = sim.solver.settings.plane_z
    peaks = []
    with np.errstate(all="ignore"):
        for s in sim.control.sources:
            peaks.append(float(sum(e.max_magnitude(pts, 0.0) for e in s.sources())))
    return peaks


def _field_key(sim, i: int) -> str:
    fields = sim.scene.fields
    if i < len(fields) and len(fields) == len(sim.control.sources):
        name = getattr(fields[i], "name", None)
        return f"fields[{i}]" + (f" ('{name}', {fields[i].type})" if name else f" ({fields[i].type})")
    return f"field source {i}"


def _body_key(sim, b: int) -> str:
    bodies = sim.scene.bodies
    return (bodies[b].key or f"bodies[{b}]") if b < len(bodies) else f"body {b}"


def step_cause(sim) -> str:
    """The scene key that sets the explicit time step, with its value: a fixed simulation.dt, the field source or
    the body whose wave speed bounds it, or the grid spacing and the duration."""
    if sim.fixed_dt is not None:
        return f"simulation.dt = {sim.fixed_dt:.3g} s"
    h = sim.model.host
    peaks = source_peaks(sim)
    for i, p in enumerate(peaks):
        if not math.isfinite(p):
            return f"{_field_key(sim, i)}: its field at the bodies is not finite ({p}); check its sizes, position and strength"
    with np.errstate(all="ignore"):
        field_peak = sim.solver.field_magnitude(sim.control)
        wave_speed = sim.model.wave_speed(field_peak)
    v0 = sim.built.initial_velocity
    speed = float(np.max(np.linalg.norm(v0, axis=1))) if v0 is not None and len(v0) else 0.0
    if not math.isfinite(speed) or speed > wave_speed:
        return f"the initial velocities (bodies[].velocity, up to {speed:.3g} m/s)"
    br = np.linalg.norm(h["remanence"], axis=1)
    elastic = (h["bulk_modulus"] + 4.0 * h["shear_modulus"] / 3.0) * h["stiffening"]
    magnetic = field_peak * br / MU0
    with np.errstate(all="ignore"):
        k = int(np.nanargmax((elastic + magnetic) / h["density"]))
    b = int(h["body"][k])
    who = _body_key(sim, b)
    if magnetic[k] > elastic[k] and peaks:
        i = int(np.argmax(peaks))
        return (f"{_field_key(sim, i)} (|B| up to {peaks[i]:.3g} T at the bodies, with {who}'s |Br| = {br[k]:.3g} T: "
                f"magnetic stiffening)")
    rho, G = float(h["density"][k]), float(h["shear_modulus"][k])
    c = math.sqrt(float(elastic[k] / rho)) if rho > 0 else math.inf
    if rho < 100.0:
        return f"{who}.material.density = {rho:.3g} kg/m^3 (wave speed {c:.3g} m/s)"
    if G > 1e9:
        return f"{who}.material.shear_modulus = {G:.3g} Pa (wave speed {c:.3g} m/s)"
    return (f"simulation.duration = {sim.scene.simulation.duration:g} s at simulation.dx = {sim.model.dx:g} m "
            f"(wave speed {c:.3g} m/s in {who})")


def check_time_step(sim, source: str) -> list[float]:
    """Refuse (SceneError naming the key) a run whose applied field at the bodies or whose first time step is not
    a finite positive number: it would sit at t = 0 for ever. Returns :func:`source_peaks`."""
    peaks = source_peaks(sim)
    for i, p in enumerate(peaks):
        if not math.isfinite(p):
            raise SceneError(f"{source}: {_field_key(sim, i)}: the field it gives at the bodies is not finite ({p} T); "
                             f"check its sizes, position and strength")
    if sim.integrator != "implicit" and not (math.isfinite(sim.dt) and sim.dt > 0.0):
        raise SceneError(f"{source}: the time step is not a finite positive number ({sim.dt!r} s); it is set by "
                         f"{step_cause(sim)}")
    return peaks


def time_step_problem(sim, dt: float) -> str:
    """The message of a SimulationError for a computed time step ``dt`` that is not finite and positive."""
    return f"the time step is not a finite positive number ({dt!r} s); it is set by {step_cause(sim)}"


def check_steps(sim, duration: float, source: str, allow_large: bool = False) -> float:
    """The estimated explicit step count of a run of ``duration`` s (from the first time step; the implicit
    integrator's: 0). Refuses (SceneError naming the key that sets the step) more than MAX_STEPS unless
    ``allow_large``."""
    if sim.integrator == "implicit":
        return 0.0
    steps = duration / sim.dt
    if steps > MAX_STEPS and not allow_large:
        raise SceneError(f"{source}: about {steps:.3g} time steps of {sim.dt:.3g} s over {duration:g} s, more than "
                         f"{MAX_STEPS:.0e}; the step is set by {step_cause(sim)}: check that value and its units, "
                         f"or add {ALLOW_FLAG} to run it anyway")
    return steps


# ------------------------------------------------------------------------------------------- plausibility
def plausibility_notes(sim, peaks: list[float] | None = None) -> list[str]:
    """Notes on field and remanence values no magnetic soft robot meets: |B| above PLAUSIBLE_FIELD_T from a source
    (mT typed as T?), |Br| above PLAUSIBLE_REMANENCE_T in a body (the magnetisation M in A/m, or a magnet's own
    remanence, typed as the composite's?). The run goes on; run.json's notes keep them. ``peaks``: the sources'
    :func:`source_peaks` when known."""
    notes = []
    for i, p in enumerate(source_peaks(sim) if peaks is None else peaks):
        if math.isfinite(p) and p > PLAUSIBLE_FIELD_T:
            notes.append(f"{_field_key(sim, i)}: |B| reaches {p:.3g} T at the bodies, above {PLAUSIBLE_FIELD_T:g} T "
                         f"(more than lab coils and magnets give a soft robot): fields are in tesla, was it mT?")
    h = sim.model.host
    br = np.linalg.norm(h["remanence"], axis=1)
    for b in np.unique(h["body"]):
        top = float(br[h["body"] == b].max(initial=0.0))
        if top > PLAUSIBLE_REMANENCE_T:
            notes.append(f"{_body_key(sim, int(b))}.magnetization: |Br| = {top:.3g} T, above {PLAUSIBLE_REMANENCE_T:g} T "
                         f"(the strongest NdFeB magnets reach about 1.5 T, an elastomer loaded with them far less): "
                         f"Br is in tesla, was it mT?")
    return notes
