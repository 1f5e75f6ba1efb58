"""What the solvers share to run the kernels: the device and CPU threads, the device structs a launch takes
(grid settings, bodies, grid block, contact grid) and the helper threads of a CPU step."""

import math
import os
import queue
import threading
import weakref
from typing import TYPE_CHECKING

import warp as wp

from magsoro.errors import MagsoroError, SimulationError
from magsoro.mpm.settings import ColliderMode

if TYPE_CHECKING:
    from magsoro.mpm.model import Model, SolverSettings


def resolve_device(name: str | None) -> str:
    """'cpu', 'cuda' or 'cuda:N'; None picks CUDA when present, else CPU."""
    if name is None:
        return "cuda" if wp.get_cuda_device_count() > 0 else "cpu"
    if name.startswith("cuda") and wp.get_cuda_device_count() == 0:
        raise SimulationError(f"device {name!r} requested but no CUDA device is available; use device = 'cpu'")
    return name


# Automatic CPU threads: one per this many particles, up to the cores available. Below it a thread's share of a
# step is too small to pay for handing work to another thread (benchmarks/README.md, "CPU threads").
PARTICLES_PER_THREAD = 4000


def usable_cores() -> int:
    """CPU cores this process may run on (its affinity mask; a container's or Slurm's cpuset)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def threads_from_env() -> tuple[int | None, str | None]:
    """(threads, note) from the environment variable MAGSORO_THREADS: (None, None) when unset; a whole number
    >= 1 is capped at the usable cores (more threads than cores only wait for each other: 99,999 of them ran a
    step 2,000 times slower), and the note says so. Anything else raises MagsoroError in one line."""
    env = os.environ.get("MAGSORO_THREADS")
    if env is None or not env.strip():
        return None, None
    try:
        requested = int(env.strip())
    except ValueError:
        requested = 0
    if requested < 1:
        raise MagsoroError(f"MAGSORO_THREADS: must be a whole number >= 1 (CPU threads a step is split over), got {env!r}")
    cores = usable_cores()
    if requested > cores:
        return cores, (f"MAGSORO_THREADS = {requested} is more than the {cores} usable CPU core(s); "
                       f"{cores} thread(s) used")
    return requested, None


def resolve_threads(requested: int | None, device: str, n_particles: int) -> int:
    """Threads a CPU step is split over. ``requested`` None is automatic: the environment variable MAGSORO_THREADS
    if set (sweep workers set 1; capped at the usable cores, :func:`threads_from_env`), else one thread per
    PARTICLES_PER_THREAD particles up to the usable cores. Always 1 on CUDA."""
    if not device.startswith("cpu"):
        return 1
    if requested is None:
        requested, _ = threads_from_env()
        if requested is None:
            requested = min(usable_cores(), n_particles // PARTICLES_PER_THREAD)
    if requested < 1:
        requested = 1
    return int(min(requested, n_particles))


COLLIDER_SKIN = 0.1  # cells: total-Lagrangian nodes touch a collider from this signed distance down


def grid_settings(model: "Model", settings: "SolverSettings", gravity, colliders, n_colliders: int, dt: float,
                  step: wp.array | None = None, impulse: wp.array | None = None):
    """The grid update's :class:`GridSettings` struct (kernels.py): step, damping factor exp(-c dt), gravity (the
    kernels' vector), domain walls, grid spacing and the colliders ``colliders`` (an array of ``n_colliders``
    DeviceCollider structs). ``step``: the solver's one-element Step array (:mod:`magsoro.mpm.kernels.stencil`); the
    kernel then takes dt and the damping factor from it instead of from ``dt``. ``impulse``: float64 array of 3 per collider, to which the
    grid update adds the momentum each collider takes from the nodes (None: not recorded)."""
    sc = model.scalar
    vec = model.kernels["vec"]
    gs = model.kernels["GridSettings"]()
    gs.dt = sc(dt)
    gs.damping_factor = sc(math.exp(-settings.damping * dt))
    gs.gravity = gravity
    gs.dx = sc(model.dx)
    gs.domain_lo = vec(*[sc(v) for v in model.domain_lo])
    gs.domain_hi = vec(*[sc(v) for v in model.domain_hi])
    gs.wall_mode = int(ColliderMode.named(settings.walls))
    gs.wall_friction = sc(settings.wall_friction)
    gs.colliders = colliders
    gs.n_colliders = n_colliders
    gs.clamp_velocity = model.clamp_velocity
    gs.plane_z = wp.float64(settings.plane_z)
    total = settings.formulation == "total"
    gs.node_shift = 1 if total else 0
    # Total Lagrangian: the nodes move with the material, and a resting node sits where the collider stopped it,
    # at a signed distance of about -dt v_impact. Vibrations of a tenth of a cell then lift it out of contact
    # for a step, free of friction, and a block on a 30 degree slope at friction 0.7 crept away (1.8 cells in
    # 40 ms); a skin of a tenth of a cell keeps it in contact (0.15 cells, as the updated form).
    gs.collider_skin = wp.float64(COLLIDER_SKIN * model.dx if total else 0.0)
    if step is None:  # an array all the same: Warp's tape looks at every array of a struct argument
        step = model.placeholder_step
    else:
        gs.stepped = 1
    gs.step = step
    if impulse is None:  # as for step: an array all the same, not written
        impulse = model.placeholder_impulse
    else:
        gs.record_impulse = 1
    gs.collider_impulse = impulse
    if model.plane == "axisymmetric":  # the axis r = 0 is a node line (build.model_domain pads the grid past it)
        gs.axis = 1
        gs.axis_node = int(round(-model.domain_lo[0] / model.dx))
    return gs


def bodies_array(model: "Model", cut=lambda arr: arr, step: wp.array | None = None) -> wp.array:
    """The kernels' per-particle constants (:mod:`magsoro.mpm.kernels.stencil` Bodies) of ``model`` as a one-element
    array, over the slice ``cut`` of its particles (a CPU thread's share; default all). ``step``: the solver's
    one-element Step array, from which the kernels then take dt and the uniform field (else their arguments)."""
    k = model.kernels
    b = k["Bodies"]()
    b.vol0, b.mass, b.shear, b.bulk = cut(model.vol0), cut(model.mass), cut(model.shear), cut(model.bulk)
    b.radius0 = cut(model.radius0)
    b.spacing = model.scalar(model.spacing)
    b.material_model, b.material_params = cut(model.material_model), cut(model.material_params)
    b.Br, b.follows, b.clamped = cut(model.Br), cut(model.follows), cut(model.clamped)
    b.clamp_velocity = model.clamp_velocity  # indexed by clamp code, not by particle: never cut
    # the stimulus tables are indexed by each particle's stimulus row, not by particle: never cut
    b.stimulus, b.stretch_inv, b.stretch_scale = cut(model.stimulus), model.stretch_inv, model.stretch_scale
    b.stretch_hoop_inv = model.stretch_hoop_inv
    b.n_stimuli = len(model.stimuli)
    # pressure loads: per particle its face area vector and row; the table of values is indexed by row
    b.pressure_area, b.pressure_row = cut(model.pressure_area), cut(model.pressure_row)
    b.pressure_value, b.n_pressures = model.pressure_value, len(model.pressures)
    b.pressure_share, b.pressure_net = cut(model.pressure_share), model.pressure_net
    if step is not None:
        b.step, b.stepped = step, 1
    return wp.array([b], dtype=k["Bodies"], device=model.device)


def block_struct(model: "Model", org, shape):
    """The kernels' Block struct (:mod:`magsoro.mpm.kernels.stencil`) of the grid block of ``model``'s grid starting at
    global node ``org`` with ``shape`` nodes."""
    k, sc = model.kernels, model.scalar
    block = k["Block"]()
    block.lo = k["vec"](*[sc(model.domain_lo[a] + org[a] * model.dx) for a in range(model.dim)])
    block.shape = k["ivec"](*[int(v) for v in shape])
    block.dx = sc(model.dx)
    return block


def contact_node_arrays(model: "Model", cap: int, fold: bool) -> dict:
    """Node arrays of the contact classification (:mod:`magsoro.mpm.kernels.contact`) for a grid of ``cap`` nodes: group
    bounds, node class, fold mean and axis, the pair's friction, the two fields' mass gradients and (``fold``)
    the reference-position moments."""
    k, sc, dev, dim = model.kernels, model.scalar, model.device, model.dim
    return {
        "split": wp.zeros(cap, dtype=wp.int32, device=dev), "gmin": wp.zeros(cap, dtype=wp.int32, device=dev),
        "gmax": wp.zeros(cap, dtype=wp.int32, device=dev), "xbar": wp.zeros(cap, dtype=k["vec"], device=dev),
        "axis": wp.zeros(cap, dtype=k["vec"], device=dev), "mu": wp.zeros(cap, dtype=sc, device=dev),
        "grad": wp.zeros(2 * cap, dtype=k["vec"], device=dev),
        "moments": wp.zeros(cap * (1 + dim + dim * dim) if fold else 1, dtype=sc, device=dev),
    }


def contact_grid(model: "Model", **fields) -> wp.array:
    """The kernels' contact argument: a one-element array of :class:`magsoro.mpm.kernels.contact` ContactGrid with
    ``fields`` set; with none, contact is off (one velocity field per node)."""
    ct = model.kernels["ContactGrid"]()
    ct.active = 0
    ct.n_nodes = 0
    for key, value in fields.items():
        setattr(ct, key, value)
    return wp.array([ct], dtype=model.kernels["ContactGrid"], device=model.device)


class Workers:
    """Helper threads of a CPU step, one per extra thread, each waiting on its own inbox. Runs one recorded launch
    per thread and returns when all are done. Hands work over through C-level queues: Python's thread pool
    (futures, conditions) costs about 40 us per hand-over, a tenth of a 10k-particle step split over two."""

    def __init__(self, n: int):
        self._inboxes = [queue.SimpleQueue() for _ in range(n)]
        self._done = queue.SimpleQueue()
        for i, inbox in enumerate(self._inboxes):
            threading.Thread(target=_worker_loop, args=(inbox, self._done), name=f"magsoro-step-{i + 1}", daemon=True).start()
        # stop the threads when the solver goes away
        self._finalizer = weakref.finalize(self, _stop_workers, self._inboxes)

    def run(self, launches) -> None:
        for inbox, one in zip(self._inboxes, launches[1:]):
            inbox.put(one)
        first_error = None
        try:
            launches[0].launch()
        except BaseException as e:  # still wait for the others: they write into the same arrays
            first_error = e
        for _ in launches[1:]:
            err = self._done.get()
            if err is not None and first_error is None:
                first_error = err
        if first_error is not None:
            raise first_error


def _worker_loop(inbox, done) -> None:
    while True:
        one = inbox.get()
        if one is None:
            return
        try:
            one.launch()
            done.put(None)
        except BaseException as e:  # passed on to the stepping thread
            done.put(e)


def _stop_workers(inboxes) -> None:
    for inbox in inboxes:
        inbox.put(None)
