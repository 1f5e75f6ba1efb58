"""Package version, kept in a leaf module so that modules can read it without importing the package root.

:func:`dependency_versions` and :func:`verbose_version` give what ``magsoro --version --verbose`` prints: the
installed version of every dependency the package declares (its own metadata, so the list follows pyproject.toml),
optional ones marked with their extra, and whether Warp sees CUDA."""

__version__ = "0.1.0"

# What the package declares when its metadata cannot be read (run from a source tree that was never installed)
_FALLBACK_REQUIREMENTS = ("warp-lang", "numpy", "scipy", "pydantic", "tqdm", "trimesh", "matplotlib", "networkx",
                          "dask", "pyarrow", "pyyaml", "pyamg")
# Imported by the package without being named in its requirements (dask[distributed] brings it)
_ALSO_IMPORTED = ("distributed",)


def dependency_versions() -> list[tuple[str, str | None, str | None]]:
    """(distribution, installed version or None, extra or None) for each requirement of magsoro, in the order
    of its metadata, then the packages it imports through another's extra. Reads metadata only: imports none."""
    import importlib.metadata as md
    import re

    try:
        requires = md.requires("magsoro") or []
    except md.PackageNotFoundError:
        requires = list(_FALLBACK_REQUIREMENTS)
    rows, seen = [], set()
    for req in requires + list(_ALSO_IMPORTED):
        name = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", req).group(1)
        extra = re.search(r"""extra\s*==\s*["']([^"']+)["']""", req)
        key = re.sub(r"[-_.]+", "-", name).lower()
        if key in seen:
            continue
        seen.add(key)
        try:
            version = md.version(name)
        except md.PackageNotFoundError:
            version = None
        rows.append((name, version, extra.group(1) if extra else None))
    return rows


def cuda_summary() -> str:
    """One line on CUDA as Warp sees it, from :mod:`magsoro.doctor`'s queries (Warp is initialised, which lists
    the devices; no kernel is compiled and no device memory is touched)."""
    try:
        from magsoro.doctor import _no_cuda_reason, cuda_info, init_warp
        from magsoro.warp_setup import quiet_warp

        quiet_warp()
        init_warp()  # Warp's own driver messages are kept off the terminal
        cuda = cuda_info()
    except Exception as exc:  # noqa: BLE001 - a broken Warp install is what this report is for
        return f"unknown (Warp's CUDA query failed: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
    toolkit = f"Warp built with CUDA {cuda['toolkit_version']}" if cuda["toolkit_version"] else "Warp built without CUDA"
    if cuda["device_count"]:
        return f"available, {cuda['device_count']} device(s), driver {cuda['driver_version']}; {toolkit}"
    return f"not available ({_no_cuda_reason(cuda)}); {toolkit}"


def verbose_version() -> str:
    """The text of ``magsoro --version --verbose``."""
    import platform
    import sys

    python = f"{platform.python_version()} ({platform.python_implementation()}, {sys.executable})"
    rows = [("magsoro", __version__), ("python", python)]
    for name, version, extra in dependency_versions():
        note = f" (optional: extra '{extra}')" if extra else ""
        rows.append((name, (version or "not installed") + note))
    rows.append(("platform", f"{platform.platform()} ({platform.machine()})"))
    rows.append(("CUDA", cuda_summary()))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)
