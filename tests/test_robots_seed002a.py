"""Robots of seed 002 sec 4-5.2: the triangle (warping), the cross (arching and grabbing) and the pentagram
(crawling and gripping) under the N35 magnet moved beneath the plate (docs/robots.md). The triangle's preview
reproduction runs in the default suite; the others' and the full reproductions are slow tests."""

import math

import numpy as np
import pytest

from magsoro.robots import ROBOTS, reproduce
from magsoro.robots.base import read_csv, scene, scene_data

SEED002A = ("triangle", "cross", "pentagram")


@pytest.mark.parametrize("name", SEED002A)
def test_preview_scene_builds(name):
    sc = scene(name, preview=True)
    full = scene(name)
    assert sc.simulation.dx >= full.simulation.dx
    assert ROBOTS[name].source.startswith("seed 002 sec ")
    assert [f.type for f in sc.fields] == ["cylinder_magnet"]


@pytest.mark.parametrize("name", ["triangle", "cross"])
def test_scene_magnet_path_is_the_full_sweep(name):
    """The magnet path written in the scene file is the sweep the robot module computes (distances giving
    B_z = 0, 5, ..., 45 mT at the robot's centre), so `magsoro run` shows what `magsoro reproduce` measures."""
    import importlib

    from magsoro.robots.triangle import cylinder_magnet, stepped_path

    mod = importlib.import_module(f"magsoro.robots.{name}")
    data = scene_data(name)
    magnet = next(f for f in data["fields"] if f.get("name") == "magnet")
    offsets = mod.magnet_offsets(magnet, mod.LEVELS_MT)
    first_hold = getattr(mod, "SETTLE", getattr(mod, "FIRST_HOLD", None))
    times, positions, reads = stepped_path(offsets, first_hold, mod.HOLD, mod.MOVE)
    assert np.allclose(magnet["path"]["times"], times)
    assert np.allclose(magnet["path"]["positions"], positions, atol=1e-5)
    assert data["simulation"]["duration"] == pytest.approx(reads[-1])
    # and the field there is the level (the magnet's own closed form, independent of the root finder)
    mid = mod.ROBOT_MID_Z if hasattr(mod, "ROBOT_MID_Z") else mod.MID_Z
    for lv, pos in zip(mod.LEVELS_MT[1:], offsets[1:]):
        bz = cylinder_magnet(magnet, pos).B([[0.0, 0.0, mid]])[0, 2]
        assert abs(bz) == pytest.approx(lv * 1e-3, rel=1e-5)


def test_cross_rod_matches_linear_beam_at_low_field():
    """The cross's rod reference reduces to the small-deflection cantilever (distributed couple over the arm,
    clamped at the centre, gravity) in a weak uniform field, and bends less than it in a strong one."""
    from magsoro.robots.cross import ARM_LENGTH, ARM_WIDTH, HALF_CORE, MU0, THICKNESS, strip_rod

    G, K, rho, br, B = 66.7e3, 20 * 66.7e3, 1500.0, 0.0443, 0.004
    E = 9 * K * G / (3 * K + G)
    EI = E * ARM_WIDTH * THICKNESS ** 3 / 12
    w = rho * 9.81 * ARM_WIDTH * THICKNESS
    end = HALF_CORE + ARM_LENGTH

    def linear(b):
        q = br / MU0 * ARM_WIDTH * THICKNESS * b
        couple = q / EI * (ARM_LENGTH * (end * HALF_CORE - HALF_CORE ** 2 / 2) + ARM_LENGTH ** 3 / 3)
        return couple - w * end ** 4 / (8 * EI)

    assert strip_rod(B, None, G, K, rho, br, tip_length=1e-9) == pytest.approx(linear(B), rel=0.03)
    # large fields bend less than the linear estimate (the couple falls as cos theta)
    assert strip_rod(0.045, None, G, K, rho, br, tip_length=1e-9) < 0.8 * linear(0.045)


def _check_triangle(res):
    assert res.passed, [r.as_dict() for r in res.rows]
    data = read_csv(res.csv)
    wt, ht = data["warp_height_Wt_mm"], data["centroid_rise_Ht_mm"]
    # a side half bent by a uniform couple lifts its end about three times its mean rise (tip / mean of a
    # parabola), and the sides' midpoints stay down: W_t / H_t near 3 at the top level
    assert 2.0 < wt[-1] / ht[-1] < 4.5
    # no lift without field, warping grows with B
    assert abs(wt[0]) < 0.05 and np.all(np.diff(wt) > 0)
    for f in (res.csv, res.png, res.animation):
        assert f.exists() and f.stat().st_size > 0
    assert res.animation.stat().st_size < 1.5e6
    _check_speeds(res, ("warping_vertex_rise_rate_mm_s",))
    sp = read_csv(res.figures[0]["csv"])
    # the robot goes along with the magnet, and slower than it
    loco = sp["locomotion_centroid_speed_along_magnet_mm_s"][-1]
    assert 0.0 < loco < sp["magnet_speed_mm_s"][-1]


def _check_speeds(res, columns):
    """Speeds under the moving magnet: one figure (CSV, PNG); the rates are positive (the right way) and, where
    several magnet speeds were run, grow with the magnet's speed (the shape follows the magnet)."""
    assert len(res.figures) == 1
    sp = read_csv(res.figures[0]["csv"])
    assert res.figures[0]["png"].stat().st_size > 0
    for col in columns:
        assert np.all(sp[col] > 0), (col, sp[col])
        assert np.all(np.diff(sp[col]) > 0), (col, sp[col])
        # quasi-static: the rate is a fraction of the magnet's speed
        assert np.all(sp[col] < sp["magnet_speed_mm_s"])


def test_speed_helpers():
    from magsoro.robots._seed002_speeds import largest_rate, magnet_speed_for

    t = np.arange(0.0, 0.2, 0.005)
    z = np.where(t < 0.1, 0.0, 0.003 * (t - 0.1))   # still, then 3 mm/s
    rate, when = largest_rate(t, z)
    assert rate == pytest.approx(0.003) and when >= 0.1
    assert largest_rate(t, z, t_from=1.0)[0] != largest_rate(t, z, t_from=1.0)[0]   # nothing after t_from: NaN
    assert magnet_speed_for(15.0, [50, 100, 200], [10.0, 20.0, 40.0]) == pytest.approx(75.0)
    assert magnet_speed_for(5.0, [50, 100], [10.0, 20.0]) is None       # below the range: not extrapolated
    assert magnet_speed_for(15.0, [50, 100], [20.0, 10.0]) is None      # not growing with the magnet's speed


def test_pass_path_with_an_approach_keeps_the_pass():
    """A pass's magnet path with an approach: the magnet waits SETTLE s farther along +y, then moves at one speed
    through PASS_FROM (at t_start) to PASS_TO (at t_pass); without one it is the explicit runs' path unchanged."""
    from magsoro.robots import _seed002_speeds as sp

    speed = 0.02
    plain, t0, t1 = sp.pass_path(speed)
    assert plain == {"times": [0.0, sp.SETTLE, t1], "positions": [[0.0, sp.PASS_FROM, sp.Z_TOP]] * 2
                     + [[0.0, sp.PASS_TO, sp.Z_TOP]]} and t0 == sp.SETTLE
    path, t_start, t_pass = sp.pass_path(speed, approach=0.06)
    assert t_start == pytest.approx(sp.SETTLE + 3.0) and t_pass - t_start == pytest.approx(t1 - t0)
    ts = np.array([0.0, sp.SETTLE, 1.0, t_start, 5.0, t_pass])
    y = np.interp(ts, path["times"], [p[1] for p in path["positions"]])  # keyframes, linear in between
    assert y[0] == y[1] == pytest.approx(sp.PASS_FROM + 0.06)
    assert y[3] == pytest.approx(sp.PASS_FROM) and y[5] == pytest.approx(sp.PASS_TO)
    moving = ts >= sp.SETTLE
    assert np.allclose(y[moving], sp.PASS_FROM + 0.06 - speed * (ts[moving] - sp.SETTLE))  # one speed throughout


def test_stroke_path_rises_moves_level_and_goes_down_at_one_speed():
    """A stroke's magnet path: SETTLE s at Z_START under the start, up to Z_TOP, level to under the end, down to
    Z_START, every leg at the stroke's speed (path length over time)."""
    from magsoro.robots import _seed002_speeds as sp

    speed, a, b = 0.01, (0.0, 0.023), (0.003, -0.0115)
    path, (t_up, t_moved, t_down) = sp.stroke_path(a, b, speed)
    p, t = np.asarray(path["positions"]), np.asarray(path["times"])
    assert p[0].tolist() == p[1].tolist() == [0.0, 0.023, sp.Z_START] and t[1] == sp.SETTLE
    assert p[2].tolist() == [0.0, 0.023, sp.Z_TOP] and p[3].tolist() == [0.003, -0.0115, sp.Z_TOP]
    assert p[4].tolist() == [0.003, -0.0115, sp.Z_START]
    legs = np.linalg.norm(np.diff(p[1:], axis=0), axis=1) / np.diff(t[1:])
    assert np.allclose(legs, speed) and [t_up, t_moved, t_down] == t[2:].tolist()
    assert t_moved - t_up == pytest.approx(math.hypot(0.003, 0.0345) / speed)


@pytest.mark.slow
def test_triangle_stroke_preview_moves_the_robot_along_the_stroke(tmp_path):
    """magsoro reproduce triangle_stroke --preview (about 2 minutes): one stroke at 20 mm/s by the implicit
    integrator on the coarse grid moves the robot +1.20 mm along the stroke (measured with steps of 0.25 mm of
    magnet travel throughout and of 0.5 to 2 mm: 1.19 to 1.20), back 1.3 to 1.4 mm while the magnet moves level;
    the top vertex rises at 0.37 of the magnet's speed (softer than the full grid's 0.2: one cell through the
    plate)."""
    res = reproduce("triangle_stroke", out=tmp_path, preview=True)
    table = read_csv(res.csv)
    assert table["magnet_speed_mm_s"].tolist() == [20.0]
    assert table["centroid_along_stroke_mm"][0] == pytest.approx(1.20, abs=0.1)
    assert -1.5 < table["centroid_along_level_move_mm"][0] < -1.2
    assert table["vertex_rise_rate_mm_s"][0] / 20.0 == pytest.approx(0.37, abs=0.03)
    assert (tmp_path / "triangle_stroke_views.png").is_file() and (tmp_path / "triangle_stroke_course.csv").is_file()


def test_rise_path_waits_then_rises_at_one_speed():
    """A rise's magnet path: SETTLE s at Z_START under the point, then up to Z_TOP at the rise's speed."""
    from magsoro.robots import _seed002_speeds as sp

    path, t_up = sp.rise_path((0.001, -0.002), 0.005)
    p, t = np.asarray(path["positions"]), np.asarray(path["times"])
    assert p.tolist() == [[0.001, -0.002, sp.Z_START]] * 2 + [[0.001, -0.002, sp.Z_TOP]]
    assert t.tolist() == [0.0, sp.SETTLE, t_up] and t_up - sp.SETTLE == pytest.approx((sp.Z_TOP - sp.Z_START) / 0.005)


def test_cross_rise_scene_is_the_arching_rise_at_20_mm_s():
    """scenes/cross_rise.toml's magnet is the paper's actuator south face up on the 20 mm/s rise that
    ``magsoro reproduce cross_rise`` runs first (so `magsoro run` shows what it measures), with the cross's bodies."""
    from magsoro.robots import _seed002_speeds as sp

    data = scene_data("cross_rise")
    magnet = data["fields"][0]
    path, t_up = sp.rise_path((0.0, 0.0), 0.02)
    assert magnet["remanence"] == -sp.ACTUATOR_BR
    assert magnet["path"]["times"] == pytest.approx(path["times"])
    assert np.allclose(magnet["path"]["positions"], path["positions"])
    assert data["simulation"]["duration"] == pytest.approx(t_up + sp.AFTER)
    assert data["simulation"]["integrator"] == "implicit"
    assert [b["name"] for b in data["bodies"]] == [b["name"] for b in scene_data("cross")["bodies"]]


@pytest.mark.slow
def test_cross_rise_preview_arches_and_grabs(tmp_path):
    """magsoro reproduce cross_rise --preview (about a minute): the magnet rising at 20 mm/s on the coarse grid
    arches the cross 4.96 mm and makes it grab 5.12 mm from the start of its rise to the top (measured). One cell
    through the strips makes them far softer than the full grid: they bend 3.9 mm already with the magnet at its
    start (7 mT), where the full grid bends 0.9 mm and the static solver about 1 mm (cross.csv: 0.39 at 5 mT, 1.31
    at 10 mT)."""
    res = reproduce("cross_rise", out=tmp_path, preview=True)
    table = read_csv(res.csv)
    assert table["magnet_speed_mm_s"].tolist() == [20.0]
    assert table["arching_deflection_growth_mm"][0] == pytest.approx(4.96, abs=0.15)
    assert table["grabbing_deflection_growth_mm"][0] == pytest.approx(5.12, abs=0.15)
    assert all(r.passed for r in res.rows)
    assert (tmp_path / "cross_rise_course.png").is_file()


@pytest.mark.slow
def test_triangle_preview_warps(tmp_path):
    _check_triangle(reproduce("triangle", out=tmp_path, preview=True))


@pytest.mark.slow
def test_triangle_full(tmp_path):
    _check_triangle(reproduce("triangle", out=tmp_path))


def _check_cross(res):
    assert res.passed, [r.as_dict() for r in res.rows]
    data = read_csv(res.csv)
    # arching lifts the centre (its tips stay on the plate), grabbing lifts the tips (its centre stays down)
    assert np.all(data["arch_centre_z_mm"][1:] >= data["arch_centre_z_mm"][0] - 0.05)
    assert data["grab_centre_z_mm"][-1] - data["grab_centre_z_mm"][0] < 0.5
    # a 10 mm strip cannot rise by more than its length
    assert data["grab_deflection_mm"].max() < 12.0 and data["arch_deflection_mm"].max() < 12.0
    assert res.animation.stat().st_size < 1.5e6
    _check_speeds(res, ("arching_deflection_rate_mm_s", "grabbing_deflection_rate_mm_s"))


@pytest.mark.slow
def test_cross_preview(tmp_path):
    _check_cross(reproduce("cross", out=tmp_path, preview=True))


@pytest.mark.slow
def test_cross_full(tmp_path):
    _check_cross(reproduce("cross", out=tmp_path))


# the pentagram checks that our model fails: the five strips closing alike on the coarse (dx 2 mm) lattice (the
# preview's grip), and the paper's gait (the table shape of Fig. 14a3) in none of the crawls: the robot is carried
# along folded in a heap (scenes/pentagram.toml says so). The crawl check passes (the robot moves with the magnet).
PENTAGRAM_KNOWN_GAPS = ("gripping: spread", "crawling: crawls showing the table shape")


def _check_pentagram(res, crawls: int):
    data = read_csv(res.csv)
    # gripping: the outer parts rise off the plate and move in towards the centre as the field grows
    assert data["outer_parts_rise_mm"][-1] > 5.0
    assert data["grip_closure_mm"][-1] > data["grip_closure_mm"][1] > -0.5
    # nothing leaves the domain or sinks through the plate
    crawl = read_csv(res.csv.with_name("pentagram_crawl.csv"))
    assert np.all(np.isfinite(crawl["centroid_x_mm"])) and crawl["centroid_z_mm"].min() > 0.5
    assert res.animation.stat().st_size < 1.5e6
    # the gait study: every crawl reached the four moments of Fig. 14a (the magnet passes the whole robot) and
    # moved the robot the magnet's way
    gait = read_csv(res.csv.with_name("pentagram_gait.csv"))
    assert len(gait["hinge_mm"]) == crawls
    for key in ("a1_part2_rise_mm", "a3_angle_parts12_deg", "a3_angle_parts13_deg"):
        assert np.all(np.isfinite(gait[key])), key
    assert np.all(gait["displacement_mm"] > 1.0)
    failing = [r.quantity for r in res.rows if not r.passed]
    unexpected = [q for q in failing if not q.startswith(PENTAGRAM_KNOWN_GAPS)]
    assert not unexpected, [r.as_dict() for r in res.rows]
    if failing:
        pytest.xfail(f"known gaps to seed 002 sec 5.2: {failing}")


def test_pentagram_hinges_split_the_strip():
    from magsoro.robots.pentagram import HUB_INRADIUS, STRIP_LENGTH, _hinge, with_hinges

    base = scene_data("pentagram")
    assert _hinge(base) == pytest.approx(5e-3)
    # the scene's own hinges give its own strips back
    same = with_hinges(base, 5e-3)["bodies"]
    assert all(np.allclose(a["shape"]["vertices"], b["shape"]["vertices"]) for a, b in zip(same, base["bodies"]))
    d = with_hinges(base, 1e-3)
    for k in range(1, 6):
        spans = {b["name"].split("_")[1]: (b["shape"]["vertices"][0][0], b["shape"]["vertices"][1][0])
                 for b in d["bodies"] if b["name"].startswith(f"s{k}_")}
        lengths = {kind: hi - lo for kind, (lo, hi) in spans.items()}
        assert lengths["h1"] == pytest.approx(1e-3) and lengths["h2"] == pytest.approx(1e-3)
        for kind in ("p1", "p2", "p3"):
            assert lengths[kind] == pytest.approx((STRIP_LENGTH - 2e-3) / 3)
        assert spans["p1"][0] == pytest.approx(HUB_INRADIUS)
        assert spans["p3"][1] == pytest.approx(HUB_INRADIUS + STRIP_LENGTH)   # the tips stay where they were
        assert spans["h1"][0] == pytest.approx(spans["p1"][1]) and spans["p2"][0] == pytest.approx(spans["h1"][1])
    assert scene("pentagram", d).bodies  # the scene still validates
    with pytest.raises(Exception, match="hinge length 20 mm leaves no thick parts"):
        with_hinges(base, 20e-3)


def test_pentagram_gait_reads_the_arch_and_the_table():
    from magsoro.robots.pentagram import gait

    def run(rise, angle_12, angle_13, dx=2e-3):
        a1 = {"rise": rise}
        a3 = {"angle_12": angle_12, "angle_13": angle_13}
        return {"moments": {"a1": a1, "a3": a3}, "dx": dx}

    # Fig. 14a: part 2 lifted by a part's thickness over part 3 at rest; then a table (part 2 upright, 1 and 3 parallel)
    assert gait(run([0.0, 4e-3, 0.5e-3], 90.0, 10.0)) == {"arch": True, "table": True}
    assert gait(run([0.0, 2e-3, 0.5e-3], 90.0, 10.0))["arch"] is False       # part 2 not lifted enough
    assert gait(run([0.0, 4e-3, 3e-3], 90.0, 10.0))["arch"] is False         # part 3 lifted too
    assert gait(run([0.0, 4e-3, 3e-3], 90.0, 10.0, dx=4e-3))["arch"] is True  # ... by less than a cell
    assert gait(run([0.0, 0.0, 0.0], 150.0, 10.0))["table"] is False         # folded over, not upright
    assert gait(run([0.0, 0.0, 0.0], 90.0, 80.0))["table"] is False          # part 1 not parallel to part 3
    assert gait({"moments": {}, "dx": 2e-3}) == {"arch": False, "table": False}  # the magnet never got there


@pytest.mark.slow
def test_pentagram_preview(tmp_path):
    _check_pentagram(reproduce("pentagram", out=tmp_path, preview=True), 1)


@pytest.mark.slow
def test_pentagram_full(tmp_path):
    _check_pentagram(reproduce("pentagram", out=tmp_path), 6)
