"""``magsoro doctor``: what this machine can run and whether the engine gives the same answer on it.

Gathers versions (magsoro, Warp, numpy, Python, OS), the CPU and its memory, the devices Warp sees (CUDA name,
architecture, memory), whether the CUDA driver and NVRTC are available and Warp's kernel cache, then runs checks:

- ``cuda``: the device under test is a working CUDA device (a small allocation and copy);
- ``compile``: the engine's kernels compile for CUDA. On a CUDA device a short run of the parity scene on it
  (which compiles and loads the engine there); without one, PTX for a representative subset of the engine's Warp
  modules through NVRTC (:mod:`magsoro.cuda_compile`);
- ``parity``: a small 3D scene (a magnetised block dropped onto a second block resting on a friction floor, contact
  between the bodies with friction, a point-dipole field whose gradient pulls the block sideways) run for a fixed
  number of identical steps on a reference and on the device under test: CPU float32 against the device (float32)
  on a CUDA device, CPU float64 against CPU float32 without one. Reports the largest particle-position difference
  (m and cells), the run's largest displacement (for scale) and the speed of each run.

Every check ends ``passed``, ``failed`` or ``not checked`` (with the reason); :func:`run_doctor` returns the
report as a JSON-ready dict and :func:`format_text` the human table.
"""

from __future__ import annotations

import contextlib
import math
import os
import platform
import re
import sys
import tempfile
import time
from pathlib import Path

PASSED, FAILED, NOT_CHECKED = "passed", "failed", "not checked"

# -- the parity scene ------------------------------------------------------------------------------------------
PARITY_DX = 5.0e-4  # m: grid spacing of the parity scene
PARITY_DT = 5.0e-6  # s: fixed step (CFL bound of the scene about 1e-5 s), so both runs take identical steps
PARITY_STEPS = 400  # 2 ms: the block hits the base after about 35 steps and slides on it, pulled by the dipole

# Pass threshold of the largest particle-position difference, in cells (x PARITY_DX = 5e-7 m).
# Measured on CPU (Warp 1.19, x86-64) for CPU float32 against CPU float64 after PARITY_STEPS steps: 1.34e-8 m
# (2.7e-5 cells) for this scene, and 0.9e-8 to 1.3e-8 m (1.8e-5 to 2.7e-5 cells) over 16 variants of it (time
# step 4 to 6 us, impact speed 0.3 to 0.8 m/s, block offsets, dipole moment 0.5 to 4 mA m^2); the run's largest
# displacement is 2.5e-4 m (0.5 cells). float32 round-off amplified by these dynamics is thus about 1e-8 m. A
# CUDA run in float32 differs from the CPU float32 run by at most the sum of each one's distance from the exact
# (float64) answer, so by about twice that, plus the reordering of atomic sums: the same order. 1e-3 cells is
# about 40 times the largest difference measured and 500 times below the displacement: a wrong or missing term
# on the device (a force, a contact or friction branch, the field gradient) moves particles by a sizeable
# fraction of the displacement, far above it.
PARITY_THRESHOLD_CELLS = 1.0e-3

# Compile check without CUDA: NVRTC takes about 20 s per engine module here (2 CPU cores), so doctor compiles a
# representative subset (the 3D float32 engine) for one architecture, not the whole set.
COMPILE_ARCH = 90
COMPILE_MAX_MODULES = 2
# the 3D float32 contact engine's scatter and gather first (what the parity scene runs, the largest kernels)
_COMPILE_PREFERRED = ("engine 3d float32 (contact): p2g", "engine 3d float32 (contact): g2p")
_COMPILE_SUBSET = (("engine", "3d", "float32"), ("3d", "float32"), ("engine",))


def parity_scene(precision: str) -> dict:
    """The parity scene as a scene dict (for :func:`magsoro.scene.parse_scene`); 832 particles.

    A 2 x 2 x 1 mm magnetised block (Br 0.1 T along x) falls at 0.5 m/s onto a 3 x 3 x 1 mm block resting just
    above a friction floor (mu 0.5), with contact friction 0.5 between the bodies; a point dipole (1 mA m^2 along
    x) 4 mm beside the block pulls it along x with a force of about 12 times its weight (gradient force), so it
    slides on the base. Gravity along -z. The floor plane lies between grid nodes on purpose: a plane through a
    node row is a tie that float32 and float64 round differently (in one precision the base then rests on the
    floor, in the other it falls through the first node row), which differs by 0.6 cells after 400 steps."""
    return {
        "name": "doctor_parity",
        "simulation": {
            "dim": 3, "dx": PARITY_DX, "particles_per_cell": 2,
            "domain_lo": [0.0, 0.0, 0.0], "domain_hi": [0.008, 0.008, 0.008],
            "duration": PARITY_STEPS * PARITY_DT, "dt": PARITY_DT,
            "gravity": [0.0, 0.0, -9.81], "damping": 5.0, "precision": precision,
        },
        "bodies": [
            {"name": "base", "shape": {"type": "box", "center": [0.004, 0.004, 0.0015], "size": [0.003, 0.003, 0.001]},
             "material": {"density": 1100.0, "shear_modulus": 50.0e3}},
            {"name": "magnet", "shape": {"type": "box", "center": [0.0045, 0.004, 0.003], "size": [0.002, 0.002, 0.001]},
             "material": {"density": 1500.0, "shear_modulus": 30.0e3},
             "magnetization": [0.1, 0.0, 0.0], "velocity": [0.0, 0.0, -0.5]},
        ],
        "colliders": [{"type": "half_space", "point": [0.0, 0.0, 0.00085], "normal": [0.0, 0.0, 1.0],
                       "mode": "friction", "friction": 0.5}],
        "contact": {"friction": 0.5},
        "fields": [{"type": "dipole", "moment": [0.001, 0.0, 0.0], "position": [0.0085, 0.004, 0.003]}],
    }


# -- small helpers ---------------------------------------------------------------------------------------------
def _one_line(exc: BaseException | str, limit: int = 300) -> str:
    text = exc if isinstance(exc, str) else (f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__)
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


@contextlib.contextmanager
def stdout_to_stderr():
    """Everything written to stdout meanwhile (Python prints and, at the file-descriptor level, what Warp's native
    code, LLVM or NVRTC print) goes to stderr, so stdout carries only the report."""
    sys.stdout.flush()
    saved = None
    try:
        saved = os.dup(1)
        os.dup2(2, 1)
    except OSError:
        saved = None
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stderr.flush()
        if saved is not None:
            os.dup2(saved, 1)
            os.close(saved)


def init_warp() -> list[str]:
    """Initialise Warp, returning what its native code printed on stderr meanwhile (such as "Could not find or
    load the NVIDIA CUDA driver") instead of letting it reach the terminal: doctor reports the driver's state
    itself, and a refused --device stays a one-line error. Empty when Warp was initialised already."""
    import warp as wp

    sys.stderr.flush()
    with tempfile.TemporaryFile() as tmp:
        try:
            saved = os.dup(2)
        except OSError:
            wp.init()
            return []
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        return [line for line in tmp.read().decode("utf-8", "replace").splitlines() if line.strip()]


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith(("model name", "hardware", "cpu model")):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _memory() -> dict:
    """Total and available memory in bytes: /proc/meminfo, else os.sysconf; None where neither tells."""
    total = avail = None
    try:
        info = {}
        for line in Path("/proc/meminfo").read_text().splitlines():
            key, _, rest = line.partition(":")
            parts = rest.split()
            if parts and parts[0].isdigit():
                info[key] = int(parts[0]) * (1024 if len(parts) > 1 and parts[1].lower() == "kb" else 1)
        total, avail = info.get("MemTotal"), info.get("MemAvailable", info.get("MemFree"))
    except OSError:
        pass
    if total is None:
        try:
            page = os.sysconf("SC_PAGE_SIZE")
            total = page * os.sysconf("SC_PHYS_PAGES")
            avail = page * os.sysconf("SC_AVPHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            pass
    return {"total_bytes": total, "available_bytes": avail}


def _usable_cores() -> int | None:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count()


def _version_str(v) -> str | None:
    if v is None:
        return None
    return ".".join(str(p) for p in v) if isinstance(v, (tuple, list)) else str(v)


def _dir_size(path: Path) -> tuple[int, int]:
    """(bytes, files) under ``path``; unreadable entries are skipped."""
    size = files = 0
    for root, _, names in os.walk(path):
        for name in names:
            try:
                size += os.lstat(os.path.join(root, name)).st_size
                files += 1
            except OSError:
                pass
    return size, files


def _fmt_bytes(n) -> str:
    if n is None:
        return "unknown"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} B"


# -- facts -----------------------------------------------------------------------------------------------------
def versions() -> dict:
    import numpy as np
    import warp as wp

    from magsoro._version import __version__

    return {
        "magsoro": __version__,
        "warp": wp.config.version,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "os": platform.platform(),
        "machine": platform.machine(),
    }


def cuda_info() -> dict:
    """Driver, toolkit, NVRTC and device count as Warp sees them (Warp initialised)."""
    import warp as wp

    wp.init()
    archs = list(wp.get_cuda_supported_archs())
    driver = wp.get_cuda_driver_version()
    return {
        "driver_available": driver is not None,
        "driver_version": _version_str(driver),
        "toolkit_version": _version_str(wp.get_cuda_toolkit_version()),  # the toolkit Warp was built with
        "nvrtc_available": bool(archs),
        "nvrtc_archs": archs,
        "device_count": wp.get_cuda_device_count(),
    }


def devices() -> list[dict]:
    import warp as wp

    out = []
    for d in wp.get_devices():
        row = {"alias": d.alias, "name": d.name, "kind": "cuda" if d.is_cuda else "cpu"}
        if d.is_cuda:
            row["arch"] = int(d.arch)
            row["sm_count"] = getattr(d, "sm_count", None)
            for key, attr in (("total_memory_bytes", "total_memory"), ("free_memory_bytes", "free_memory")):
                try:
                    row[key] = int(getattr(d, attr))
                except Exception:  # noqa: BLE001 - an attribute this Warp lacks or a query the driver refuses
                    row[key] = None
            row["pci_bus_id"] = getattr(d, "pci_bus_id", None)
        out.append(row)
    return out


def kernel_cache() -> dict:
    import warp as wp

    wp.init()
    d = wp.config.kernel_cache_dir
    row = {"dir": str(d) if d else None, "exists": bool(d) and Path(d).is_dir(), "size_bytes": None, "files": None, "modules": None}
    if row["exists"]:
        row["size_bytes"], row["files"] = _dir_size(Path(d))
        try:
            row["modules"] = sum(1 for p in Path(d).iterdir() if p.is_dir())
        except OSError:
            pass
    return row


# -- device under test -----------------------------------------------------------------------------------------
def resolve_device(name: str | None) -> str:
    """'cpu', 'cuda' or 'cuda:N' (None: CUDA when there is a device, else the CPU); MagsoroError otherwise."""
    import warp as wp

    from magsoro.errors import MagsoroError

    count = wp.get_cuda_device_count()
    if name is None:
        return "cuda:0" if count > 0 else "cpu"
    name = name.strip().lower()
    if name == "cpu":
        return "cpu"
    m = re.fullmatch(r"cuda(?::(\d+))?", name)
    if not m:
        raise MagsoroError(f"--device {name}: expected cpu, cuda or cuda:N")
    if count == 0:
        raise MagsoroError(f"--device {name}: no CUDA device on this machine ({_no_cuda_reason(cuda_info())}); use --device cpu")
    index = int(m.group(1) or 0)
    if index >= count:
        raise MagsoroError(f"--device {name}: this machine has {count} CUDA device(s): cuda:0 to cuda:{count - 1}")
    return f"cuda:{index}"


def _no_cuda_reason(cuda: dict) -> str:
    if cuda["device_count"]:
        return ""
    if cuda["toolkit_version"] is None:
        return "this Warp build has no CUDA support"
    if not cuda["driver_available"]:
        return "no CUDA driver"
    return f"CUDA driver {cuda['driver_version']} found but no CUDA device"


# -- checks ----------------------------------------------------------------------------------------------------
def cuda_check(device: str, cuda: dict) -> dict:
    """The device under test works: allocate, fill and read back an array on it."""
    if not device.startswith("cuda"):
        reason = _no_cuda_reason(cuda) or "--device cpu chosen"
        return {"status": NOT_CHECKED, "reason": reason}
    import numpy as np
    import warp as wp

    t0 = time.perf_counter()
    try:
        a = wp.array(np.arange(1024, dtype=np.float32), device=device)
        ok = bool(np.array_equal(a.numpy(), np.arange(1024, dtype=np.float32)))
        wp.synchronize_device(device)
    except Exception as exc:  # noqa: BLE001 - any failure of the device is the finding
        return {"status": FAILED, "error": _one_line(exc), "seconds": time.perf_counter() - t0}
    d = wp.get_device(device)
    detail = f"{device} {d.name}, sm_{d.arch}"
    if ok:
        return {"status": PASSED, "detail": detail, "seconds": time.perf_counter() - t0}
    return {"status": FAILED, "detail": detail, "error": "an array copied to the device read back different values",
            "seconds": time.perf_counter() - t0}


def _pick_modules(mods: list) -> list:
    """A representative subset of ``warp_modules()`` for the compile check: the 3D float32 engine with contact
    (its p2g and g2p), else the first labels naming the 3D float32 engine."""
    preferred = [m for m in mods if str(m[0]).lower() in _COMPILE_PREFERRED]
    if preferred:
        return preferred[:COMPILE_MAX_MODULES]
    for words in _COMPILE_SUBSET:
        pick = [m for m in mods if all(w in str(m[0]).lower() for w in words)]
        if pick:
            return pick[:COMPILE_MAX_MODULES]
    return list(mods[:1])


def compile_check(device: str, cuda: dict | None = None, progress=None) -> dict:
    """On a CUDA device: compile and load the engine there by a short run of the parity scene. Without one: PTX
    for a subset of the engine's modules through NVRTC (:func:`magsoro.cuda_compile.compile_to_ptx`)."""
    cuda = cuda_info() if cuda is None else cuda
    t0 = time.perf_counter()
    if device.startswith("cuda"):
        try:
            run = _parity_run("float32", device, steps=2)
        except Exception as exc:  # noqa: BLE001 - a compile, load or launch failure is the finding
            return {"status": FAILED, "mode": "device", "target": device, "error": _one_line(exc, 2000),
                    "seconds": time.perf_counter() - t0}
        return {"status": PASSED, "mode": "device", "target": device, "seconds": time.perf_counter() - t0,
                "detail": f"engine (3D float32, contact) compiled and loaded on {device} in {run['first_step_s']:.1f} s"}
    if not cuda["nvrtc_available"]:
        return {"status": NOT_CHECKED, "reason": "no NVRTC (this Warp build has no CUDA support)"}
    try:
        import importlib

        cuda_compile = importlib.import_module("magsoro.cuda_compile")
    except Exception as exc:  # noqa: BLE001 - ImportError, or the module failing at import: not checked, said why
        why = re.sub(r"\s*\((?:/|[A-Za-z]:\\)[^)]*\)", "", _one_line(exc))  # drop the file path Python appends
        return {"status": NOT_CHECKED, "reason": f"magsoro.cuda_compile not importable ({why})"}
    if progress is not None:
        progress(f"compile check: PTX sm_{COMPILE_ARCH} of a subset of the engine through NVRTC")
    try:
        mods = list(cuda_compile.warp_modules())
        if not mods:
            return {"status": NOT_CHECKED, "reason": "magsoro.cuda_compile.warp_modules() lists no module"}
        pick = _pick_modules(mods)
        with tempfile.TemporaryDirectory(prefix="magsoro-doctor-ptx-") as out:
            results = list(cuda_compile.compile_to_ptx(modules=pick, archs=(COMPILE_ARCH,), output_dir=out))
    except Exception as exc:  # noqa: BLE001 - the compile tool itself broke: a failed check
        return {"status": FAILED, "mode": "ptx", "error": _one_line(exc, 2000), "seconds": time.perf_counter() - t0}
    rows = [{"name": r.name, "arch": int(r.arch), "ok": bool(r.ok), "seconds": float(r.seconds), "error": r.error or ""}
            for r in results]
    ok = bool(rows) and all(r["ok"] for r in rows)
    out = {"status": PASSED if ok else FAILED, "mode": "ptx", "target": f"sm_{COMPILE_ARCH} PTX (NVRTC, no device)",
           "modules": [str(m[0]) for m in pick], "modules_available": len(mods), "results": rows,
           "seconds": time.perf_counter() - t0}
    if not rows:
        out["error"] = "compile_to_ptx returned no result"
    return out


def _parity_run(precision: str, device: str, steps: int = PARITY_STEPS) -> dict:
    """Run the parity scene ``steps`` steps; positions (float64) and timings. Errors propagate."""
    import numpy as np
    import warp as wp

    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    t0 = time.perf_counter()
    sim = Simulation(parse_scene(parity_scene(precision)), device=device, source="doctor parity scene")
    sim.step(PARITY_DT)  # the first step loads (on a cold kernel cache: compiles) the kernels
    wp.synchronize_device(device)
    t1 = time.perf_counter()
    for _ in range(steps - 1):
        sim.step(PARITY_DT)
    wp.synchronize_device(device)
    t2 = time.perf_counter()
    x = sim.state.x.numpy().astype(np.float64)
    timed = steps - 1
    return {
        "x": x,
        "x0": np.asarray(sim.model.host["positions"], dtype=np.float64),
        "particles": int(sim.model.n_particles),
        "contact": bool(sim.solver.contact_active),
        "field_gradient_max": float(np.abs(sim.solver.grad_B_particle.numpy()).max()) if sim.model.n_particles else 0.0,
        "first_step_s": t1 - t0,
        "steps_per_s": timed / (t2 - t1) if t2 > t1 and timed > 0 else None,
    }


def parity_check(device: str) -> dict:
    """The parity scene on a reference and on ``device``: CPU float32 vs ``device`` float32 on CUDA, CPU float64
    vs CPU float32 on the CPU."""
    import numpy as np

    if device.startswith("cuda"):
        ref, test = ("cpu", "float32"), (device, "float32")
    else:
        ref, test = ("cpu", "float64"), ("cpu", "float32")
    threshold_m = PARITY_THRESHOLD_CELLS * PARITY_DX
    out = {
        "reference": {"device": ref[0], "precision": ref[1]},
        "test": {"device": test[0], "precision": test[1]},
        "scene": "3D: magnetised block dropped onto a block on a friction floor; contact friction 0.5; dipole field gradient",
        "steps": PARITY_STEPS, "dt": PARITY_DT, "dx": PARITY_DX,
        "threshold_m": threshold_m, "threshold_cells": PARITY_THRESHOLD_CELLS,
    }
    t0 = time.perf_counter()
    runs = {}
    for role, (dev, prec) in (("reference", ref), ("test", test)):
        try:
            runs[role] = _parity_run(prec, dev)
        except Exception as exc:  # noqa: BLE001 - a run that fails (or cannot start) on one side is the finding
            out.update(status=FAILED, error=f"{role} run ({dev}, {prec}): {_one_line(exc, 1000)}",
                       seconds=time.perf_counter() - t0)
            return out
    a, b = runs["reference"], runs["test"]
    diff = np.linalg.norm(b["x"] - a["x"], axis=1)
    disp = np.linalg.norm(a["x"] - a["x0"], axis=1)
    max_diff = float(diff.max()) if len(diff) else 0.0
    finite = bool(np.isfinite(a["x"]).all() and np.isfinite(b["x"]).all())
    if not finite:
        max_diff = float("nan")
    passed = finite and max_diff <= threshold_m
    out.update(
        status=PASSED if passed else FAILED,
        particles=a["particles"],
        contact_active=a["contact"] and b["contact"],
        field_gradient_max_T_per_m=a["field_gradient_max"],
        max_position_difference_m=max_diff if finite else None,
        max_position_difference_cells=max_diff / PARITY_DX if finite else None,
        max_displacement_m=float(disp.max()) if len(disp) else 0.0,
        runs=[{"role": role, "device": dev, "precision": prec,
               "steps_per_s": runs[role]["steps_per_s"],
               "particle_steps_per_s": runs[role]["steps_per_s"] * runs[role]["particles"] if runs[role]["steps_per_s"] else None,
               "first_step_s": runs[role]["first_step_s"]}
              for role, (dev, prec) in (("reference", ref), ("test", test))],
        seconds=time.perf_counter() - t0,
    )
    if not finite:
        out["error"] = "non-finite particle positions"
    elif not passed:
        out["error"] = (f"largest position difference {max_diff:.3g} m ({max_diff / PARITY_DX:.3g} cells) is above the "
                        f"threshold {threshold_m:.3g} m ({PARITY_THRESHOLD_CELLS:g} cells)")
    return out


# -- the report ------------------------------------------------------------------------------------------------
def run_doctor(device: str | None = None, compile: bool = True, progress=None) -> dict:
    """Everything ``magsoro doctor`` reports, as a JSON-ready dict. ``device``: the device under test (None: CUDA
    when present, else the CPU; MagsoroError for a device this machine lacks). ``progress(text)``: called before
    each slow step."""
    t0 = time.perf_counter()
    say = progress or (lambda text: None)
    init_messages = init_warp()
    dev = resolve_device(device)
    cuda = cuda_info()
    cuda["warp_init_messages"] = init_messages
    report = {
        "device": dev,
        "versions": versions(),
        "cpu": {"model": _cpu_model(), "cores": os.cpu_count(), "usable_cores": _usable_cores()},
        "memory": _memory(),
        "cuda": cuda,
        "devices": devices(),
        "kernel_cache": kernel_cache(),
    }
    checks = {"cuda": cuda_check(dev, cuda)}
    # the parity runs go before the PTX compile: building every engine variant for PTX adds kernels to the
    # engine's Warp modules, and a CPU run after that would compile those larger modules afresh
    if compile and dev.startswith("cuda"):
        say(f"compile check: the engine on {dev}")
        checks["compile"] = compile_check(dev, cuda)
    say("parity check: " + ("CPU float32 vs " + dev if dev.startswith("cuda") else "CPU float32 vs CPU float64")
        + f", {PARITY_STEPS} steps (the first run on a cold kernel cache compiles the engine: minutes)")
    checks["parity"] = parity_check(dev)
    if not compile:
        checks["compile"] = {"status": NOT_CHECKED, "reason": "--no-compile"}
    elif not dev.startswith("cuda"):
        checks["compile"] = compile_check(dev, cuda, progress=say)
    report["checks"] = {k: checks[k] for k in ("cuda", "compile", "parity")}
    report["not_checked"] = [f"{_LABELS[k]}: {c['reason']}" for k, c in report["checks"].items() if c["status"] == NOT_CHECKED]
    report["failed"] = [k for k, c in report["checks"].items() if c["status"] == FAILED]
    report["ok"] = not report["failed"]
    report["exit_code"] = 0 if report["ok"] else 1
    report["seconds"] = time.perf_counter() - t0
    return report


_LABELS = {"cuda": "CUDA", "compile": "compile", "parity": "parity"}


def to_json(report: dict) -> str:
    """The report as one JSON object (a non-finite number becomes null: strict JSON has no NaN)."""
    import json

    def clean(x):
        if isinstance(x, float):
            return x if math.isfinite(x) else None
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if hasattr(x, "item") and not isinstance(x, (str, bytes)):  # numpy scalars
            return clean(x.item())
        return x

    return json.dumps(clean(report), indent=2, allow_nan=False)


def _g(x, spec=".3g") -> str:
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def format_text(report: dict) -> str:
    v, cpu, mem, cuda, kc = report["versions"], report["cpu"], report["memory"], report["cuda"], report["kernel_cache"]
    lines = [
        f"magsoro {v['magsoro']}, Warp {v['warp']}, numpy {v['numpy']}, Python {v['python']}",
        f"system    {v['os']} ({v['machine']})",
        f"CPU       {cpu['model']}, {cpu['cores']} cores ({cpu['usable_cores']} usable)",
        f"memory    {_fmt_bytes(mem['total_bytes'])} total, {_fmt_bytes(mem['available_bytes'])} available",
    ]
    drv = f"driver {cuda['driver_version']}" if cuda["driver_available"] else "driver not available"
    nvrtc = (f"NVRTC available (sm_{min(cuda['nvrtc_archs'])} to sm_{max(cuda['nvrtc_archs'])})" if cuda["nvrtc_available"]
             else "NVRTC not available")
    lines.append(f"CUDA      {drv}; Warp built with toolkit {cuda['toolkit_version'] or 'none'}; {nvrtc}; "
                 f"{cuda['device_count']} device(s)")
    for d in report["devices"]:
        if d["kind"] == "cuda":
            lines.append(f"device    {d['alias']}: {d['name']}, sm_{d['arch']}, {d.get('sm_count')} SMs, "
                         f"{_fmt_bytes(d.get('total_memory_bytes'))} total, {_fmt_bytes(d.get('free_memory_bytes'))} free")
        else:
            lines.append(f"device    {d['alias']}: {d['name']}")
    if kc["exists"]:
        lines.append(f"kernels   cache {kc['dir']}: {_fmt_bytes(kc['size_bytes'])} in {kc['modules']} module folders")
    else:
        lines.append(f"kernels   cache {kc['dir']}: not created yet (the first run compiles every kernel)")
    lines.append(f"under test: {report['device']}")
    lines.append("")
    lines.append(f"{'check':<9} {'result':<12} detail")
    checks = report["checks"]
    for key, c in checks.items():
        name, status = _LABELS[key], c["status"]
        details = _check_details(key, c)
        lines.append(f"{name:<9} {status:<12} {details[0]}")
        lines.extend(f"{'':<22} {d}" for d in details[1:])
    lines.append("")
    if report["not_checked"]:
        lines.append("not checked:")
        lines.extend(f"  {t}" for t in report["not_checked"])
    n = {s: sum(1 for c in checks.values() if c["status"] == s) for s in (PASSED, FAILED, NOT_CHECKED)}
    if report["ok"]:
        lines.append(f"result: every check that ran passed ({n[PASSED]} passed, {n[NOT_CHECKED]} not checked) "
                     f"in {report['seconds']:.1f} s")
    else:
        lines.append(f"result: FAILED: {', '.join(_LABELS[k] for k in report['failed'])} ({n[PASSED]} passed, "
                     f"{n[FAILED]} failed, {n[NOT_CHECKED]} not checked) in {report['seconds']:.1f} s")
    return "\n".join(lines)


def _check_details(key: str, c: dict) -> list[str]:
    if c["status"] == NOT_CHECKED:
        return [c["reason"]]
    out = []
    if key == "cuda":
        out.append(c.get("detail", ""))
    elif key == "compile":
        if c.get("mode") == "device":
            out.append(c.get("detail") or f"engine on {c.get('target')}")
        else:
            rows = c.get("results") or []
            good = sum(r["ok"] for r in rows)
            out.append(f"{c.get('target', 'PTX')}: {good} of {len(rows)} module(s) compiled in {_g(c.get('seconds'), '.1f')} s "
                       f"(subset of {c.get('modules_available', '?')} modules)")
            for r in rows:
                if r["ok"]:
                    out.append(f"ok      {r['name']} sm_{r['arch']} {r['seconds']:.1f} s")
                else:
                    err = (r["error"] or "no message").strip().splitlines() or ["no message"]
                    out.append(f"FAILED  {r['name']} sm_{r['arch']}: {err[0]}")
                    out.extend(f"        {e}" for e in err[1:8])
                    if len(err) > 8:
                        out.append(f"        ... ({len(err) - 8} more lines in --json)")
    elif key == "parity":
        ref, test = c["reference"], c["test"]
        out.append(f"{test['device']} {test['precision']} vs {ref['device']} {ref['precision']}, {c['steps']} steps of {c['dt']:g} s"
                   + (f", {c['particles']} particles" if "particles" in c else ""))
        if c.get("max_position_difference_m") is not None:
            out.append(f"largest position difference {_g(c['max_position_difference_m'])} m "
                       f"({_g(c['max_position_difference_cells'])} cells), threshold {c['threshold_m']:.3g} m "
                       f"({c['threshold_cells']:g} cells); largest displacement {_g(c.get('max_displacement_m'))} m")
        for r in c.get("runs", []):
            out.append(f"speed {r['device']} {r['precision']}: {_g(r['steps_per_s'], '.0f')} steps/s "
                       f"(first step {r['first_step_s']:.2f} s: loads the kernels, compiles them on a cold cache)")
    if c.get("error"):
        err = str(c["error"]).strip().splitlines() or [""]
        out.append(f"error: {err[0]}")
        out.extend(f"       {e}" for e in err[1:8])
    return out or [""]
