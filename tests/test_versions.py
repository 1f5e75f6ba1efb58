"""Reproducible installs: constraints.txt pins every dependency CI installs to a version inside pyproject.toml's
range, and ``magsoro --version --verbose`` lists the versions that matter."""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

try:
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name
    from packaging.version import Version
except ImportError:  # packaging comes with matplotlib and dask; pip vendors it too
    from pip._vendor.packaging.requirements import Requirement
    from pip._vendor.packaging.utils import canonicalize_name
    from pip._vendor.packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
DECLARED = [Requirement(r) for r in PYPROJECT["project"]["dependencies"]
            + PYPROJECT["project"]["optional-dependencies"]["test"]]


def _pins() -> dict[str, str]:
    pins = {}
    for n, raw in enumerate((ROOT / "constraints.txt").read_text(encoding="utf-8").splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        req = Requirement(line)
        spec = list(req.specifier)
        assert len(spec) == 1 and spec[0].operator == "==" and "*" not in spec[0].version and not req.marker, \
            f"constraints.txt line {n}: {raw!r} is not an exact pin NAME==VERSION"
        name = canonicalize_name(req.name)
        assert name not in pins, f"constraints.txt line {n}: {req.name} pinned twice"
        pins[name] = spec[0].version
    return pins


def test_constraints_pin_every_declared_dependency_inside_its_range():
    pins = _pins()
    for req in DECLARED:
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} (pyproject.toml) has no pin in constraints.txt"
        assert req.specifier.contains(Version(pins[name]), prereleases=True), \
            f"constraints.txt pins {req.name}=={pins[name]}, outside pyproject.toml's range '{req.specifier}'"
        for extra in req.extras:  # dask[distributed]: the extra's package is pinned as well
            assert canonicalize_name(extra) in pins or extra == "complete", f"{req.name}[{extra}]: {extra} not pinned"


def test_constraints_leave_out_the_project_itself():
    assert canonicalize_name(PYPROJECT["project"]["name"]) not in _pins()


def test_upper_bounds_on_the_libraries_whose_api_we_call():
    # a new major release of these may change an API the engine uses; the bound makes pip keep to a tested one
    for req in DECLARED:
        if canonicalize_name(req.name) in ("warp-lang", "numpy", "scipy", "pydantic", "trimesh", "matplotlib"):
            assert any(s.operator == "<" for s in req.specifier), f"{req.name}: no upper bound in pyproject.toml"


def _magsoro(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "magsoro.cli", *args], capture_output=True, text=True, timeout=120, check=False,
                          cwd=ROOT)


def test_version_verbose_lists_the_dependencies():
    import importlib.metadata as md

    plain = _magsoro("--version")
    assert plain.returncode == 0 and plain.stdout.strip().startswith("magsoro ")
    assert len(plain.stdout.strip().splitlines()) == 1

    r = _magsoro("--version", "--verbose")
    assert r.returncode == 0, r.stderr
    rows = {line.split()[0]: line.split(None, 1)[1] for line in r.stdout.strip().splitlines()}
    assert rows["python"].startswith(".".join(map(str, sys.version_info[:3])))
    for req in DECLARED:
        assert req.name in rows, f"--version --verbose does not list {req.name}:\n{r.stdout}"
        try:
            installed = md.version(req.name)
        except md.PackageNotFoundError:
            installed = "not installed"
        assert rows[req.name].startswith(installed), (req.name, rows[req.name], installed)
    for name in ("warp-lang", "numpy", "scipy", "pydantic", "matplotlib", "distributed", "CUDA"):
        assert name in rows
    assert rows["CUDA"].startswith(("available", "not available", "unknown")), rows["CUDA"]
    assert "Warp" not in r.stdout.split("CUDA", 1)[0]  # Warp's start-up banner stays off stdout


@pytest.mark.parametrize("args", [["--verbose"]])
def test_verbose_alone_is_not_a_version_request(args):
    r = _magsoro(*args)
    assert r.returncode == 2 and "usage" in r.stdout.lower()
