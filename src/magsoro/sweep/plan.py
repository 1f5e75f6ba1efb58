"""Turn a scene file and ``--param`` specifications into the list of runs, every scene validated up front."""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

from magsoro.bundled import resolve_data_path
from magsoro.errors import SceneError
from magsoro.io.files import read_toml_file
from magsoro.sweep.params import (Param, RunSpec, SweepError, check_run_count, combine, format_value, parse_param,
                                  set_path, slug)


@dataclass
class SweepPlan:
    """Everything a sweep needs before its first run: the base scene, the parameters and the runs."""

    scene_path: Path
    base: dict
    params: list[Param]
    zipped: bool
    runs: list[RunSpec]

    @property
    def base_dir(self) -> Path:
        """The folder of the scene file, against which the scene's relative file names resolve."""
        return self.scene_path.parent

    def describe(self) -> dict:
        """JSON-able record of the plan (sweep.json), enough to check a --resume against the same sweep."""
        return {
            "scene_file": str(self.scene_path),
            "params": [{"key": p.key, "values": p.values, "spec": p.text} for p in self.params],
            "mode": "zip" if self.zipped else "product",
            "runs": [{"index": r.index, "name": r.name, "params": r.params} for r in self.runs],
        }


def _apply(base: dict, params: dict, specs: dict[str, str]) -> dict:
    data = copy.deepcopy(base)
    for key, value in params.items():
        set_path(data, key, value, specs.get(key, key))
    return data


def _check_materials(scene, source: str) -> None:
    """Resolve every body's material as the build will (library names, material files), host-only and cheap:
    a misspelt library name is the likeliest error of a material sweep, and parse_scene leaves it to the build."""
    from magsoro.materials.library import MaterialLibraryError, load_library
    from magsoro.scene.build import resolve_material

    libs = scene.material_library_paths
    try:
        library = load_library(libs) if libs else None
    except MaterialLibraryError as exc:
        raise SceneError(f"{source}: material_library: {exc}") from None
    for i, b in enumerate(scene.bodies):
        base_dir = b.base_dir or scene.base_dir
        key = b.key or f"bodies[{i}]"
        resolve_material(b.material, base_dir, f"{b.source or source}: {key}.material", library)


def _validate(data: dict, source: str, base_dir: Path) -> str | None:
    """One-line message when ``data`` is not a valid scene (parse_scene, then the materials), else None."""
    from magsoro.scene import parse_scene

    try:
        scene = parse_scene(copy.deepcopy(data), source, base_dir)
        _check_materials(scene, source)
    except SceneError as exc:
        return str(exc)
    return None


def make_plan(scene_file, param_specs: list[str], zipped: bool = False, allow_large: bool = False) -> SweepPlan:
    """Parse the --param specs, build every run's scene and validate all of them with parse_scene.

    A bad key or value fails here, before any run starts, with one line that names the --param: a path that
    does not exist is caught while setting it; a value the schema refuses is traced to the --param that,
    applied alone to the base scene, already makes it invalid (or to the whole combination when only the
    combination is invalid). More runs than :data:`~magsoro.sweep.params.MAX_RUNS` are refused unless
    ``allow_large`` (never more than HARD_MAX_RUNS), before any is made.
    """
    path = resolve_data_path(scene_file).resolve()  # scenes/... and examples/...: the installed copy elsewhere
    base = read_toml_file(path, SceneError, "scene file")
    params = [parse_param(s) for s in param_specs]
    specs = {p.key: p.text for p in params}
    check_run_count(params, zipped, allow_large)
    combos = combine(params, zipped)
    width = max(3, len(str(len(combos) - 1)))
    runs, checked = [], {}
    for index, combo in enumerate(combos):
        data = _apply(base, combo, specs)
        summary = ", ".join(f"{k}={format_value(v)}" for k, v in combo.items())
        problem = _validate(data, f"{scene_file} [{summary}]", path.parent)
        if problem is not None:
            # blame the single --param value that breaks the scene on its own, if there is one
            for key, value in combo.items():
                if (key, format_value(value)) not in checked:
                    alone = _apply(base, {key: value}, specs)
                    checked[(key, format_value(value))] = _validate(alone, str(scene_file), path.parent)
                single = checked[(key, format_value(value))]
                if single is not None:
                    raise SweepError(f"--param {specs[key]}: value {format_value(value)} makes the scene invalid: {single}")
            raise SweepError(f"--param combination {summary} makes the scene invalid: {problem}")
        runs.append(RunSpec(index, combo, f"{index:0{width}d}-{slug(combo)}", data))
    return SweepPlan(path, base, params, zipped, runs)
