"""The documentation site (mkdocs.yml, docs/, scripts/docs_site.py, scripts/docs_griffe.py).

Quick checks that need no docs package: the nav names pages that exist and every page is reachable, the
generated reference pages match their generators, the docs extra is pinned, every public function and class on
the API pages has a docstring, the references page names every seed. With the docs extra installed, the whole
site is built as CI builds it: ``mkdocs build --strict`` (any warning fails; about 5 s).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
API_PAGES = DOCS / "reference" / "api"

#: Public API without a docstring; remove a name once it has one.
KNOWN_UNDOCUMENTED: set[str] = set()


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _mkdocs_config() -> dict:
    class Loader(yaml.SafeLoader):
        pass

    # mkdocs.yml names a Python function (the toc's slugify) with a python/ tag: keep it out of a plain load
    Loader.add_multi_constructor("tag:yaml.org,2002:python/", lambda loader, suffix, node: None)
    return yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=Loader)


def _nav_files(nav) -> list[str]:
    out = []
    for item in nav:
        value = next(iter(item.values())) if isinstance(item, dict) else item
        out += _nav_files(value) if isinstance(value, list) else [value]
    return out


def test_nav_lists_pages_that_exist_and_every_page_is_reachable():
    config = _mkdocs_config()
    assert config["theme"]["name"] == "material"
    nav = _nav_files(config["nav"])
    assert len(nav) == len(set(nav)), "a page appears twice in mkdocs.yml's nav"
    missing = [p for p in nav if not (DOCS / p).is_file()]
    assert not missing, f"mkdocs.yml's nav names pages that do not exist: {missing}"
    not_in_nav = {line.strip().lstrip("/") for line in config.get("not_in_nav", "").splitlines() if line.strip()}
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    orphans = sorted(pages - set(nav) - not_in_nav)
    assert not orphans, f"pages under docs/ that are neither in the nav nor in not_in_nav: {orphans}"
    for section in ("Getting started", "How-to guides", "Reference", "Explanation", "Robot gallery", "References"):
        assert any(isinstance(i, dict) and section in i for i in config["nav"]), f"no '{section}' in the nav"


def test_generated_reference_pages_are_current():
    site = _load("docs_site", ROOT / "scripts" / "docs_site.py")
    assert not site.stale_pages(), "regenerate with: python scripts/docs_site.py"
    cli = (DOCS / "reference" / "cli.md").read_text(encoding="utf-8")
    from magsoro.cli import build_parser

    commands = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction").choices
    assert [f"## magsoro {c}" for c in commands] == re.findall(r"^## magsoro \S+$", cli, re.M), "one section per command"


def test_docs_extra_is_pinned_in_constraints():
    try:
        from packaging.requirements import Requirement
        from packaging.utils import canonicalize_name
        from packaging.version import Version
    except ImportError:  # packaging comes with matplotlib and dask; pip vendors it too
        from pip._vendor.packaging.requirements import Requirement
        from pip._vendor.packaging.utils import canonicalize_name
        from pip._vendor.packaging.version import Version

    extra = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["optional-dependencies"]["docs"]
    pins = {}
    for line in (ROOT / "constraints.txt").read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, version = line.split("==")
            pins[canonicalize_name(name)] = version
    for raw in extra:
        req = Requirement(raw)
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} (docs extra) has no pin in constraints.txt"
        assert req.specifier.contains(Version(pins[name])), f"constraints.txt pins {req.name}=={pins[name]} outside '{req.specifier}'"
    assert {"mkdocs", "mkdocs-material", "mkdocstrings", "mkdocstrings-python", "griffelib"} <= set(pins)


def _api_objects():
    """(dotted name, object) of every function and class the API pages render, with their public methods."""
    for page in sorted(API_PAGES.glob("*.md")):
        text = page.read_text(encoding="utf-8")
        for m in re.finditer(r"^::: (\S+)\n((?:    .*\n?)*)", text, re.M):
            ident, options = m.group(1), m.group(2)
            members = re.search(r"members: \[([^\]]*)\]", options)
            try:
                target = importlib.import_module(ident)
            except ImportError:
                module, _, attr = ident.rpartition(".")
                target = getattr(importlib.import_module(module), attr)
            if members:
                names = [n.strip() for n in members.group(1).split(",") if n.strip()]
            elif inspect.ismodule(target):
                names = list(target.__all__)
            else:
                names = []
            if inspect.isclass(target):
                yield ident, target
            for name in names:
                yield f"{ident}.{name}", getattr(target, name)


def _doc(cls, key: str) -> str | None:
    """The docstring of ``cls.key``, its own or the one it inherits (as the site renders it)."""
    for klass in cls.__mro__:
        if key in vars(klass):
            value = vars(klass)[key]
            func = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
            doc = getattr(func, "__doc__", None)
            if doc and doc.strip():
                return doc
    return None


def _undocumented(name: str, obj):
    """Names of ``obj`` (a function, or a class and its public methods and properties) without a docstring."""
    if not (inspect.isclass(obj) or inspect.isfunction(obj)):
        return
    own = (obj.__dict__.get("__doc__") if inspect.isclass(obj) else obj.__doc__) or ""
    if not own.strip() or (inspect.isclass(obj) and own.startswith(f"{obj.__name__}(")):  # a dataclass's own signature
        yield name
    if inspect.isclass(obj):
        for key, value in vars(obj).items():
            func = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
            field = key in getattr(obj, "__dataclass_fields__", {})  # a field whose default is a function
            if not key.startswith("_") and not field and inspect.isfunction(func) and not _doc(obj, key):
                yield f"{name}.{key}"


def test_every_public_function_and_class_on_the_api_pages_has_a_docstring():
    objects = list(_api_objects())
    assert len(objects) > 60, [n for n, _ in objects]
    missing = {n for name, obj in objects for n in _undocumented(name, obj)}
    assert not missing - KNOWN_UNDOCUMENTED, f"public API without a docstring: {sorted(missing - KNOWN_UNDOCUMENTED)}"
    fixed = KNOWN_UNDOCUMENTED - missing
    assert not fixed, f"documented now: remove from KNOWN_UNDOCUMENTED: {sorted(fixed)}"


def test_references_name_every_seed_and_the_hooks_cite_them():
    site = _load("docs_site", ROOT / "scripts" / "docs_site.py")
    refs = (DOCS / "references.md").read_text(encoding="utf-8")
    seeds = sorted(p.name[:3] for p in (ROOT.parent / "shared" / "seeds").glob("00*.txt")) or ["000", "001", "002", "003", "004"]
    assert sorted(site.SEEDS) == seeds
    for seed, cite in site.SEEDS.items():
        assert f"| {seed} | {cite} |" in refs and f"**{cite}** (seed {seed})" in refs, seed

    page = "# Title\n\nText after seed 001 and seeds 004.\n\n```\nseed 003 in code\n```\n"
    noted = site._seed_note(page, "how-to/x.md")
    assert noted.splitlines()[0] == "# Title"
    assert "seed 001: da Veiga et al. 2021; seed 004: Calmé et al. 2026" in noted and "seed 003:" not in noted
    assert "[References](../references.md)" in noted
    assert site._seed_note("# No seeds here\n", "x.md") == "# No seeds here\n"

    assert site._repo_target("tutorial.md", "../examples/tutorial/strip.toml", DOCS, ROOT) == ROOT / "examples/tutorial/strip.toml"
    assert site._repo_target("tutorial.md", "tutorial/walker.png", DOCS, ROOT) is None  # inside docs/
    assert site._repo_target("tutorial.md", "https://example.org/a.toml", DOCS, ROOT) is None
    assert site._repo_target("tutorial.md", "../no/such/file.toml", DOCS, ROOT) is None


def test_prose_docstrings_become_markdown():
    pytest.importorskip("griffe", reason="the docs extra is not installed")
    ext = _load("docs_griffe", ROOT / "scripts" / "docs_griffe.py")
    text = "See :func:`solve` and :class:`~magsoro.fields.profiles.Keyframes`.\n\n>>> x = 1  # doctest: +SKIP\n>>> x\n1\n\nEnd."
    out = ext.prose_to_markdown(text)
    assert "`solve`" in out and "`Keyframes`" in out and ":func:" not in out
    assert "```pycon\n>>> x = 1\n>>> x\n1\n```" in out and out.endswith("End.")


def test_readme_and_changelog_say_how_to_build_and_release():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert '-e ".[docs]"' in readme and "mkdocs serve" in readme and "git tag v" in readme
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    from magsoro import __version__

    assert "## [Unreleased]" in changelog and f"## [{__version__}] - " in changelog


def test_site_builds_with_no_warning(tmp_path):
    """What CI runs: ``mkdocs build --strict`` turns every warning (broken link or anchor, a docstring griffe
    cannot parse, a page outside the nav) into a failure."""
    pytest.importorskip("mkdocs", reason="the docs extra is not installed: pip install -e '.[docs]'")
    pytest.importorskip("mkdocstrings_handlers.python", reason="the docs extra is not installed")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, timeout=300, env={**__import__("os").environ,
                                                                                   "NO_MKDOCS_2_WARNING": "1"})
    warnings = [line for line in r.stderr.splitlines() if "WARNING" in line or "ERROR" in line]
    assert r.returncode == 0 and not warnings, r.stderr[-4000:]
    site = tmp_path / "site"
    assert (site / "index.html").is_file() and (site / "reference" / "api" / "simulation" / "index.html").is_file()
    assert (site / "_repo" / "examples" / "tutorial" / "strip.toml").is_file()  # a repository file a page links to
    api = (site / "reference" / "api" / "fields" / "index.html").read_text(encoding="utf-8")
    assert "CylinderMagnet" in api and "tesla" in api
