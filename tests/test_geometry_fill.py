"""Lattice fill of meshes and primitives: exact particle volume, volume against the exact solid, mesh repair."""

import copy

import numpy as np
import pytest
import trimesh

from magsoro.errors import SceneError
from magsoro.geometry.mesh import MeshError, MeshShape
from magsoro.geometry.primitives import AnnularSector, Polygon, Slab, Transformed, Tube, euler_rotation, fill_lattice
from magsoro.scene import parse_scene
from magsoro.scene.build import fill_bodies

DX = 1e-3  # m; 10 cells across the 10 mm solids below
ORIGIN = np.zeros(3)

# solids in mm, exact volumes in m^3 (the torus and cylinder meshes are fine enough that the mesh volume is within
# 0.3 % of the smooth solid, so both comparisons below are meaningful)
SOLIDS = {
    "cube": (lambda: trimesh.creation.box(extents=[10.0, 10.0, 10.0]), 1000e-9),
    "cylinder": (lambda: trimesh.creation.cylinder(radius=5.0, height=10.0, sections=128), np.pi * 25 * 10e-9),
    "torus": (lambda: trimesh.creation.torus(major_radius=6.0, minor_radius=2.5, major_sections=128, minor_sections=64), 2 * np.pi**2 * 6 * 2.5**2 * 1e-9),
}


@pytest.mark.parametrize("name", list(SOLIDS))
def test_mesh_fill_volume_within_2_percent(tmp_path, name):
    make, exact = SOLIDS[name]
    path = tmp_path / f"{name}.stl"
    make().export(path)
    shape = MeshShape.from_file(path, scale=1e-3, position=[0.0203, 0.0197, 0.0151], rotation=euler_rotation([20, 35, 10]))
    pts, v_each = fill_lattice(shape, DX, 2, ORIGIN, 3)
    filled = len(pts) * v_each
    assert v_each == pytest.approx((DX / 2) ** 3, rel=1e-15)
    assert abs(filled / exact - 1) < 0.02, (name, filled, exact)
    assert abs(shape.volume() / exact - 1) < 0.003
    # grid aligned: every particle sits at origin + (j + 1/2) dx / 2
    j = pts / (DX / 2) - 0.5
    assert np.allclose(j, np.rint(j), atol=1e-6)


def test_mesh_contains_matches_analytic_torus(tmp_path):
    """The ray test against the smooth torus: disagreements only within a mesh-facet distance of the surface."""
    R, r = 6e-3, 2.5e-3
    path = tmp_path / "torus.obj"
    trimesh.creation.torus(major_radius=R, minor_radius=r, major_sections=128, minor_sections=64).export(path)
    shape = MeshShape.from_file(path)
    rng = np.random.default_rng(1)
    p = rng.uniform(-9e-3, 9e-3, size=(20000, 3))
    d = np.hypot(np.hypot(p[:, 0], p[:, 1]) - R, p[:, 2]) - r  # signed distance to the smooth torus
    inside = shape.contains(p)
    far = np.abs(d) > 5e-5
    assert np.array_equal(inside[far], d[far] < 0)


def _scene(body, dim=3):
    return {
        "simulation": {"dim": 3, "dx": DX, "domain_lo": [0.0, 0.0, 0.0], "domain_hi": [0.04, 0.04, 0.03], "duration": 1e-3},
        "bodies": [body],
    }


def test_mesh_body_mass_is_density_times_filled_volume(tmp_path):
    trimesh.creation.cylinder(radius=5.0, height=10.0, sections=128).export(tmp_path / "cyl.stl")
    body = {"name": "c", "shape": {"type": "mesh", "file": "cyl.stl", "scale": 1e-3, "position": [0.02, 0.02, 0.015]},
            "material": "ecoflex-00-30-ndfeb100"}
    p = fill_bodies(parse_scene(_scene(body), base_dir=tmp_path))
    rep = p.report[0]
    mass = float(np.sum(p.volumes * p.density))
    assert mass == pytest.approx(1876.198 * rep["filled_volume"], rel=1e-4)
    assert rep["mass"] == pytest.approx(mass, rel=1e-12)
    assert abs(rep["filled_volume"] / rep["shape_volume"] - 1) < 0.02


def test_open_mesh_repaired_or_refused(tmp_path):
    box = trimesh.creation.box(extents=[10.0, 10.0, 10.0])
    holed = trimesh.Trimesh(box.vertices, box.faces[1:], process=False)  # one triangle missing: trimesh fills it
    holed.export(tmp_path / "holed.stl")
    repaired = MeshShape.from_file(tmp_path / "holed.stl", scale=1e-3)
    assert repaired.volume() == pytest.approx(1e-6, rel=1e-9)
    cyl = trimesh.creation.cylinder(radius=5.0, height=10.0, sections=64)
    side = np.abs(cyl.face_normals[:, 2]) < 0.5  # keep the mantle only: two 64-gon holes trimesh cannot fill
    trimesh.Trimesh(cyl.vertices, cyl.faces[side], process=False).export(tmp_path / "open.stl")
    with pytest.raises(MeshError, match=r"open\.stl.*not a closed surface"):
        MeshShape.from_file(tmp_path / "open.stl")
    body = {"name": "o", "shape": {"type": "mesh", "file": "open.stl", "scale": 1e-3, "position": [0.02, 0.02, 0.015]}, "material": "ecoflex-00-30"}
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape\.file: .*open\.stl.*could not be repaired"):
        fill_bodies(parse_scene(_scene(body), source="s.toml", base_dir=tmp_path), source="s.toml")


def test_missing_mesh_file_is_named(tmp_path):
    body = {"name": "m", "shape": {"type": "mesh", "file": "nope.stl", "scale": 1e-3}, "material": "ecoflex-00-30"}
    with pytest.raises(SceneError, match=r"s\.toml: bodies\[0\]\.shape\.file: mesh file '.*nope\.stl' not found"):
        parse_scene(_scene(body), source="s.toml", base_dir=tmp_path)


def test_primitive_volumes():
    h = DX / 2
    tube = Tube([0.02, 0.02, 0.02], 6e-3, 3e-3, 12e-3, axis=[1, 1, 0])
    star = Transformed(Slab(Polygon([[0, 0], [8e-3, 0], [8e-3, 3e-3], [2e-3, 3e-3], [2e-3, 8e-3], [0, 8e-3]]), 4e-3), [0.015, 0.012, 0.02], euler_rotation([0, 0, 30]))
    arc = Transformed(Slab(AnnularSector(8e-3, 3e-3, np.deg2rad(-30), np.deg2rad(200)), 3e-3), [0.02, 0.02, 0.02], euler_rotation([90, 0, 0]))
    for shape in (tube, star, arc):
        pts, v = fill_lattice(shape, DX, 2, ORIGIN, 3)
        assert v == pytest.approx(h**3)
        assert abs(len(pts) * v / shape.volume() - 1) < 0.03, (type(shape.local if hasattr(shape, "local") else shape).__name__, len(pts) * v, shape.volume())
    assert tube.volume() == pytest.approx(np.pi * (36e-6 - 9e-6) * 12e-3)
    assert arc.volume() == pytest.approx(np.deg2rad(230) * 8e-3 * 3e-3 * 3e-3)
    # 2D arc strip: an annular sector in the plane
    sector = Transformed(AnnularSector(5e-3, 2e-3, 0.0, np.pi), [0.01, 0.01])
    pts, a = fill_lattice(sector, 2.5e-4, 2, np.zeros(2), 2)
    assert abs(len(pts) * a / (np.pi * 5e-3 * 2e-3) - 1) < 0.02


def test_new_shape_keys_in_a_scene(tmp_path):
    d = _scene({"name": "t", "shape": {"type": "tube", "center": [0.02, 0.02, 0.015], "outer_radius": 5e-3, "inner_radius": 6e-3, "length": 0.01}, "material": "ecoflex-00-30"})
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape\.inner_radius: must be < outer_radius"):
        parse_scene(d)
    d = _scene({"name": "a", "shape": {"type": "arc", "center": [0.02, 0.02, 0.015], "radius": 5e-3, "width": 2e-3}, "material": "ecoflex-00-30"})
    with pytest.raises(SceneError, match=r"bodies\[0\]\.shape\.thickness: required"):
        parse_scene(d)
    d["bodies"][0]["shape"]["thickness"] = 2e-3
    p = fill_bodies(parse_scene(d))
    assert abs(p.report[0]["filled_volume"] / p.report[0]["shape_volume"] - 1) < 0.05
