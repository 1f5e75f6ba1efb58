"""``magsoro import-magneticmpm``: a robot written here in the prototype's YAML format (three box segments, STL
meshes made with numpy, ASCII and binary) becomes a scene whose particles hold the meshes' volume, whose parts carry
remenance x magnetisation_vector, whose fixed segment is clamped, and which runs; bad files give one line naming the
file and the key, exit status 2."""

import struct
from pathlib import Path

import numpy as np
import pytest

from magsoro.cli import main
from magsoro.scene import load_scene
from magsoro.scene.build import fill_bodies

REMENANCE = 0.11  # T
# (lower corner, upper corner) in mm, magnetisation_vector, density kg/m^3, shear modulus as written, fixed
SEGMENTS = [
    ((0.0, -1.0, 0.0), (8.0, 1.0, 1.0), [0, 0, 0], 1100, "1e5", True),
    ((8.0, -1.0, 0.0), (16.0, 1.0, 1.0), [1, 0, 0], 1850, "2.0e5", False),
    ((16.0, -1.5, 0.0), (22.0, 1.5, 1.5), [0.0, -0.6, 0.8], 1850, "200000", False),
]


def _box_triangles(lo, hi) -> np.ndarray:
    """(12, 3, 3) outward-wound triangles of an axis-aligned box."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return corners[np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])]


def _normals(tri):
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def write_ascii_stl(path: Path, tri: np.ndarray) -> None:
    lines = ["solid box"]
    for t, n in zip(tri, _normals(tri)):
        lines += [f"facet normal {n[0]:g} {n[1]:g} {n[2]:g}", " outer loop"]
        lines += [f"  vertex {v[0]:.9g} {v[1]:.9g} {v[2]:.9g}" for v in t]
        lines += [" endloop", "endfacet"]
    path.write_text("\n".join(lines + ["endsolid box"]) + "\n")


def write_binary_stl(path: Path, tri: np.ndarray) -> None:
    with open(path, "wb") as f:
        f.write(b"magsoro test box".ljust(80, b" ") + struct.pack("<I", len(tri)))
        f.writelines(struct.pack("<12fH", *n, *t.ravel(), 0) for t, n in zip(tri, _normals(tri)))


def make_robot(folder: Path, segments=SEGMENTS, extra_top: str = "", extra_segment: str = "") -> Path:
    """The robot in the prototype's format: robot.yaml and meshes/seg{i}.stl (even i ASCII, odd i binary), in mm."""
    (folder / "meshes").mkdir(parents=True)
    text = [f"name: test-strip\nn_segments: {len(segments)}\nremenance: {REMENANCE}\n{extra_top}segments:"]
    for i, (lo, hi, vec, rho, G, fixed) in enumerate(segments):
        (write_binary_stl if i % 2 else write_ascii_stl)(folder / "meshes" / f"seg{i}.stl", _box_triangles(lo, hi))
        text.append(f"  - mesh: seg{i}.stl\n    magnetisation_vector: {list(vec)}\n    density: {rho}\n"
                    f"    shear_modulus: {G}\n    fixed: {'true' if fixed else 'false'}")
    text[-1] += extra_segment
    path = folder / "robot.yaml"
    path.write_text("\n".join(text) + "\n")
    return path


def _import(robot: Path, out: Path, *extra) -> int:
    return main(["import-magneticmpm", str(robot), "--out", str(out), *extra])


def test_imported_robot_volume_remanence_clamps_and_runs(tmp_path, capsys):
    robot = make_robot(tmp_path / "proto")
    out = tmp_path / "scenes" / "strip.toml"
    assert _import(robot, out) == 0
    printed = capsys.readouterr().out
    assert "segment_0" in printed and "clamped" in printed

    scene = load_scene(out)
    parts = {b.name: b for b in scene.bodies}
    assert list(parts) == ["segment_0", "segment_1", "segment_2"]
    for i, (lo, hi, vec, rho, G, fixed) in enumerate(SEGMENTS):
        b = parts[f"segment_{i}"]
        assert b.magnetization == [REMENANCE * v for v in vec]  # the file's remenance x vector, exactly
        assert b.clamped is fixed
        assert b.material.density == rho and b.material.shear_modulus == float(G)
        assert b.shape.type == "mesh" and b.shape.scale == 1e-3
        assert (out.parent / b.shape.file).resolve() == (robot.parent / "meshes" / f"seg{i}.stl").resolve()

    p = fill_bodies(scene, str(out))
    for i, (lo, hi, vec, *_rest) in enumerate(SEGMENTS):
        mesh_volume = float(np.prod(np.subtract(hi, lo))) * 1e-9  # m^3
        sel = p.body == i
        assert abs(p.volumes[sel].sum() / mesh_volume - 1.0) < 0.05, (i, p.volumes[sel].sum(), mesh_volume)
        np.testing.assert_array_equal(p.remanence[sel], np.tile([REMENANCE * v for v in vec], (sel.sum(), 1)))
        assert p.clamped[sel].all() == SEGMENTS[i][5] and p.clamped[sel].any() == SEGMENTS[i][5]
    # the grid spacing follows the thinnest segment: 3 cells across its 1 mm
    assert scene.simulation.dx == pytest.approx(1e-3 / 3, rel=1e-3)
    assert not scene.colliders  # a fixed segment: no floor by default

    # it runs: a few steps under gravity and a field; the fixed segment stays, the others move
    import tomllib

    from magsoro.scene import parse_scene
    from magsoro.simulation import Simulation

    data = tomllib.loads(out.read_text())
    data["fields"] = [{"type": "uniform", "B": [0.0, 0.0, 0.05]}]
    sim = Simulation(parse_scene(data, str(out), out.parent))
    x0 = sim.state.x.numpy().copy()
    for _ in range(5):
        sim.step()
    x = sim.state.x.numpy()
    clamped = sim.model.host["clamped"]
    assert np.isfinite(x).all() and sim.time > 0
    assert clamped.sum() == (p.body == 0).sum()
    np.testing.assert_array_equal(x[clamped], x0[clamped])
    assert np.abs(x[~clamped] - x0[~clamped]).max() > 0


def test_untethered_robot_gets_a_floor_and_scale_option(tmp_path, capsys):
    free = [(lo, hi, vec, rho, G, False) for lo, hi, vec, rho, G, _ in SEGMENTS]
    robot = make_robot(tmp_path / "proto", free)
    out = tmp_path / "free.toml"
    assert _import(robot, out, "--cells-across", "2") == 0
    scene = load_scene(out)
    (floor,) = scene.colliders
    assert floor.type == "half_space" and floor.point[2] == 0.0 and floor.normal == [0.0, 0.0, 1.0]
    assert scene.simulation.dx == pytest.approx(0.5e-3, rel=1e-3)
    assert scene.simulation.domain_lo[2] < -2 * scene.simulation.dx  # the floor lies inside, off the wall cells
    # a file in metres read with --scale 1: the same scene in SI
    scaled = make_robot(tmp_path / "metres", [(np.multiply(lo, 1e-3), np.multiply(hi, 1e-3), *rest)
                                              for lo, hi, *rest in free])
    out_m = tmp_path / "free_m.toml"
    assert _import(scaled, out_m, "--cells-across", "2", "--scale", "1") == 0
    again = load_scene(out_m)
    assert again.simulation.dx == pytest.approx(scene.simulation.dx, rel=1e-6)
    np.testing.assert_allclose(again.simulation.domain_lo, scene.simulation.domain_lo, rtol=0, atol=1e-9)
    assert _import(robot, out) == 2  # exists: refused without --overwrite
    assert "--overwrite" in capsys.readouterr().err


@pytest.mark.parametrize("change, key", [
    (lambda t: t.replace("remenance:", "remanence:"), "remanence"),
    (lambda t: t.replace("    density: 1850\n", "    densty: 1850\n", 1), "segments[1].densty"),
    (lambda t: t.replace("seg2.stl", "missing.stl"), "segments[2].mesh"),
    (lambda t: t.replace("n_segments: 3", "n_segments: 4"), "n_segments"),
    (lambda t: t.replace("magnetisation_vector: [1, 0, 0]", "magnetisation_vector: [1, 0]"), "segments[1].magnetisation_vector"),
    (lambda t: t.replace("    density: 1100\n", ""), "segments[0].density"),
    (lambda t: t.replace("fixed: true", "fixed: maybe"), "segments[0].fixed"),
    (lambda t: t + "remenance: 0.2\n", "duplicate key 'remenance'"),
    (lambda t: t.replace("segments:", "segments: [", 1), "not valid YAML"),
])
def test_bad_robot_files_give_one_line(tmp_path, capsys, change, key):
    robot = make_robot(tmp_path / "proto")
    robot.write_text(change(robot.read_text()))
    out = tmp_path / "out" / "scene.toml"
    assert _import(robot, out) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("magsoro import-magneticmpm: error: ") and str(robot) in err and key in err, err
    assert not out.exists() and not out.parent.exists()


def test_unknown_key_suggests_the_known_one(tmp_path, capsys):
    robot = make_robot(tmp_path / "proto", extra_segment="\n    shear_modulu: 3")
    assert _import(robot, tmp_path / "s.toml") == 2
    err = capsys.readouterr().err
    assert "segments[2].shear_modulu: unknown key (did you mean 'shear_modulus'?)" in err
