"""Compile the package's Warp kernels to CUDA PTX through NVRTC, with no GPU and no CUDA driver.

Warp ships NVRTC inside its native library, so a CPU-only machine can still run the whole CUDA code path up to
PTX: Warp's Python-side code generation for the ``cuda`` target, then NVRTC (front end and NVVM) for a chosen
``sm_XX``. A construct that Warp's Python side accepts but that does not compile as CUDA (a native snippet, a
builtin or adjoint missing for one type on the CUDA side, ...) then fails here instead of on the first GPU run.
The CPU test suite cannot see such errors: it compiles the same kernels with Clang for the CPU.

What gets compiled (:func:`warp_modules`)
-----------------------------------------

The engine's kernels are built by ``functools.cache``'d factories parameterised by dimension, precision and
flags (:func:`magsoro.mpm.kernels.make_kernels`, which assembles :mod:`~magsoro.mpm.kernels.p2g`, :mod:`~magsoro.mpm.kernels.grid`,
:mod:`~magsoro.mpm.kernels.g2p`, :mod:`~magsoro.mpm.kernels.contact` and the stress kernel). Warp files a kernel made inside a
factory under the Warp module of the Python module that defines it, so ``magsoro.mpm.kernels.p2g`` holds every variant
created in the process, and compiles them all as one unit on the first launch. :func:`warp_modules` therefore
builds each variant past the factory's cache (the same source and closure, so the same generated code), takes it
back out of the package's Warp module (which keeps holding only what the process's own runs created: building all
variants through the caches would make the next CPU launch compile every one of them, minutes of Clang) and puts
the kernels of each factory call into a Warp module of their own, one per (variant, defining module), with the
defining module's options (``max_unroll``, ``enable_backward``, ...). That also names the failing variant in a
report and lets the compiles run in parallel. (The one exception: ``contact_classify``, which the transfers'
stencil builds through its cache, stays in ``magsoro.mpm.kernels.contact`` for every dimension and precision, about a
second of compile each.) Every variant the package can create is listed:

- ``engine {2,3}D {float32,float64}[ (contact)| (adjoint)]: p2g | g2p | grid``: the transfers and the grid
  update, without and with the two velocity fields per node of contact (``two_fields``), and the differentiable
  rollout's variant with the adjoints of the kernels it records (``differentiable``); updated and total
  Lagrangian are the same kernels (a run-time argument);
- ``engine {2,3}D {float32,float64}: contact | kernels``: ``contact_classify`` and the stress kernels
  (``stress_kernel``, ``body_stress_kernel``; one per dimension and precision);
- ``fields {2,3}D {float32,float64}[ (adjoint)]: device``: the field accumulate kernel (:mod:`magsoro.fields.device`) for the
  device function of every field source (found from the ``device_func`` methods of the package's sources);
- ``viscous {2,3}D {float32,float64}: viscous``: the Prony update and overstress kernels (:mod:`magsoro.mpm.laws.viscous`);
- ``bench reference {2,3}D: reference``: the bare MLS-MPM step of ``magsoro bench``;
- ``diff.rollout`` (and any other module with module-level kernels): those kernels as they are.

:func:`uncovered_kernels` lists every ``@wp.kernel`` defined in the package's source that none of the modules
holds (a new factory this file does not call yet).

Compiling (:func:`compile_to_ptx`)
----------------------------------

Each (module, arch) pair is one job; jobs run on a thread pool (NVRTC runs outside the GIL; Warp serialises only
its Python code generation), largest first. PTX lands in Warp's kernel cache (or ``output_dir``) under a
content-hashed name, so a second run with unchanged kernels finds it there and compiles nothing. A failed compile
never raises: its :class:`CompileResult` carries the error, for NVRTC the first error lines of its log (NVRTC
writes the log to the process's stderr; the failed jobs are compiled again one at a time with stderr captured).

Costs (a 2-core machine, cold cache, ``python benchmarks/compile_time.py``): the kernels a simulation runs carry
no adjoint and compile in seconds per module (3D float32: p2g 5 s of PTX, 7 s with contact; g2p 2-5 s); the
differentiable rollout's variants, whose kernels keep their adjoints, are most of the whole list (3D float32 p2g
about 90 s per arch). ``tests/test_cuda_compile.py`` compiles a covering subset in the quick suite. Peak memory
stays under 1 GB with two compiles at a time.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import importlib
import os
import re
import sys
import tempfile
import threading
import time
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

__all__ = ["CompileResult", "compile_to_ptx", "nvrtc_archs", "uncovered_kernels", "warp_modules"]

DIMS = (2, 3)
SCALAR_NAMES = ("float32", "float64")
MAX_WORKERS = 8  # parallel NVRTC compiles at most (a few hundred MB each)
_PACKAGE = "magsoro"
_MODULE_PREFIX = "magsoro_ptx"  # names of the per-variant Warp modules (and of their cache folders)
_RUN_LOCK = threading.Lock()


@dataclass
class CompileResult:
    """Outcome of compiling one Warp module to PTX for one architecture."""

    name: str  # a label like "engine 3D float32 (contact): p2g" or "fields 3D float64: device"
    arch: int  # 80 or 90
    ok: bool
    seconds: float
    error: str  # "" when ok; else the first useful line(s) of the code-generation / NVRTC error


# ---------------------------------------------------------------------------------------------------------------
# what the package creates


def nvrtc_archs() -> tuple[int, ...]:
    """The ``sm_XX`` NVRTC in this Warp build can compile for (empty: no NVRTC, e.g. a CPU-only Warp build)."""
    import warp as wp

    wp.init()
    try:
        return tuple(sorted(int(a) for a in wp.get_cuda_supported_archs()))
    except Exception:  # noqa: BLE001 - a Warp without CUDA support at all
        return ()


def _package_dir() -> Path:
    return Path(importlib.import_module(_PACKAGE).__file__).parent


@functools.cache
def _source_files() -> tuple[tuple[str, ast.Module], ...]:
    """(module name, parsed source) of every Python file of the package (read once per process)."""
    root = _package_dir()
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        parts = [_PACKAGE, *rel.parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        try:
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        except (OSError, SyntaxError, UnicodeDecodeError):
            continue
        out.append((".".join(parts), tree))
    return tuple(out)


def _is_kernel_decorator(node: ast.expr) -> bool:
    if isinstance(node, ast.Call):
        node = node.func
    return (isinstance(node, ast.Attribute) and node.attr == "kernel") or (isinstance(node, ast.Name) and node.id == "kernel")


def _kernel_definitions() -> list[tuple[str, str, bool]]:
    """(module, qualified name, defined at module level) of every ``@wp.kernel`` function in the source."""
    found = []

    def visit(body, prefix: str, module: str, top: bool):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                qual = f"{prefix}{node.name}"
                if any(_is_kernel_decorator(d) for d in node.decorator_list):
                    found.append((module, qual, top))
                visit(node.body, f"{qual}.<locals>.", module, False)
            elif isinstance(node, ast.ClassDef):
                visit(node.body, f"{prefix}{node.name}.", module, False)
            else:  # statements holding statements (if / try / with ...): same scope
                for field in ("body", "orelse", "finalbody"):
                    sub = getattr(node, field, None)
                    if isinstance(sub, list):
                        visit(sub, prefix, module, top)
                for handler in getattr(node, "handlers", None) or []:
                    visit(handler.body, prefix, module, top)

    for module, tree in _source_files():
        visit(tree.body, "", module, True)
    return found


def _field_device_functions() -> list:
    """The Warp device functions of the package's field sources: every name a ``device_func`` method returns."""
    import warp as wp

    funcs = {}
    for module, tree in _source_files():
        names = []
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            for meth in cls.body:
                if isinstance(meth, ast.FunctionDef) and meth.name == "device_func":
                    for ret in (n for n in ast.walk(meth) if isinstance(n, ast.Return) and n.value is not None):
                        names += [n.id for n in ast.walk(ret.value) if isinstance(n, ast.Name)]
        if not names:
            continue
        mod = importlib.import_module(module)
        for name in names:
            obj = getattr(mod, name, None)
            if isinstance(obj, wp.Function):
                funcs[(obj.func.__module__, obj.func.__qualname__)] = obj
    return [funcs[k] for k in sorted(funcs)]


def _groups_of(label: str, made: Iterable, seen: set) -> list[tuple[str, list]]:
    """Split the kernels a factory returned into one group per defining Warp module, skipping kernels already
    listed (a factory result shared between variants)."""
    import warp as wp

    by_module: dict[str, list] = {}
    for k in made:
        if isinstance(k, wp.Kernel) and id(k) not in seen:
            seen.add(id(k))
            by_module.setdefault(k.module.name, []).append(k)
    return [(f"{label}: {name.rsplit('.', 1)[-1]}", ks) for name, ks in by_module.items()]


def _own_module(label: str, kernels: list):
    """A Warp module holding just ``kernels`` (all of one defining module), with that module's options."""
    source = kernels[0].module
    module_type = type(source)
    name = f"{_MODULE_PREFIX}.{re.sub(r'[^0-9A-Za-z]+', '_', label).strip('_')}"
    m = module_type(name, None)
    m.options = dict(source.options)
    m.magsoro_kernels = tuple(kernels)  # Warp tracks live kernels weakly; kernels of one key would be collected
    for k in kernels:
        if k.module is not source:
            raise ValueError(f"{label}: kernels of different Warp modules in one group")
        m.kernels[k.key] = k
        m._live_kernels.add(k)
        if getattr(k.adj, "has_unresolved_static_expressions", False):
            m.has_unresolved_static_expressions = True
    return m


def _kernels_in(made) -> list:
    import warp as wp

    if isinstance(made, wp.Kernel):
        return [made]
    if isinstance(made, dict):
        made = made.values()
    return [k for k in made if isinstance(k, wp.Kernel)]


def _fresh(factory, *args) -> list:
    """The kernels of ``factory(*args)`` built past its ``functools.cache`` and taken back out of the package's
    Warp module they registered in.

    Warp compiles a module with every kernel alive in it, and the factories' caches keep what they built alive
    for good: built through the caches, every variant listed here would ride along in the first compile of a
    later run in the same process (on the CPU, with Clang, backward code included: minutes). Built around the
    cache and taken out of that module's live set, the copies (same source, same closure, so the same generated
    code) live only in the modules of :func:`warp_modules`, and the package's modules hold what they held."""
    import warp as wp

    fn = getattr(factory, "__wrapped__", factory)
    home = wp.get_module(fn.__module__)
    live_before = set(home._live_kernels)
    latest_before = dict(home.kernels)
    kernels = _kernels_in(fn(*args))
    for k in kernels:
        if k.module is home and k not in live_before:
            home._live_kernels.discard(k)
            if home.kernels.get(k.key) is k:
                if k.key in latest_before:
                    home.kernels[k.key] = latest_before[k.key]
                else:
                    del home.kernels[k.key]
    return kernels


@functools.cache
def _catalogue() -> tuple:
    import warp as wp

    from magsoro.bench.reference import reference_kernels
    from magsoro.fields.device import accumulate_kernel
    from magsoro.mpm.kernels.contact import make_contact
    from magsoro.mpm.kernels.g2p import make_g2p
    from magsoro.mpm.kernels.grid import make_grid
    from magsoro.mpm.interaction import make_interaction_kernels
    from magsoro.mpm.kernels import _stress_kernel
    from magsoro.mpm.newton.static import make_static_kernels
    from magsoro.mpm.kernels.p2g import make_p2g
    from magsoro.mpm.laws.viscous import make_viscous

    scalars = {"float32": wp.float32, "float64": wp.float64}
    seen: set = set()
    groups: list[tuple[str, list]] = []
    # the engine as magsoro.mpm.kernels.make_kernels assembles it, one variant at a time
    for dim in DIMS:
        for sname in SCALAR_NAMES:
            sc = scalars[sname]
            for contact, differentiable in ((False, False), (True, False), (False, True)):
                label = f"engine {dim}D {sname}" + (" (contact)" if contact else "") + (" (adjoint)" if differentiable else "")
                for factory in (make_p2g, make_grid, make_g2p):
                    groups += _groups_of(label, _fresh(factory, dim, sc, contact, differentiable), seen)
                if not contact and not differentiable:
                    # one per dimension and precision; contact_classify comes from the cache, where the transfers'
                    # stencil (magsoro.mpm.kernels.stencil) has already put it
                    groups += _groups_of(label, _fresh(_stress_kernel, dim, sc), seen)
                    groups += _groups_of(label, _kernels_in(make_contact(dim, sc)["contact_classify"]), seen)
    # the 2D plane-stress variants of the kernels that evaluate a law (magsoro.mpm.kernels.stencil.make_body_elastic)
    for sname in SCALAR_NAMES:
        sc = scalars[sname]
        for contact in (False, True):
            label = f"engine 2D {sname} plane stress" + (" (contact)" if contact else "")
            groups += _groups_of(label, _fresh(make_p2g, 2, sc, contact, False, "stress"), seen)
        groups += _groups_of(f"engine 2D {sname} plane stress", _fresh(_stress_kernel, 2, sc, "stress"), seen)
        groups += _groups_of(f"static 2D {sname} plane stress", _fresh(make_static_kernels, 2, sc, "stress"), seen)
        groups += _groups_of(f"viscous 2D {sname} plane stress", _fresh(make_viscous, 2, sc, "stress"), seen)
        # axisymmetric bodies: p2g with the hoop stretch and hoop force (the explicit engine's one-field variant)
        for contact in (False, True):
            label = f"engine 2D {sname} axisymmetric" + (" (contact)" if contact else "")
            groups += _groups_of(label, _fresh(make_p2g, 2, sc, contact, False, "axisymmetric"), seen)
        # and the Newton solvers' tangent with its hoop terms
        groups += _groups_of(f"static 2D {sname} axisymmetric", _fresh(make_static_kernels, 2, sc, "axisymmetric"), seen)
    field_funcs = _field_device_functions()
    for dim in DIMS:
        for sname in SCALAR_NAMES:
            for differentiable in (False, True):
                made = [k for f in field_funcs for k in _fresh(accumulate_kernel, f, dim, scalars[sname], differentiable)]
                groups += _groups_of(f"fields {dim}D {sname}" + (" (adjoint)" if differentiable else ""), made, seen)
    for dim in DIMS:
        for sname in SCALAR_NAMES:
            groups += _groups_of(f"interaction {dim}D {sname}", _fresh(make_interaction_kernels, dim, scalars[sname]), seen)
            groups += _groups_of(f"static {dim}D {sname}", _fresh(make_static_kernels, dim, scalars[sname]), seen)
            # the reference grid split by contact group (contact between bodies in the Newton solvers)
            groups += _groups_of(f"static {dim}D {sname} (contact)",
                                 _fresh(make_static_kernels, dim, scalars[sname], "strain", True), seen)
            groups += _groups_of(f"viscous {dim}D {sname}", _fresh(make_viscous, dim, scalars[sname]), seen)
    for dim in DIMS:
        groups += _groups_of(f"bench reference {dim}D", _fresh(reference_kernels, dim), seen)
    # kernels defined at module level (the differentiable rollout's, and any new module's)
    top: dict[str, list] = {}
    for module, qual, at_top in _kernel_definitions():
        if at_top:
            top.setdefault(module, []).append(getattr(importlib.import_module(module), qual))
    for module in sorted(top):
        for _, ks in _groups_of(module, top[module], seen):
            groups.append((module.removeprefix(f"{_PACKAGE}."), ks))
    return tuple((label, _own_module(label, ks)) for label, ks in groups)


def warp_modules() -> list[tuple[str, object]]:
    """(label, warp.context.Module) of every Warp module the package creates, built (not compiled) on import/ by
    their factory functions.

    One module per (variant, defining module), see the module docstring; the same objects on every call."""
    return list(_catalogue())


def uncovered_kernels(modules=None) -> list[str]:
    """``module:qualname`` of each ``@wp.kernel`` in the package's source that none of ``modules`` (default:
    :func:`warp_modules`) holds; empty when every kernel the package defines gets compiled."""
    mods = warp_modules() if modules is None else list(modules)
    held = {(k.func.__module__, k.func.__qualname__) for entry in mods for k in entry[1].kernels.values()}
    return sorted(f"{m}:{q}" for m, q, _ in _kernel_definitions() if (m, q) not in held)


# ---------------------------------------------------------------------------------------------------------------
# compiling


def _weight(label: str) -> float:
    """Rough relative compile cost, only to start the largest jobs first."""
    w = 1.0
    if "3D" in label:
        w *= 4.0
    if "(contact)" in label:
        w *= 1.5
    if "(adjoint)" in label:  # the adjoints are most of the cost (docs/engine.md, "Compile time")
        w *= 15.0
    if label.endswith(("p2g", "g2p")):
        w *= 6.0
    elif label.endswith("reference"):
        w *= 3.0
    return w


def _workers(n_jobs: int) -> int:
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, MAX_WORKERS, n_jobs))


@contextlib.contextmanager
def _captured_stderr():
    """Send the process's file descriptor 2 (where NVRTC writes its log) to a temporary file; yields a function
    returning what was written so far. Without a usable descriptor 2 it captures nothing."""
    with tempfile.TemporaryFile() as tmp:
        with contextlib.suppress(Exception):  # a closed or replaced sys.stderr: nothing to flush
            sys.stderr.flush()
        try:
            saved = os.dup(2)
        except OSError:
            yield lambda: ""
            return
        os.dup2(tmp.fileno(), 2)

        def read() -> str:
            tmp.seek(0)
            return tmp.read().decode("utf-8", errors="replace")

        try:
            yield read
        finally:
            os.dup2(saved, 2)
            os.close(saved)


_NVRTC_ERROR = re.compile(r"\(\d+\): (?:catastrophic )?error\b|^\s*(?:catastrophic )?error\b", re.IGNORECASE)
_ANY_ERROR = re.compile(r"\berror\b", re.IGNORECASE)


def _log_excerpt(log: str, max_errors: int = 3) -> str:
    """The first errors of an NVRTC log (``file.cu(line): error: ...``), each with the source line and caret
    NVRTC prints below it; without such lines, the log's last lines that mention an error."""
    lines = [ln.rstrip() for ln in log.splitlines()]
    out, n, i = [], 0, 0
    while i < len(lines) and n < max_errors:
        if _NVRTC_ERROR.search(lines[i]):
            out.append(lines[i].strip())
            n += 1
            j = i + 1
            while j < len(lines) and j <= i + 2 and lines[j].strip() and not _ANY_ERROR.search(lines[j]):
                out.append(lines[j])
                j += 1
            i = j
        else:
            i += 1
    if not out:
        out = [ln for ln in lines if _ANY_ERROR.search(ln)][-5:]
    return "\n".join(out)


def _first_lines(exc: BaseException, n: int = 6) -> str:
    text = f"{type(exc).__name__}: {exc}".strip()
    return "\n".join(text.splitlines()[:n])


def _module_dir(module, output_dir) -> str | None:
    if output_dir is None:
        return None  # Warp's kernel cache, under the module's content-hashed name
    return os.path.join(os.fspath(output_dir), module.get_module_identifier())


def _compile_one(label: str, module, arch: int, output_dir) -> tuple[CompileResult, bool]:
    """Compile; the flag says whether the failure came from the native (NVRTC) step, whose log went to fd 2."""
    import warp as wp

    t0 = time.perf_counter()
    try:  # the module's hash (its folder name) may already run code generation, so it is inside too
        paths = wp.compile_aot_module(module, device=None, arch=arch, module_dir=_module_dir(module, output_dir), use_ptx=True)
    except Exception as exc:  # noqa: BLE001 - every failure is a finding to report, never a crash of the check
        native = str(exc).startswith("CUDA kernel build failed")
        return CompileResult(label, arch, False, time.perf_counter() - t0, _first_lines(exc)), native
    dt = time.perf_counter() - t0
    missing = [os.fspath(p) for p in paths if not os.path.isfile(p) or os.path.getsize(p) == 0]
    if not paths or missing:
        return CompileResult(label, arch, False, dt, f"no PTX written ({', '.join(missing) or 'no artifact'})"), False
    return CompileResult(label, arch, True, dt, ""), False


def _cleanup_failed_build(module, output_dir) -> None:
    """Remove the build folders Warp leaves behind after a failed compile in this process."""
    import shutil

    import warp as wp

    try:
        base = _module_dir(module, output_dir) or os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier())
    except Exception:  # noqa: BLE001 - the module could not even be hashed: nothing was built
        return
    for path in Path(base).parent.glob(f"{Path(base).name}_p{os.getpid()}_t*"):
        shutil.rmtree(path, ignore_errors=True)


def compile_to_ptx(modules=None, archs=(80, 90), output_dir=None) -> list[CompileResult]:
    """Compile each module to PTX for each arch with no GPU; never raises for a compile error, reports it.

    ``modules``: (label, Warp module) pairs, default :func:`warp_modules`; an entry may carry a third item, the
    archs for that module alone. ``output_dir``: where the PTX goes (one folder per module under its
    content-hashed name); default Warp's kernel cache, where a later call with unchanged kernels finds it and
    compiles nothing. Results come in the order of ``modules``, then ``archs``."""
    import warp as wp

    wp.init()
    entries = warp_modules() if modules is None else list(modules)
    with _RUN_LOCK:  # one call at a time: each redirects the process's stderr
        return _compile_all(entries, archs, output_dir)


def _compile_all(entries, archs, output_dir) -> list[CompileResult]:
    jobs = []
    for entry in entries:
        label, module = entry[0], entry[1]
        for arch in (entry[2] if len(entry) > 2 else archs):
            jobs.append((str(label), module, int(arch)))
    results: list[CompileResult | None] = [None] * len(jobs)
    supported = set(nvrtc_archs())
    todo = []
    for i, (label, module, arch) in enumerate(jobs):
        if arch in supported:
            todo.append(i)
        else:
            why = (f"NVRTC in this Warp build does not support sm_{arch} (supported: {', '.join(map(str, sorted(supported)))})"
                   if supported else "NVRTC is not available in this Warp build")
            results[i] = CompileResult(label, arch, False, 0.0, why)
    # largest first; one arch after the other among equals (NVRTC reuses its precompiled header within an arch)
    todo.sort(key=lambda i: (-_weight(jobs[i][0]), jobs[i][2]))

    native_failures = []
    lock = threading.Lock()

    def run(i):
        label, module, arch = jobs[i]
        res, native = _compile_one(label, module, arch, output_dir)
        with lock:
            results[i] = res
            if native:
                native_failures.append(i)

    if todo:
        with _captured_stderr() as read:
            with ThreadPoolExecutor(max_workers=_workers(len(todo))) as pool:
                list(pool.map(run, todo))
            echo = read()
        if echo.strip():  # warnings, and the logs of failed compiles (which their results also carry)
            sys.stderr.write(echo)
    # NVRTC's log of a failed job went to the shared stderr among other jobs' output: compile each such job
    # again alone (a front-end error stops NVRTC early, so this is quick) and keep its own log
    for i in sorted(native_failures):
        label, module, arch = jobs[i]
        with _captured_stderr() as read:
            res, native = _compile_one(label, module, arch, output_dir)
            log = read()
        if not res.ok:
            excerpt = _log_excerpt(log) if native else ""
            if excerpt:
                res.error = f"NVRTC (sm_{arch}) rejected the generated CUDA:\n{excerpt}"
            res.seconds = results[i].seconds
        results[i] = res
    for i, res in enumerate(results):
        if res is not None and not res.ok:
            _cleanup_failed_build(jobs[i][1], output_dir)
    return [r for r in results if r is not None]
