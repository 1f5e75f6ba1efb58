"""Each kernel's argument order is written in one place, its launcher (issue "Implicit engine", Build 1 "Seams
first"): the explicit solver, the static and implicit solvers, the viscous and interaction code and the
differentiable rollout all launch the engine's kernels through the ``launch_*`` functions next to the kernels'
factories. An AST walk of src/magsoro finds every ``wp.launch(...)`` and checks where it stands."""

import ast
import pathlib

import pytest
import warp as wp

SRC = pathlib.Path(__file__).resolve().parents[1] / "src" / "magsoro"

#: kernel name -> (module under src/magsoro, its launcher): the only function that may launch it
LAUNCHERS = {
    # magsoro.mpm.kernels.p2g
    "p2g": ("mpm/kernels/p2g.py", "launch_p2g"),
    "p2g_scatter": ("mpm/kernels/p2g.py", "launch_p2g_scatter"),
    "node_displacement": ("mpm/kernels/p2g.py", "launch_node_displacement"),
    "contact_scan": ("mpm/kernels/p2g.py", "launch_contact_scan"),
    "contact_scatter": ("mpm/kernels/p2g.py", "launch_contact_scatter"),
    "pressure_net": ("mpm/kernels/p2g.py", "launch_pressure_net"),
    # magsoro.mpm.kernels.grid
    "grid_update": ("mpm/kernels/grid.py", "launch_grid_update"),
    "add_grid": ("mpm/kernels/grid.py", "launch_add_grid"),
    "contact_resolve": ("mpm/kernels/grid.py", "launch_contact_resolve"),
    # magsoro.mpm.kernels.g2p
    "g2p": ("mpm/kernels/g2p.py", "launch_g2p"),
    "remap_scatter": ("mpm/kernels/g2p.py", "launch_remap_scatter"),
    "remap_node_velocity": ("mpm/kernels/g2p.py", "launch_remap_node_velocity"),
    "remap_F": ("mpm/kernels/g2p.py", "launch_remap_F"),
    "contact_gather": ("mpm/kernels/g2p.py", "launch_contact_gather"),
    "reset_reductions": ("mpm/kernels/g2p.py", "launch_reset_reductions"),
    "load_step": ("mpm/kernels/g2p.py", "launch_load_step"),
    "load_params": ("mpm/kernels/g2p.py", "launch_load_params"),
    # magsoro.mpm.kernels.contact
    "contact_classify": ("mpm/kernels/contact.py", "launch_contact_classify"),
    # magsoro.mpm.kernels
    "stress_kernel": ("mpm/kernels/__init__.py", "launch_stress"),
    "body_stress_kernel": ("mpm/kernels/__init__.py", "launch_body_stress"),
    # magsoro.mpm.laws.viscous
    "viscous_update": ("mpm/laws/viscous.py", "launch_viscous_update"),
    "overstress_tangent": ("mpm/laws/viscous.py", "launch_overstress_tangent"),
    "add_overstress": ("mpm/laws/viscous.py", "launch_add_overstress"),
    # magsoro.mpm.newton.static
    "place_particles": ("mpm/newton/static.py", "launch_place_particles"),
    "material_tangent": ("mpm/newton/static.py", "launch_material_tangent"),
    "assemble_tangent": ("mpm/newton/static.py", "launch_assemble_tangent"),
    # magsoro.mpm.interaction
    "deposit_moments": ("mpm/interaction.py", "launch_deposit_moments"),
    "gather_field": ("mpm/interaction.py", "launch_gather_field"),
    "add_field": ("mpm/interaction.py", "launch_add_field"),
}

#: launchers of kernels that the walk cannot name (the kernel comes in as an argument)
OTHER_LAUNCHERS = {
    ("fields/device.py", "launch_accumulate"): "a field source's accumulate kernel (fields.device.accumulate_kernel)",
}

#: (module, function) -> why it may launch kernels of its own directly: none of them is an engine kernel
ALLOWED = {
    ("bench/reference.py", "__init__"): "the benchmark's own minimal MLS-MPM (its p2g / grid / g2p are not the "
                                       "engine's: the reference the engine is timed against)",
    ("diff/rollout.py", "_step"): "the rollout's own field kernels (_fill_uniform, _add_field), each launched once",
}

#: kernels a factory makes that the package never launches (tests launch them directly)
NOT_LAUNCHED = {"particle_stress": "magsoro.mpm.newton.static: the static solver's stress kernel, used by the tests"}


def kernel_name(node: ast.expr) -> str | None:
    """The name the kernel argument of a launch gives: k["p2g"], self.k["g2p"], kv["viscous_update"] -> the
    string; a bare name or an attribute (p2g, self.g2p) -> that name; anything else None."""
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, str):
        return node.slice.value
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def launches(tree: ast.AST) -> list[tuple[str | None, str | None, int]]:
    """Every ``wp.launch(...)`` of a module: (kernel name or None, enclosing top-level-or-nested function name, line)."""
    found = []

    def visit(node, func):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            func = node.name
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "launch"
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "wp"):
            arg = node.args[0] if node.args else next((k.value for k in node.keywords if k.arg == "kernel"), None)
            found.append((kernel_name(arg) if arg is not None else None, func, node.lineno))
        for child in ast.iter_child_nodes(node):
            visit(child, func)

    visit(tree, None)
    return found


def package_launches(root: pathlib.Path = SRC) -> list[tuple[str, str | None, str | None, int]]:
    """(module path under ``root``, kernel name, enclosing function, line) of every wp.launch in the package."""
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        for name, func, line in launches(ast.parse(path.read_text(), filename=str(path))):
            out.append((rel, name, func, line))
    return out


def misplaced(found) -> list[str]:
    """The launches that break the rule, as 'module:line: why'."""
    by_launcher = {where: name for name, where in LAUNCHERS.items()}
    bad = []
    for rel, name, func, line in found:
        if (rel, func) in ALLOWED:
            continue
        if name in LAUNCHERS:
            if (rel, func) != LAUNCHERS[name]:
                mod, launcher = LAUNCHERS[name]
                bad.append(f"{rel}:{line}: kernel {name!r} launched in {func}(), not through {mod}:{launcher}()")
        elif (rel, func) in by_launcher:
            bad.append(f"{rel}:{line}: launcher {func}() launches {name!r}, not its kernel {by_launcher[rel, func]!r}")
        elif (rel, func) not in OTHER_LAUNCHERS:
            bad.append(f"{rel}:{line}: a launch in {func}() outside the launchers ({name!r}); give the kernel a "
                       f"launcher next to its factory")
    return bad


def test_every_engine_kernel_is_launched_only_by_its_launcher():
    bad = misplaced(package_launches())
    assert not bad, "\n".join(bad)


def test_each_launcher_launches_its_kernel_once():
    found = package_launches()
    for name, (rel, launcher) in LAUNCHERS.items():
        inside = [n for r, n, f, _ in found if (r, f) == (rel, launcher)]
        assert inside == [name], (name, rel, launcher, inside)
    for rel, launcher in OTHER_LAUNCHERS:
        assert len([1 for r, _, f, _ in found if (r, f) == (rel, launcher)]) == 1, (rel, launcher)


def test_allowed_direct_launches_still_exist():
    # an allowance whose launch went away is removed from the list, so the list stays the whole story
    found = {(r, f) for r, _, f, _ in package_launches()}
    assert set(ALLOWED) <= found, set(ALLOWED) - found


@pytest.mark.parametrize("contact", [False, True])
def test_every_kernel_the_factories_make_has_a_launcher(contact):
    from magsoro.mpm.interaction import make_interaction_kernels
    from magsoro.mpm.kernels import make_kernels
    from magsoro.mpm.newton.static import make_static_kernels
    from magsoro.mpm.laws.viscous import make_viscous

    tables = [make_kernels(2, wp.float64, contact), make_viscous(2, wp.float64), make_static_kernels(2, wp.float64),
              make_interaction_kernels(2, wp.float64)]
    names = {n for t in tables for n, obj in t.items() if isinstance(obj, wp.Kernel)}
    missing = names - set(LAUNCHERS) - set(NOT_LAUNCHED)
    assert not missing, missing


def test_a_stray_launch_is_found(tmp_path):
    # the check itself can fail: a copy of the solver with a direct launch of g2p, and a launcher that launches the
    # wrong kernel, are both reported
    (tmp_path / "mpm" / "kernels").mkdir(parents=True)
    solver = (SRC / "mpm" / "solver.py").read_text()
    solver += ('\n\ndef _stray(k, n, args):\n'
               '    wp.launch(k["g2p"], dim=n, inputs=args, device="cpu")\n')
    (tmp_path / "mpm" / "solver.py").write_text(solver)
    (tmp_path / "mpm" / "kernels" / "p2g.py").write_text(
        'import warp as wp\n\n\ndef launch_pressure_net(kernels, n):\n    return wp.launch(kernels["p2g"], dim=n)\n')
    (tmp_path / "mpm" / "kernels" / "grid.py").write_text(
        'import warp as wp\n\n\ndef helper(kernel, n):\n    return wp.launch(kernel, dim=n)\n')
    bad = misplaced(package_launches(tmp_path))
    assert any("mpm/solver.py" in b and "'g2p'" in b and "_stray" in b for b in bad), bad
    assert any("mpm/kernels/p2g.py" in b and "'p2g'" in b for b in bad), bad
    assert any("mpm/kernels/grid.py" in b and "helper" in b for b in bad), bad
