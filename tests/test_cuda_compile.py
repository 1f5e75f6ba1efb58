"""The package's Warp kernels compile to CUDA PTX for sm_80 and sm_90 through NVRTC, with no GPU (issue "GPU
readiness"): :mod:`magsoro.cuda_compile`.

Cost and what the quick suite compiles
--------------------------------------

Everything (the 67 modules of ``warp_modules()``, O3) on a cold kernel cache is dominated by the differentiable
rollout's variants, whose kernels carry their adjoints (the 3D float32 p2g alone about 90 s of PTX per arch on a
2-core machine); the kernels a simulation runs have none and compile in seconds each (docs/engine.md, "Compile
time"). The quick suite compiles a covering subset instead (``quick_plan``: 63 compiles):

- sm_90 (H100), the engine in a Latin square over (dimension, precision, contact): 3D float32 with contact,
  3D float64 without, 2D float32 without, 2D float64 with. So every engine kernel is compiled in each of
  2D/3D x float32/float64, and both forms of the contact switch (``two_fields``, the only compile-time flag; the
  total / updated Lagrangian choice is a run-time argument) in each dimension and in each precision. Also every
  other module: ``contact_classify`` and ``stress_kernel`` for all four (dimension, precision), the field
  accumulate kernel with every field source's device function in all four, the magnetic interaction's deposit and
  gather kernels, the static solver's kernels and the Prony update kernels in all four, the bench reference (2D, 3D) and the differentiable rollout's kernels;
  and the rollout's variant with adjoints in 2D float64 (p2g, g2p, grid and the field module); the 2D float32
  plane-stress variants of p2g (without contact) and of the stress kernels.
- sm_80 (A100): the other two 2D engine variants (2D float32 with contact, 2D float64 without), with which every
  engine kernel is compiled in both precisions and both contact forms, ``contact_classify`` and ``stress_kernel``
  in all four (dimension, precision), one field module (3D float32: the accumulate kernel with every field
  source's device function), the 3D float32 magnetic interaction, the 3D float64 static solver, the 2D float32 Prony kernels, the 2D bench reference and the rollout's kernels: every kernel and every device
  function the package defines, at least once. What changes between sm_80 and sm_90 is the arch-guarded code in
  Warp's CUDA headers, which depends on the builtins and types a kernel uses, not on the variant.

The rest (the other plane-stress variants, the two 3D variants left out, 3D float32 without contact and 3D float64 with, the 3D engine, three
field modules and the 3D bench reference on sm_80, the other adjoint variants) is compiled by the ``slow`` test, which with the quick one
covers every module of ``warp_modules()`` for both archs. PTX goes to Warp's kernel cache under content-hashed
names: a second run with unchanged kernels compiles nothing.
"""

import re

import pytest
import warp as wp

from magsoro import cuda_compile as cc

ARCHS = (80, 90)
#: warp_modules(): 8 engine variants x (p2g, g2p, grid) + the rollout's 4 (adjoint) variants x 3 + (contact,
#: kernels) x 4 + fields x 4 (and x 4 with adjoints) + magnetic interaction x 4 + static solver x 4 + viscous
#: (Prony) x 4 + reference x 2 + rollout
EXPECTED_MODULES = 8 * 3 + 4 * 3 + 2 * 4 + 4 + 4 + 4 + 4 + 4 + 2 + 1
#: field sources with a device function (dipole, cuboid, cylinder exact and multipole, current loop, Magpylib
#: lattice, regional uniform): each field module holds one accumulate kernel per function
EXPECTED_FIELD_FUNCTIONS = 7
#: the quick plan: sm_90 gets 4 engine variants x 3 + the 27 other modules + the 2D float64 adjoint variant x 3 and
#: its field module, sm_80 2 x 3 + 14 (see the docstring)
EXPECTED_QUICK_JOBS = (4 * 3 + 27 + 3 + 1) + (2 * 3 + 14)

_missing = [a for a in ARCHS if a not in cc.nvrtc_archs()]
pytestmark = pytest.mark.skipif(
    bool(_missing),
    reason=("this Warp build has no NVRTC (no CUDA support compiled in)" if not cc.nvrtc_archs()
            else f"this Warp build's NVRTC cannot compile for sm_{', sm_'.join(map(str, _missing))}"),
)

_VARIANT = re.compile(r"^engine (\dD) (float\d\d)( \(contact\))?: (p2g|g2p|grid)$")
#: the differentiable rollout's variants (the same kernels with their adjoints): the quick suite compiles one
_ADJOINT = re.compile(r"^(engine|fields) (\dD) (float\d\d) \(adjoint\): \w+$")
QUICK_ADJOINT = ("2D", "float64", 90)
#: engine variants (dimension, precision, contact) compiled for each arch in the quick suite
QUICK_VARIANTS = {
    90: {("3D", "float32", True), ("3D", "float64", False), ("2D", "float32", False), ("2D", "float64", True)},
    80: {("2D", "float32", True), ("2D", "float64", False)},
}


def _variant(label: str):
    m = _VARIANT.match(label)
    return None if m is None else (m.group(1), m.group(2), bool(m.group(3)))


#: on sm_80, of the field modules and the bench references (same kernels, other dimension / precision) only these
SM80_ONE_OF = {"fields ": "fields 3D float32: device", "bench reference ": "bench reference 2D: reference",
              "interaction ": "interaction 3D float32: interaction", "static ": "static 3D float64: static",
              "viscous ": "viscous 2D float32: viscous"}


def _quick_arch(label: str, arch: int) -> bool:
    if " plane stress" in label:
        # the laws' 2D plane-stress variants: here p2g (which holds the plane-stress laws and the Prony thickness
        # solve) and the stress kernels, float32, sm_90; the static solver's and the Prony kernels (33 s and 54 s of
        # NVRTC on the 2-core machine) with the rest in the slow test
        return arch == 90 and label.startswith("engine 2D float32 plane stress:")
    a = _ADJOINT.match(label)
    if a is not None:
        return (a.group(2), a.group(3), arch) == QUICK_ADJOINT
    v = _variant(label)
    if v is not None:
        return v in QUICK_VARIANTS[arch]
    if arch == 80:
        return all(label == keep for prefix, keep in SM80_ONE_OF.items() if label.startswith(prefix))
    return True


def quick_plan(modules) -> list[tuple[str, object, tuple[int, ...]]]:
    """(label, module, archs) of the quick suite's compiles (module docstring)."""
    plan = []
    for label, module in modules:
        archs = tuple(a for a in ARCHS if _quick_arch(label, a))
        if archs:
            plan.append((label, module, archs))
    return plan


def _report(results) -> str:
    bad = [r for r in results if not r.ok]
    return f"{len(bad)} of {len(results)} PTX compiles failed:\n" + "\n".join(
        f"- {r.name} sm_{r.arch}:\n    " + r.error.replace("\n", "\n    ") for r in bad)


@pytest.fixture(scope="module")
def modules():
    return cc.warp_modules()


@pytest.fixture(scope="module")
def quick_results(modules):
    """The quick plan compiled once for the whole module (Warp's kernel cache keeps the PTX between runs)."""
    return cc.compile_to_ptx(quick_plan(modules))


def test_catalogue_lists_every_kernel(modules):
    labels = [label for label, _ in modules]
    assert len(labels) == len(set(labels)), "duplicate labels"
    assert len(modules) >= EXPECTED_MODULES, f"warp_modules() lists {len(modules)} modules, expected {EXPECTED_MODULES}: {labels}"
    variants = {_variant(label) for label in labels} - {None}
    assert len(variants) == 8, f"engine variants: {sorted(variants)}"
    assert cc.uncovered_kernels(modules) == [], "kernels defined in the source but in no module of warp_modules()"
    for label, module in modules:
        assert module.kernels, f"{label}: no kernel"
        if label.startswith("fields "):
            assert len(module._get_live_kernels()) >= EXPECTED_FIELD_FUNCTIONS, label


_BUILT_AROUND_CACHE = re.compile(r"^(engine .*: (p2g|g2p|grid|kernels)|fields .*|interaction .*|static .*|bench reference .*)$")


def test_package_modules_keep_only_their_own_kernels(modules):
    """warp_modules() builds its variants past the factories' caches and takes them out of the package's Warp
    modules, which Warp compiles whole on a launch: the later CPU runs of this session do not compile them."""
    for label, m in modules:
        if _BUILT_AROUND_CACHE.match(label):
            kernels = m._get_live_kernels()
            assert kernels and not any(k in k.module._live_kernels for k in kernels), label


def test_quick_plan_covers_every_kernel_per_dim_and_precision(modules):
    """sm_90: every engine kernel in each (dimension, precision), each contact form in each dimension and each
    precision, every other module. sm_80: every kernel the package defines at least once, and the field
    functions."""
    plan = quick_plan(modules)
    assert len([a for *_, archs in plan for a in archs]) >= EXPECTED_QUICK_JOBS
    keys = {}
    for label, module, archs in plan:
        v = _variant(label)
        if v is None:
            assert 90 in archs, label
        elif 90 in archs:
            keys.setdefault((v[0], v[1]), set()).update(module.kernels)
    assert {label.split(":")[0] for label, *_ in plan if _ADJOINT.match(label)} == {
        "engine 2D float64 (adjoint)", "fields 2D float64 (adjoint)"}
    sm80 = [(label, m) for label, m, archs in plan if 80 in archs]
    assert cc.uncovered_kernels(sm80) == []
    assert any(label.startswith("fields ") for label, _ in sm80)
    all_keys = set().union(*(set(m.kernels) for label, m in modules if _variant(label)))
    for dim in ("2D", "3D"):
        for prec in ("float32", "float64"):
            assert keys.get((dim, prec)) == all_keys, (dim, prec)
    sm90 = QUICK_VARIANTS[90]
    for dim in ("2D", "3D"):
        assert {c for d, _, c in sm90 if d == dim} == {False, True}, dim
    for prec in ("float32", "float64"):
        assert {c for _, p, c in sm90 if p == prec} == {False, True}, prec


def test_ptx_sm80_sm90(quick_results):
    assert len(quick_results) >= EXPECTED_QUICK_JOBS, f"only {len(quick_results)} compiles ran"
    assert {r.arch for r in quick_results} == set(ARCHS)
    assert all(r.ok for r in quick_results), _report(quick_results)


@pytest.mark.slow
def test_ptx_everything_else(modules, quick_results):
    """The rest of warp_modules() x (sm_80, sm_90): with the quick test, every module for both archs."""
    done = {(r.name, r.arch) for r in quick_results}
    rest = [(label, m, tuple(a for a in ARCHS if (label, a) not in done)) for label, m in modules]
    rest = [e for e in rest if e[2]]
    results = cc.compile_to_ptx(rest)
    assert len(results) + len(done) >= len(ARCHS) * EXPECTED_MODULES
    assert all(r.ok for r in results), _report(results)


def test_compile_errors_are_reported(tmp_path):
    """The check can fail: CUDA that NVRTC rejects (a native snippet: Warp's Python side passes it through as is)
    and a kernel Warp's code generation rejects both come back as ok=False with the error, next to a kernel that
    compiles; an arch NVRTC cannot target is reported, not raised."""

    @wp.func_native("return x + no_such_cuda_symbol;")
    def broken_native(x: float) -> float: ...

    @wp.kernel(module="unique")
    def nvrtc_rejects(a: wp.array(dtype=float)):
        i = wp.tid()
        a[i] = broken_native(a[i])

    @wp.kernel(module="unique")
    def codegen_rejects(a: wp.array(dtype=float)):
        i = wp.tid()
        a[i] = wp.vec3(1.0, 2.0, 3.0)  # a vector into a float array

    @wp.kernel(module="unique")
    def compiles(a: wp.array(dtype=float)):
        i = wp.tid()
        a[i] = 2.0 * a[i]

    results = cc.compile_to_ptx(
        [("nvrtc rejects", nvrtc_rejects.module), ("codegen rejects", codegen_rejects.module), ("compiles", compiles.module),
         ("no such arch", compiles.module, (1,))],
        archs=ARCHS, output_dir=tmp_path)
    by = {(r.name, r.arch): r for r in results}
    assert set(by) == {(n, a) for n in ("nvrtc rejects", "codegen rejects", "compiles") for a in ARCHS} | {("no such arch", 1)}
    for arch in ARCHS:
        r = by[("nvrtc rejects", arch)]
        assert not r.ok and "no_such_cuda_symbol" in r.error and "error" in r.error, r.error
        assert f"sm_{arch}" in r.error, r.error
        r = by[("codegen rejects", arch)]
        assert not r.ok and "codegen_rejects" in r.error and "array" in r.error, r.error
        assert by[("compiles", arch)].ok, by[("compiles", arch)].error
    r = by[("no such arch", 1)]
    assert not r.ok and "sm_1" in r.error
    assert list(tmp_path.rglob("*.ptx")), "the module that compiles wrote no PTX"
