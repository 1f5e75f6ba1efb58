"""Build hook (the project's metadata is in pyproject.toml): the wheel ships the repository's scenes/ and examples/
as package data under magsoro/_bundled/, so the robot library and the tutorial's scenes run from an installed
wheel as they do from the checkout. magsoro.bundled chooses the files and finds them at run time."""

import importlib.util
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent


def _bundled_module():
    # by its file path: the package itself is not importable while it is being built
    spec = importlib.util.spec_from_file_location("_magsoro_bundled", ROOT / "src" / "magsoro" / "bundled.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class BuildPyWithBundle(build_py):
    """build_py, then a copy of scenes/ and examples/ into the built package (not for editable installs, which
    read them from the checkout)."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return
        bundled = _bundled_module()
        for rel in bundled.bundled_files(ROOT):
            target = Path(self.build_lib) / "magsoro" / bundled.BUNDLE_DIR / rel
            self.mkpath(str(target.parent))
            self.copy_file(str(ROOT / rel), str(target))


setup(cmdclass={"build_py": BuildPyWithBundle})
