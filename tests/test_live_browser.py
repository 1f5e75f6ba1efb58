"""``magsoro live``: the server's input checks and life cycle without a browser, the poses of magnet sources, the
saved scene and the recording, the default camera, then the page in headless Chromium (driven over the DevTools
protocol as in test_report_browser.py; skipped, saying why, without Chromium): sliders (|B| and direction, Bx in
mT, a magnet's strength and place) change the field the engine uses and the particles follow, the floor and the
magnet are drawn, the colour mode switches, the probe plot fills, pause, step and reset act, "Save as scene" writes
a scene that loads back to the page's settings, "Record" writes a run folder that render and report read, bad input
is refused on the page, no console errors, and the server stops when the page closes."""

from __future__ import annotations

import base64
import json
import os
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from magsoro.viz.live import (
    ControlError,
    Controls,
    Limits,
    parse_command,
    parse_control,
)
from magsoro.viz.live_scene import IDENTITY_POSE

# a clamped strip magnetised along x in a field along +y: about 270 particles, bends up within milliseconds
STRIP = """
name = "live_strip"

[simulation]
dim = 2
dx = 4.0e-4
particles_per_cell = 2
domain_lo = [0.0, -0.008]
domain_hi = [0.014, 0.008]
duration = 1.0
damping = 200.0
depth = 5.0e-3

[[bodies]]
name = "strip"
shape = { type = "rectangle", center = [0.0055, 0.0], size = [0.009, 0.0012] }
material = { density = 1030.0, shear_modulus = 100.0e3 }
magnetization = [0.1, 0.0, 0.0]

[[clamps]]
region = { type = "rectangle", center = [0.0008, 0.0], size = [0.0012, 0.003] }

[[fields]]
type = "uniform"
B = [0.0, 0.01, 0.0]
"""

DIPOLE = """
[[fields]]
type = "dipole"
name = "magnet"
moment = [0.0, 0.01, 0.0]
position = [0.006, -0.02, 0.0]
"""

# a floor below the strip and a probe at its tip: what the page draws and plots
FLOOR_PROBE = """
[[colliders]]
type = "half_space"
point = [0.0, -0.0065]
normal = [0.0, 1.0]

[[probes]]
type = "tip"
name = "tip"
body = "strip"
region = { type = "rectangle", center = [0.0098, 0.0], size = [0.0006, 0.0014] }

[output]
every = 0.002
"""


@pytest.fixture
def strip(tmp_path) -> Path:
    path = tmp_path / "strip.toml"
    path.write_text(STRIP)
    return path


def _server(path: Path, **options):
    from magsoro.scene import load_scene
    from magsoro.viz.live import LiveServer

    return LiveServer(load_scene(path), str(path), port=0, **options)


def _request(url: str, method: str = "GET", body: bytes | None = None, headers: dict | None = None):
    """(status, parsed JSON or raw bytes, headers) of one request; HTTP errors are answers, not exceptions."""
    req = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            code, raw, hdrs = r.status, r.read(), r.headers
    except urllib.error.HTTPError as exc:
        code, raw, hdrs = exc.code, exc.read(), exc.headers
    if hdrs.get("Content-Type", "").startswith("application/json"):
        return code, json.loads(raw), hdrs
    return code, raw, hdrs


def _post(url: str, payload, raw: bytes | None = None, headers: dict | None = None):
    body = raw if raw is not None else json.dumps(payload).encode()
    return _request(url, "POST", body, {"Content-Type": "application/json", **(headers or {})})


class _Any:
    def __eq__(self, other):
        return True


_ANY = _Any()


def _frame(raw: bytes, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(positions (n, 3) m, colour values (n)) of a /frame answer."""
    a = np.frombuffer(raw, dtype="<f4")
    assert a.size == 4 * n, (a.size, n)
    return a[: 3 * n].reshape(n, 3), a[3 * n:]


def _wait_for(cond, timeout: float, what: str, step: float = 0.05):
    deadline = time.monotonic() + timeout
    while True:
        value = cond()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(step)


# ------------------------------------------------------------------------------------------ input checks
LIM2 = Limits(dim=2, max_field=0.02, max_gain=2.0, sources=("magnet",))
LIM3 = Limits(dim=3, max_field=0.02, max_gain=2.0, sources=())


def test_parse_control_accepts_and_switches_mode():
    c0 = Controls(True, 0.01, 90.0, 0.0, {"magnet": 1.0})
    c = parse_control({"field": {"magnitude": 0.015}}, c0, LIM2)
    assert c.magnitude == 0.015 and not c.follow_scene and c.azimuth == 90.0  # a value set by hand leaves the scene's profile
    c = parse_control({"field": {"follow_scene": True}}, c, LIM2)
    assert c.follow_scene and c.magnitude == 0.015
    c = parse_control({"gains": {"magnet": 0}, "field": {"azimuth": -180, "magnitude": 0}}, c, LIM2)
    assert c.gains == {"magnet": 0.0} and c.azimuth == -180.0 and c.magnitude == 0.0
    np.testing.assert_allclose(parse_control({"field": {"magnitude": 0.02, "azimuth": 0, "elevation": 90}}, c0, LIM3).vector(),
                               [0, 0, 0.02], atol=1e-15)
    assert parse_control({}, c0, LIM2) == c0


@pytest.mark.parametrize("payload, message", [
    ({"field": {"magnitude": "abc"}}, 'field.magnitude: must be a number (T), got "abc"'),
    ({"field": {"magnitude": True}}, "field.magnitude: must be a number"),
    ({"field": {"azimuth": None}}, "field.azimuth: must be a number (degrees), got null"),
    ({"field": {"magnitude": float("nan")}}, "field.magnitude: must be a finite number"),
    ({"field": {"magnitude": 10**400}}, "field.magnitude: must be a finite number"),
    ({"field": {"magnitude": 0.5}}, "field.magnitude: 0.5 T is out of range [0, 0.02] T"),
    ({"field": {"magnitude": -0.001}}, "out of range"),
    ({"field": {"azimuth": 181}}, "field.azimuth: 181 degrees is out of range [-180, 180]"),
    ({"field": {"elevation": 10}}, "field.elevation: 10 degrees is out of range [0, 0]"),  # 2D: in-plane only
    ({"field": {"follow_scene": "yes"}}, "field.follow_scene: must be true or false"),
    ({"field": {"strength": 1}}, "field: unknown key 'strength'"),
    ({"field": 0.01}, "field: must be an object"),
    ({"gains": {"coil": 1.0}}, "gains: no field source named 'coil'; sources with a gain: magnet"),
    ({"gains": {"magnet": 3}}, "gains.magnet: 3 x the scene's strength is out of range [0, 2]"),
    ({"gains": [1]}, "gains: must be an object"),
    ({"speed": 2}, "unknown key 'speed'; allowed: field, gains"),
    ([1, 2], "a control must be a JSON object"),
    # all or nothing: a valid field change does not go through with a bad gain
    ({"field": {"magnitude": 0.01}, "gains": {"nope": 1}}, "no field source named 'nope'"),
])
def test_parse_control_refuses(payload, message):
    with pytest.raises(ControlError) as err:
        parse_control(payload, Controls(), LIM2)
    assert message in str(err.value)


def test_parse_control_components_and_poses():
    c0 = Controls(True, 0.01, 90.0, 0.0, {"magnet": 1.0})
    c = parse_control({"field": {"Bx": 0.003}}, c0, LIM2)  # Bx set, By kept from the current vector (0.01 along +y)
    np.testing.assert_allclose(c.vector(), [0.003, 0.01, 0.0], atol=1e-15)
    assert c.cartesian == (0.003, 0.01, 0.0) and not c.follow_scene
    assert c.magnitude == pytest.approx(np.hypot(0.003, 0.01)) and c.azimuth == pytest.approx(np.degrees(np.arctan2(0.01, 0.003)))
    assert c.as_json()["B"] == [0.003, 0.01, 0.0]
    back = parse_control({"field": {"magnitude": 0.005}}, c, LIM2)  # back to magnitude/direction: the direction kept
    assert back.cartesian is None and back.azimuth == pytest.approx(c.azimuth)
    np.testing.assert_allclose(back.vector(), 0.005 / np.hypot(0.003, 0.01) * np.array([0.003, 0.01, 0.0]), atol=1e-15)
    p = parse_control({"poses": {"magnet": {"x": 0.002, "rz": 45}}}, c0, LIM2)
    assert p.poses == {"magnet": (0.002, 0.0, 0.0, 0.0, 0.0, 45.0)} and p.as_json()["poses"]["magnet"]["rz"] == 45.0
    p = parse_control({"poses": {"magnet": {"y": -0.001}}}, p, LIM2)
    assert p.poses["magnet"] == (0.002, -0.001, 0.0, 0.0, 0.0, 45.0)
    np.testing.assert_allclose(parse_control({"field": {"Bx": 0.0, "By": 0.0, "Bz": -0.02}}, c0, LIM3).vector(), [0, 0, -0.02])


@pytest.mark.parametrize("payload, message", [
    ({"field": {"Bx": 0.015, "By": 0.015}}, "field: |B| = 0.0212132 T is out of range [0, 0.02] T"),
    ({"field": {"Bx": -0.03}}, "field.Bx: -0.03 T is out of range [-0.02, 0.02] T"),
    ({"field": {"Bz": 0.001}}, "field.Bz: 0.001 T is out of range [0, 0] T"),  # 2D: in-plane only
    ({"field": {"Bx": 0.001, "magnitude": 0.01}}, "field: give magnitude, azimuth, elevation or Bx, By, Bz, not both"),
    ({"field": {"By": "1"}}, 'field.By: must be a number (T), got "1"'),
    ({"poses": {"coil": {"x": 0}}}, "poses: no field source named 'coil'; sources with a pose: magnet"),
    ({"poses": {"magnet": {"x": 5.0}}}, "poses.magnet.x: 5 m is out of range [-0.1, 0.1] m"),
    ({"poses": {"magnet": {"rz": 200}}}, "poses.magnet.rz: 200 degrees is out of range [-180, 180]"),
    ({"poses": {"magnet": {"scale": 2}}}, "poses.magnet: unknown key 'scale'; allowed: x, y, z, rx, ry, rz"),
    ({"poses": {"magnet": 1}}, "poses.magnet: must be an object"),
    ({"poses": []}, "poses: must be an object"),
])
def test_parse_control_refuses_components_and_poses(payload, message):
    lim = Limits(dim=2, max_field=0.02, max_gain=2.0, sources=("magnet",), max_offset=0.1)
    with pytest.raises(ControlError) as err:
        parse_control(payload, Controls(), lim)
    assert message in str(err.value)


def test_parse_command():
    assert [parse_command({"action": a}) for a in ("pause", "resume", "reset")] == [("pause", {}), ("resume", {}), ("reset", {})]
    assert parse_command({"action": "step"}) == ("step", {"steps": 1})
    assert parse_command({"action": "step", "steps": 25}) == ("step", {"steps": 25})
    assert parse_command({"action": "save_scene", "name": "bent-2"}) == ("save_scene", {"name": "bent-2"})
    assert parse_command({"action": "save_scene"}) == ("save_scene", {"name": "live_scene"})
    assert parse_command({"action": "record_start"}) == ("record_start", {})
    for bad, message in (({"action": "stop"}, "unknown action \"stop\""), ({}, "a command must be"), ("reset", "a command must be"),
                         ({"action": "reset", "x": 1}, "'x' is not one of reset's"),
                         ({"action": "step", "steps": 0}, "steps must be a whole number in"),
                         ({"action": "step", "steps": 1.5}, "steps must be a whole number in"),
                         ({"action": "step", "steps": True}, "steps must be a whole number in"),
                         ({"action": "save_scene", "name": "../etc/passwd"}, "a scene name must be"),
                         ({"action": "save_scene", "name": "a/b"}, "a scene name must be"),
                         ({"action": "save_scene", "name": ".hidden"}, "a scene name must be"),
                         ({"action": "save_scene", "name": "x" * 65}, "a scene name must be"),
                         ({"action": "save_scene", "name": 3}, "a scene name must be")):
        with pytest.raises(ControlError, match=message.replace("(", r"\(").replace("|", r"\|")):
            parse_command(bad)


def test_scaled_source_device_form_matches_host():
    """A source's strength slider scales B and grad B in the engine's device evaluation as on the host."""
    import warp as wp

    from magsoro.fields import Dipole, Uniform
    from magsoro.fields.device import FieldEvaluator
    from magsoro.viz.live import LiveUniform, ScaledSource

    dip = Dipole(moment=[0.0, 0.05, 0.0], position=[2e-3, -6e-3, 0.5e-3])
    scaled = ScaledSource(dip, max_gain=2.0)
    live = LiveUniform([Uniform([0.0, 0.01, 0.0])], bound=0.02)
    ev = FieldEvaluator([live, scaled], 3, wp.float64, "cpu")
    pts = np.random.default_rng(1).uniform(-2e-3, 2e-3, size=(6, 3))
    for gain, follow in ((1.0, True), (0.35, False), (0.0, False)):
        scaled.gain, live.follow_scene, live.vector = gain, follow, np.array([0.003, 0.0, -0.004])
        B, G = ev.evaluate_host(pts)
        uniform = np.array([0.0, 0.01, 0.0]) if follow else live.vector
        np.testing.assert_allclose(B, gain * dip.B(pts) + uniform, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(G, gain * dip.grad_B(pts), rtol=1e-12, atol=1e-12)
    assert live.peak() == 0.02 and scaled.max_magnitude(pts) == pytest.approx(2.0 * dip.max_magnitude(pts))


def test_moved_source_device_form_matches_host():
    """A magnet moved and turned from the page: the device form (the engine's) equals the host form, which is the
    source's own field at the moved point, turned: B'(p) = g R B(R^T (p - c - d) + c)."""
    import warp as wp

    from magsoro.fields import Dipole
    from magsoro.fields.device import FieldEvaluator
    from magsoro.viz.live import ScaledSource
    from magsoro.viz.live_scene import pose_matrix

    dip = Dipole(moment=[0.0, 0.05, 0.01], position=[2e-3, -6e-3, 0.5e-3])
    scaled = ScaledSource(dip, max_gain=2.0, pivot=dip.position)
    ev = FieldEvaluator([scaled], 3, wp.float64, "cpu")
    pts = np.random.default_rng(2).uniform(-2e-3, 2e-3, size=(6, 3))
    pose = (1e-3, -2e-3, 0.5e-3, 20.0, -35.0, 110.0)
    scaled.set_pose(pose)
    scaled.gain = 0.7
    R, d, c = pose_matrix(*pose[3:]), np.array(pose[:3]), dip.position
    q = (R.T @ (pts - c - d).T).T + c
    want_B = 0.7 * dip.B(q) @ R.T
    want_G = 0.7 * np.einsum("ij,njk,lk->nil", R, dip.grad_B(q), R)
    np.testing.assert_allclose(scaled.B(pts), want_B, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(scaled.grad_B(pts), want_G, rtol=1e-12, atol=1e-15)
    B, G = ev.evaluate_host(pts)
    np.testing.assert_allclose(B, want_B, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(G, want_G, rtol=1e-12, atol=1e-15)
    scaled.set_pose(IDENTITY_POSE)  # back where the scene put it: the source's own numbers, bit for bit
    scaled.gain = 1.0
    B, G = ev.evaluate_host(pts)
    B0, G0 = FieldEvaluator([dip], 3, wp.float64, "cpu").evaluate_host(pts)
    assert np.array_equal(B, B0) and np.array_equal(G, G0) and np.array_equal(scaled.B(pts), dip.B(pts))


@pytest.mark.parametrize("entry", [
    {"type": "dipole", "name": "m", "moment": [0.0, 0.01, 0.002], "position": [0.001, -0.02, 0.003],
     "path": {"times": [0.0, 1.0], "positions": [[0.001, -0.02, 0.003], [0.004, -0.02, 0.003]]}},
    {"type": "cylinder_magnet", "name": "m", "diameter": 0.004, "length": 0.006, "remanence": 1.2,
     "position": [0.002, -0.03, 0.0], "axis": [0.0, 1.0, 0.3]},
    {"type": "cuboid_magnet", "name": "m", "dimensions": [0.004, 0.005, 0.006], "remanence": [0.0, 0.0, 1.3],
     "position": [0.0, -0.03, 0.002], "orientation": [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]},
    {"type": "loop", "name": "m", "radius": 0.01, "current": 2.0, "turns": 50, "position": [0.0, 0.0, -0.02]},
    {"type": "helmholtz", "name": "m", "radius": 0.03, "current": -1.5, "position": [0.001, 0.0, 0.0], "axis": [1.0, 0.0, 0.0]},
])
def test_saved_source_is_the_moved_source(entry):
    """What "save as scene" writes for a moved, turned and scaled source is the field the live view drove the
    engine with: the saved entry's source equals the wrapped one at random points, B and grad B."""
    from pydantic import TypeAdapter

    from magsoro.scene.build import make_field
    from magsoro.scene.schema import AnyField
    from magsoro.viz.live import ScaledSource
    from magsoro.viz.live_scene import posed_spec, spec_pivot

    spec = TypeAdapter(AnyField).validate_python(entry)
    pose, gain = (0.002, 0.001, -0.003, 15.0, 40.0, -70.0), 0.6
    live = [ScaledSource(e, 2.0, spec_pivot(spec)) for e in make_field(spec, None).sources()]
    for s in live:
        s.set_pose(pose)
        s.gain = gain
    saved = make_field(posed_spec(spec, pose, gain), None)
    pts = np.random.default_rng(3).uniform(-4e-3, 4e-3, size=(8, 3))
    for t in (0.0, 0.5):
        np.testing.assert_allclose(sum(s.B(pts, t) for s in live), saved.B(pts, t), rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(sum(s.grad_B(pts, t) for s in live), saved.grad_B(pts, t), rtol=1e-8, atol=1e-12)
    assert posed_spec(spec, IDENTITY_POSE, 1.0) == spec  # nothing moved: the entry as it was


def test_default_camera_looks_at_the_bending_plane():
    from magsoro.viz.camera import bend_view

    g = np.random.default_rng(4)
    strip_x = g.uniform([0, -2.5e-3, -0.4e-3], [0.018, 2.5e-3, 0.4e-3], size=(500, 3))  # along x, thin in z
    m_x = np.tile([0.26, 0.0, 0.0], (500, 1))
    # the cantilever of scenes/cantilever_3d.toml: m along x, B along z -> it bends in x-z: look along y, z up
    v = bend_view(strip_x, 3, m_x, [0.0, 0.0, 0.006])
    assert v["plane"] == "x-z" and v["right"] == [1.0, 0.0, 0.0] and v["up"] == [0.0, 0.0, 1.0] and v["towards"] == [0.0, -1.0, 0.0]
    assert v["why"] == "the plane of the magnetisation and the field"
    # m along the thickness (z), B along the length (x): the same plane
    assert bend_view(strip_x, 3, np.tile([0, 0, 0.1], (500, 1)), [0.01, 0, 0])["plane"] == "x-z"
    # no torque (m along B along the length): the plane of the longest and thinnest extents
    v = bend_view(strip_x, 3, m_x, [0.01, 0.0, 0.0])
    assert v["plane"] == "x-z" and "longest and thinnest" in v["why"]
    # a strip along y magnetised along y in a field along x bends in x-y: look down z; gravity -y keeps y up
    strip_y = strip_x[:, [1, 0, 2]]
    v = bend_view(strip_y, 3, np.tile([0, 0.1, 0], (500, 1)), [0.01, 0, 0], gravity=[0, -9.81, 0])
    assert v["plane"] == "x-y" and v["up"] == [0.0, 1.0, 0.0] and v["right"] == [1.0, 0.0, 0.0]
    assert bend_view(strip_x[:, :2], 2)["towards"] == [0.0, 0.0, 1.0]  # 2D: the x-y plane


def test_collider_outlines():
    from magsoro.mpm.colliders import Collider
    from magsoro.viz.live_scene import collider_outline

    floor = collider_outline(Collider.half_space([0.0, -0.0065, 0.0], [0.0, 1.0, 0.0]), 2, [0.0, -0.008], [0.014, 0.008], 0.0)
    loop = np.array(floor["loops"][0])
    assert floor["fill"] and floor["kind"] == "half_space" and len(loop) == 4  # the part of the domain below the floor
    np.testing.assert_allclose(loop.min(axis=0), [0.0, -0.008, 0.0]) and np.testing.assert_allclose(loop.max(axis=0), [0.014, -0.0065, 0.0])
    plane = collider_outline(Collider.half_space([0.0, 0.0, 0.001], [0.0, 0.0, 1.0]), 3, [-1e-3, -2e-3, -3e-3], [1e-3, 2e-3, 3e-3], 0.0)
    loop = np.array(plane["loops"][0])
    assert len(loop) == 4 and np.allclose(loop[:, 2], 0.001) and np.allclose(np.abs(loop[:, :2]), [1e-3, 2e-3])
    box = collider_outline(Collider.box([0.0, 0.0, 0.0], [1e-3, 2e-3, 3e-3]), 3, [-1, -1, -1], [1, 1, 1], 0.0)
    assert len(box["loops"]) == 6 and not box["fill"]  # two faces and four edges
    disc = collider_outline(Collider.sphere([0.001, 0.002, 0.0], 5e-4), 2, [-1, -1], [1, 1], 0.0)
    np.testing.assert_allclose(np.linalg.norm(np.array(disc["loops"][0]) - [0.001, 0.002, 0.0], axis=1), 5e-4)


# ------------------------------------------------------------------------------------------ the server
def test_server_endpoints_and_refusals(tmp_path):
    from magsoro.fields import Dipole

    path = tmp_path / "strip_dipole.toml"
    path.write_text(STRIP + DIPOLE)
    srv = _server(path, paused=True, max_field=0.03)
    srv.start()
    url = srv.url
    try:
        code, info, _ = _request(url + "info")
        assert code == 200 and info["dim"] == 2 and info["sources"] == ["magnet"] and info["bodies"] == ["strip"]
        assert info["shown"] == info["particles"] == len(info["body"]) and info["limits"]["magnitude"] == [0.0, 0.03]
        code, page, hdrs = _request(url)
        assert code == 200 and b"<canvas id=\"view\"" in page and hdrs["Content-Type"].startswith("text/html")
        assert b"http://" not in page.replace(b"http://www.w3.org", b"") and b"https://" not in page  # nothing fetched from outside
        code, st, _ = _request(url + "state")
        assert code == 200 and st["paused"] and st["time"] == 0.0 and st["engine_field"] == [0.0, 0.01, 0.0]
        code, frame, hdrs = _request(url + "frame")
        x, body = _frame(frame, info["shown"])
        assert len(x) == info["shown"] and np.all(x[:, 2] == 0) and int(hdrs["X-Frame"]) >= 1
        assert hdrs["X-Color"] == "part" and np.array_equal(body, info["body"])  # colour values: the body index
        assert info["view"]["plane"] == "x-y" and info["colliders"] == [] and info["probes"] == [] and info["out_dir"] is None
        assert st["markers"] == [{"name": "magnet", "type": "dipole", "position": [0.006, -0.02, 0.0], "direction": [0.0, 1.0, 0.0], "size": 0.0}]

        refusals = [
            (_post(url + "control", None, raw=b"{not json"), 400, "the request is not valid JSON"),
            (_post(url + "control", None, raw=b'{"field": {"magnitude": NaN}}'), 400, "NaN is not a number JSON allows"),
            (_post(url + "control", None, raw=b'{"field": {"magnitude": 1e999}}'), 400, "must be a finite number"),
            (_post(url + "control", None, raw=b"[" * 5000 + b"]" * 5000), 400, "the request is not valid JSON"),
            (_post(url + "control", {"field": {"magnitude": "0.01"}}), 400, 'field.magnitude: must be a number (T), got "0.01"'),
            (_post(url + "control", {"field": {"magnitude": 0.04}}), 400, "0.04 T is out of range [0, 0.03] T"),
            (_post(url + "control", {"gains": {"coil": 1}}), 400, "no field source named 'coil'"),
            (_post(url + "command", {"action": "explode"}), 400, "unknown action"),
            (_post(url + "control", {"field": {}}, headers={"Origin": "http://example.com"}), 403, "requests from http://example.com are refused"),
            (_request(url + "state", headers={"Host": "attacker.example:80"}), 403, "answers only at"),
            (_post(url + "control", None, raw=b"x" * 20000), 413, "at most"),
            (_request(url + "nothing"), 404, "no such page"),
            (_post(url + "command", {"action": "save_scene", "name": "x"}), 400, "save_scene: this live view writes nothing; start it with --out DIR"),
            (_post(url + "command", {"action": "record_start"}), 400, "record_start: this live view writes nothing"),
            (_post(url + "command", {"action": "save_scene", "name": "../x"}), 400, "a scene name must be"),
            (_post(url + "view", {"color": "rainbow"}), 400, "color: unknown mode \"rainbow\"; allowed: part, speed, strain, magnetisation"),
            (_post(url + "view", {"colour": "part"}), 400, "a view setting must be"),
            (_request(url + "probe?column=tip_x"), 400, "probe: no column named \"tip_x\"; columns: none (the scene has no [[probes]])"),
            (_request(url + "probe?column=tip_x&since=-1"), 400, "probe: since must be a whole number"),
            (_post(url + "control", {"poses": {"magnet": {"x": 1.0}}}), 400, "poses.magnet.x: 1 m is out of range [-0.016, 0.016] m"),
        ]
        for (code, body, _), want_code, want in refusals:
            assert code == want_code and want in body["error"], (code, body)
        assert _request(url + "state")[1]["controls"]["magnitude"] == 0.01  # nothing changed

        code, body, _ = _post(url + "control", {"field": {"magnitude": 0.02, "azimuth": 0}, "gains": {"magnet": 0.5}})
        assert code == 200 and body["controls"]["follow_scene"] is False
        st = _wait_for(lambda: (s := _request(url + "state")[1])["applied"]["gains"] == {"magnet": 0.5} and s, 10, "the controls to apply")
        np.testing.assert_allclose(st["engine_field"], [0.02, 0.0, 0.0], atol=1e-12)
        sim = srv.session.sim
        scaled = [s for s in sim.control.sources if not s.uniform]
        assert len(scaled) == 1 and scaled[0].gain == 0.5 and scaled[0].device_params(0.0)[-1] == 0.5
        # Bx alone: By kept from the current vector, the field in components
        assert _post(url + "control", {"field": {"Bx": 0.01}})[0] == 200
        st = _wait_for(lambda: (s := _request(url + "state")[1])["applied"]["B"][0] == 0.01 and s, 10, "Bx to apply")
        np.testing.assert_allclose(st["engine_field"], [0.01, 0.0, 0.0], atol=1e-12)
        # the magnet moved 4 mm along +x and turned a quarter turn about z: the engine's source moves, the marker too,
        # and the time step is bounded anew for the field the moved magnet gives
        peak0 = sim.solver.field_magnitude(sim.control)
        assert _post(url + "control", {"poses": {"magnet": {"x": 0.004, "rz": 90}}})[0] == 200
        st = _wait_for(lambda: (s := _request(url + "state")[1])["markers"][0]["position"][0] == 0.01 and s, 10, "the magnet to move")
        assert st["markers"][0]["direction"] == [-1.0, 0.0, 0.0] and st["applied"]["poses"]["magnet"]["rz"] == 90.0
        assert scaled[0].pose == (0.004, 0.0, 0.0, 0.0, 0.0, 90.0)
        np.testing.assert_allclose(scaled[0].B([[0.01, 0.0, 0.0]]), 0.5 * Dipole([-0.01, 0.0, 0.0], [0.01, -0.02, 0.0]).B([[0.01, 0.0, 0.0]]), rtol=1e-12)
        # nearer the strip (8 mm below it): the field bound of the time step grows (Simulation.set_sources)
        assert _post(url + "control", {"poses": {"magnet": {"y": 0.012}}})[0] == 200
        _wait_for(lambda: _request(url + "state")[1]["markers"][0]["position"][1] == -0.008, 10, "the magnet to come nearer")
        assert sim.solver.field_magnitude(sim.control) > peak0 + 1e-3
        code, body, _ = _post(url + "view", {"color": "speed"})
        assert code == 200 and body == {"ok": True, "color": "speed"}
        _wait_for(lambda: _request(url + "frame")[2]["X-Color"] == "speed", 10, "the frames to carry speeds")

        # stepping, a failed step shown as the state's error, and reset
        assert _post(url + "command", {"action": "resume"})[0] == 200
        _wait_for(lambda: _request(url + "state")[1]["steps"] > 0, 60, "steps")

        def boom(t_end, callback=None):
            from magsoro.errors import SimulationError

            raise SimulationError("deliberate failure", step=7, time=1.5e-5)

        srv.session.sim.advance_to = boom
        st = _wait_for(lambda: (s := _request(url + "state")[1])["error"] and s, 10, "the failure")
        assert st["phase"] == "failed" and st["error"] == "step 7, t = 1.5e-05 s: deliberate failure" and st["speed"] == 0.0
        assert _post(url + "command", {"action": "reset"})[0] == 200
        st = _wait_for(lambda: (s := _request(url + "state")[1])["error"] is None and s, 20, "the reset")
        assert srv.session.sim is not sim and srv.session.sim.control.sources[0] is sim.control.sources[0]  # same wrappers
        assert st["applied"]["gains"] == {"magnet": 0.5}  # the controls survive a reset
        assert _post(url + "command", {"action": "pause"})[0] == 200
        st = _wait_for(lambda: (s := _request(url + "state")[1])["phase"] == "paused" and s, 10, "pause")
        time.sleep(0.3)
        assert _request(url + "state")[1]["steps"] == st["steps"]
    finally:
        srv.close()
    assert srv.session.stop_reason == "stopped"


def _expected_saved(srv):
    """The scene the page's settings make (what "save as scene" must write)."""
    from magsoro.viz.live_scene import scene_with_controls

    s = srv.session
    return scene_with_controls(s.scene, s.requested, s.fields.scene_indices(), s.dim)


def _check_saved(path: Path, srv, B, magnet_position) -> None:
    """The saved scene loads back equal to the page's settings: its uniform field B (T), the magnet's position."""
    import tomllib

    from magsoro.scene import load_scene

    back = load_scene(path)
    assert repr(back.model_dump()) == repr(_expected_saved(srv).model_dump())  # equal to the bit
    fields = {f.type: f for f in back.fields}
    assert fields["uniform"].B == B and fields["dipole"].position == magnet_position
    assert tomllib.loads(path.read_text())["name"] == "live_strip"


def _check_recording(folder: Path, frames: int) -> None:
    """A recording is a run folder that magsoro render and report read."""
    from magsoro.io.outdir import read_run_info
    from magsoro.viz.render import open_run
    from magsoro.viz.report import read_metrics, viewer_data

    info = read_run_info(folder)
    assert info["status"] == "completed" and info["live"]["every"] == 0.002 and "recorded from magsoro live" in info["message"]
    series = open_run(folder)
    assert len(series.stamps) == frames >= 2 and series.dim == 2 and series.body_names == ["strip"]
    np.testing.assert_allclose(np.diff(series.stamps), 0.002, rtol=1e-6)  # frames every output.every of simulated time
    columns, values, rows = read_metrics(folder)
    assert columns == ["time", "tip_x", "tip_y"] and rows == frames
    np.testing.assert_allclose(values[0], series.stamps, rtol=1e-6)  # a metrics row per frame, at its time
    assert viewer_data(folder)["frames"] and (folder / "final.npz").is_file()


def test_server_saves_and_records(tmp_path, monkeypatch):
    path = tmp_path / "strip.toml"
    path.write_text(STRIP + DIPOLE + FLOOR_PROBE)
    out = tmp_path / "out"
    (out / "record_001").mkdir(parents=True)  # taken: the next free number is used, nothing is replaced
    srv = _server(path, paused=True, out_dir=out)
    srv.start()
    url = srv.url
    try:
        info = _request(url + "info")[1]
        assert info["out_dir"] == str(out.resolve()) and info["probes"] == [{"column": "tip_x", "unit": "m"}, {"column": "tip_y", "unit": "m"}]
        floor = info["colliders"][0]
        assert floor["kind"] == "half_space" and floor["fill"] and max(p[1] for p in floor["loops"][0]) == pytest.approx(-0.0065)
        # step: paused, exactly the steps asked for
        assert _post(url + "command", {"action": "step", "steps": 3}) == (200, {"ok": True, "action": "step"}, _ANY)
        st = _wait_for(lambda: (s := _request(url + "state")[1])["steps"] == 3 and s["phase"] == "paused" and s, 30, "3 steps")
        assert st["paused"] and st["time"] > 0
        series = _request(url + "probe?column=tip_y&since=0")[1]
        assert series["unit"] == "m" and series["seq"] >= 2 and len(series["t"]) == len(series["v"]) == series["seq"]
        assert _request(url + f"probe?column=tip_y&since={series['seq']}")[1]["t"] == []
        # save as scene, after setting the field and moving the magnet; a second save never replaces the first
        assert _post(url + "control", {"field": {"Bx": 0.004, "By": -0.003}, "poses": {"magnet": {"x": 0.001}}})[0] == 200
        code, body, _ = _post(url + "command", {"action": "save_scene", "name": "bent"})
        assert code == 200 and body["file"] == "bent.toml" and Path(body["path"]) == out.resolve() / "bent.toml"
        _check_saved(out / "bent.toml", srv, [0.004, -0.003, 0.0], [0.007, -0.02, 0.0])
        assert _post(url + "command", {"action": "save_scene", "name": "bent"})[1]["file"] == "bent_2.toml"
        # record while running, then stop: frames every output.every, a run folder render and report read
        assert _post(url + "command", {"action": "record_start"})[0] == 200
        assert _post(url + "command", {"action": "resume"})[0] == 200
        st = _wait_for(lambda: ((s := _request(url + "state")[1])["recording"] or {}).get("frames", 0) >= 3 and s, 60, "3 frames")
        assert st["recording"]["folder"] == "record_002"
        code, body, _ = _post(url + "command", {"action": "record_start"})
        assert code == 400 and body["error"] == "record_start: already recording into record_002"
        assert _post(url + "command", {"action": "record_stop"})[0] == 200
        st = _wait_for(lambda: (s := _request(url + "state")[1])["recording"] is None and s["record_message"] and s, 20, "the recording to close")
        frames = int(st["record_message"].split(": ")[1].split()[0])
        assert st["record_message"] == f"record_002: {frames} frames written (stopped from the page)"
        _check_recording(out / "record_002", frames)
        # a recording stops itself at its frame limit, saying so
        monkeypatch.setattr("magsoro.viz.live_record.MAX_RECORD_FRAMES", 3)
        assert _post(url + "command", {"action": "record_start"})[0] == 200
        st = _wait_for(lambda: (s := _request(url + "state")[1])["recording"] is None and (s["record_message"] or "").startswith("record_003") and s, 30, "the limit")
        assert st["record_message"] == "record_003: 3 frames written (the recording reached its limit of 3 frames)"
        _check_recording(out / "record_003", 3)
        assert sorted(p.name for p in out.iterdir()) == ["bent.toml", "bent_2.toml", "record_001", "record_002", "record_003"]
        assert list((out / "record_001").iterdir()) == []
    finally:
        srv.close()


def test_server_stops_when_the_page_goes(strip):
    srv = _server(strip, paused=True, idle_timeout=0.5)
    srv.start()
    try:
        assert srv.wait(timeout=1.0) is None  # no page has connected yet: the server waits for one
        _request(srv.url + "state")
        assert "no request from the page for 0.5 s" in srv.wait(timeout=10)
    finally:
        srv.close()
    srv = _server(strip, paused=True)
    srv.start()
    try:
        _request(srv.url + "state")
        assert _request(srv.url + "bye", "POST", b"")[0] == 204
        assert srv.wait(timeout=10) == "the page was closed"
    finally:
        srv.close()


def test_time_step_allows_for_the_largest_field(strip):
    """The CFL step counts the magnetic stiffening of the largest |B| the sliders reach, not only the scene's."""
    from magsoro.simulation import Simulation

    scene_dt = Simulation.from_file(strip).dt
    small, large = _server(strip, paused=True, max_field=0.02), _server(strip, paused=True, max_field=20.0)
    try:
        assert small.session.sim.dt == pytest.approx(scene_dt, rel=1e-3)
        assert large.session.sim.dt < 0.8 * scene_dt
        assert large.session.sim.solver.field_magnitude(large.session.sim.control) == pytest.approx(20.0)
    finally:
        small.close()
        large.close()


def test_cli_serves_and_stops_on_ctrl_c(strip):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    # SIGINT back to its default in the child: a test run started in the background of a non-interactive shell
    # (`bash .ci/run &`) inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler (as in
    # tests/test_sweep.py)
    proc = subprocess.Popen([sys.executable, "-m", "magsoro", "live", str(strip), "--port", "0", "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        url = None
        deadline = time.monotonic() + 60
        lines = []
        while url is None and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "open http://" in line:
                url = line.split("open ", 1)[1].split()[0]
        assert url, f"no address printed: {lines}, {proc.stderr.read() if proc.poll() is not None else ''}"
        _wait_for(lambda: _request(url + "state")[1]["time"] > 0, 120, "the simulation to advance", step=0.2)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err[-2000:]
    assert "stopped by Ctrl-C; stopped at t = " in out and "Traceback" not in err


def test_cli_refuses_bad_options(strip, capsys):
    from magsoro.cli import main

    assert main(["live", str(strip), "--max-points", "30000", "--no-browser"]) == 2
    assert "--max-points: must be in [1, 20000]" in capsys.readouterr().err
    assert main(["live", str(strip), "--max-field", "nan", "--no-browser"]) == 2
    assert "--max-field: must be a finite number > 0" in capsys.readouterr().err
    assert main(["live", str(strip), "--out", str(strip), "--no-browser"]) == 2
    assert f"--out: {strip} is a file; give a folder" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ the page in Chromium
@pytest.fixture(scope="module")
def chromium():
    from test_report_browser import find_chromium

    binary = find_chromium()
    if binary is None:
        pytest.skip("Chromium not installed (command -v chromium failed); .ci/run installs Debian's chromium with apt-get, "
                    "or run: apt-get update && apt-get install -y chromium")
    return binary


def test_live_page_in_chromium(chromium, tmp_path):
    from test_report_browser import DevTools, _artifact

    strip = tmp_path / "strip.toml"
    strip.write_text(STRIP + DIPOLE + FLOOR_PROBE)
    out = tmp_path / "out"
    srv = _server(strip, idle_timeout=10, out_dir=out)
    srv.start()
    dt = DevTools(chromium, tmp_path / "profile")
    try:
        target = dt.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = dt.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Page", "Network"):
            dt.send(f"{domain}.enable", session=session)
        dt.send("Emulation.setDeviceMetricsOverride", {"width": 1280, "height": 860, "deviceScaleFactor": 1, "mobile": False}, session=session)
        dt.send("Page.navigate", {"url": srv.url}, session=session)
        dt.wait_event("Page.loadEventFired")

        def js(expr, await_promise=False):
            res = dt.send("Runtime.evaluate", {"expression": expr, "returnByValue": True, "awaitPromise": await_promise}, session=session)
            if "exceptionDetails" in res:
                raise RuntimeError(f"{expr}: {res['exceptionDetails']}")
            return res["result"].get("value")

        def state():
            return _request(srv.url + "state")[1]

        def frame_mean_y():
            return float(_frame(srv.session.frame()[1], len(srv.session.index))[0][:, 1].mean())

        def attr(element, name):
            return js(f"document.getElementById('{element}').getAttribute('{name}')")

        def set_input(element, value, event="input"):
            js(f"""(function () {{ var e = document.getElementById('{element}'); e.value = {json.dumps(value)};
                   e.dispatchEvent(new Event('{event}')); }})()""")

        def pixels(rgb, same=True):  # canvas pixels of exactly this colour (same=False: of any other colour)
            # read from a copy made for reading: Chrome warns about repeated reads of a drawn canvas
            return js("""(function () {
                var c = document.getElementById('view'), k = document.createElement('canvas');
                k.width = c.width; k.height = c.height;
                var x = k.getContext('2d', {willReadFrequently: true}); x.drawImage(c, 0, 0);
                var d = x.getImageData(0, 0, c.width, c.height).data, n = 0;
                for (var i = 0; i < d.length; i += 4) if ((d[i] === %d && d[i+1] === %d && d[i+2] === %d) === %s) n++;
                return n; })()""" % (*rgb, "true" if same else "false"))

        # the page runs: status, time and particles drawn; the strip bends up in the scene's +y field
        _wait_for(lambda: js("document.getElementById('status').textContent") == "running", 120, "the page to say running")
        _wait_for(lambda: js("document.getElementById('view').getAttribute('data-points')") == "270", 20, "particles drawn")
        _wait_for(lambda: frame_mean_y() > 3e-4, 30, "the strip to bend up")
        assert js("document.getElementById('time').textContent").startswith("t = ")
        assert "steps/s" in js("document.getElementById('readout').textContent")
        np.testing.assert_allclose(state()["engine_field"], [0.0, 0.01, 0.0])
        # the floor is drawn (filled below its line, in its own grey), and the magnet as a marker
        assert attr("view", "data-floor") == "1" and attr("view", "data-colliders") == "1" and attr("view", "data-markers") == "1"
        assert pixels((0xd5, 0xdb, 0xe1)) > 2000, "the floor is not drawn"
        # the probe plot fills with the scene's first probe column
        _wait_for(lambda: int(attr("probe-plot", "data-samples") or 0) > 3, 20, "probe samples plotted")
        assert attr("probe-plot", "data-column") == "tip_x"

        # move the sliders as a user would: 15 mT pointing down (-y)
        js("""(function () {
            var m = document.getElementById('magnitude'); m.value = 15; m.dispatchEvent(new Event('input'));
            var a = document.getElementById('azimuth'); a.value = -90; a.dispatchEvent(new Event('input'));
        })()""")
        st = _wait_for(lambda: (s := state())["applied"]["azimuth"] == -90.0 and s["applied"]["magnitude"] == 0.015 and s, 10, "the slider values to reach the engine")
        assert st["applied"]["follow_scene"] is False and js("document.getElementById('follow').checked") is False
        np.testing.assert_allclose(st["engine_field"], [0.0, -0.015, 0.0], atol=1e-12)
        sim = srv.session.sim
        # what the solver itself adds as the uniform field at this time (its field evaluator over control.sources)
        np.testing.assert_allclose(sim.solver.field_evaluator(sim.control).uniform_value(sim.time), [0.0, -0.015, 0.0], atol=1e-12)
        # the particles follow: the strip swings below the axis, on the server and on the page
        _wait_for(lambda: frame_mean_y() < -3e-4, 40, "the strip to bend down")
        _wait_for(lambda: (js("liveView().mean_y") or 0) < -3e-4, 10, "the page's particles to follow")
        assert "-15.000" in js("document.getElementById('applied').textContent")
        assert js("document.getElementById('By').value") == "-15"  # the components follow the direction set
        # Bx in mT: 5 mT along x on top of the -15 mT along y
        set_input("Bx", "5")
        st = _wait_for(lambda: (s := state())["applied"]["B"][0] == 0.005 and s, 10, "Bx to reach the engine")
        np.testing.assert_allclose(st["engine_field"], [0.005, -0.015, 0.0], atol=1e-12)
        np.testing.assert_allclose(sim.solver.field_evaluator(sim.control).uniform_value(sim.time), [0.005, -0.015, 0.0], atol=1e-12)
        # the magnitude slider follows (to its step of 1/1000 of its range)
        _wait_for(lambda: abs(float(js("document.getElementById('magnitude').value")) - 1e3 * np.hypot(0.005, 0.015)) < 0.02, 10, "|B| to follow Bx")
        # the magnet's strength and place: half as strong, 2 mm along +x
        set_input("gain-magnet", "0.5")
        js("document.getElementById('pose-magnet').open = true")
        set_input("pose-magnet-x", "2")
        st = _wait_for(lambda: (s := state())["markers"][0]["position"][0] == pytest.approx(0.008) and s, 10, "the magnet to move")
        scaled = [s for s in sim.control.sources if not s.uniform][0]
        assert st["applied"]["gains"] == {"magnet": 0.5} and scaled.gain == 0.5 and scaled.pose[0] == pytest.approx(0.002)
        # colour by strain: the frames carry strains, the page draws them with a colour bar
        set_input("color-mode", "strain", "change")
        _wait_for(lambda: attr("view", "data-color") == "strain", 10, "strain colours drawn")
        assert _request(srv.url + "frame")[2]["X-Color"] == "strain"
        assert js("document.getElementById('colorbar').style.display") == "flex"
        assert "%" in js("document.getElementById('colorbar-hi').textContent")
        # plot the tip's height instead: it is below the axis now
        set_input("probe-column", "tip_y", "change")
        _wait_for(lambda: attr("probe-plot", "data-column") == "tip_y" and int(attr("probe-plot", "data-samples") or 0) > 0, 10, "tip_y plotted")
        assert js("liveView().probe.last") < 0

        # bad input from the page is refused, with the server's message shown on the page
        bad = [({"field": {"magnitude": "strong"}}, 'field.magnitude: must be a number (T), got "strong"'),
               ({"field": {"magnitude": 1.0}}, "field.magnitude: 1 T is out of range [0, 0.02] T"),
               ({"gains": {"coil": 1.0}}, "gains: no field source named 'coil'")]
        for payload, message in bad:
            js(f"liveControl({json.dumps(payload)})", await_promise=True)
            shown = js("document.getElementById('message').textContent")
            assert shown.startswith("refused: " + message), shown
            assert js("document.getElementById('message').className") == "refused"
        np.testing.assert_allclose(state()["engine_field"], [0.005, -0.015, 0.0], atol=1e-12)  # unchanged

        # pause and resume from the buttons
        js("document.getElementById('pause').click()")
        _wait_for(lambda: js("document.getElementById('status').textContent") == "paused", 10, "paused")
        t_paused = state()["time"]
        time.sleep(0.4)
        assert state()["time"] == t_paused and js("document.getElementById('pause').textContent") == "Resume"
        # step while paused: exactly the time steps asked for
        steps0 = state()["steps"]
        set_input("step-count", "4")
        js("document.getElementById('step').click()")
        _wait_for(lambda: state()["steps"] == steps0 + 4 and state()["phase"] == "paused", 20, "4 steps")
        time.sleep(0.3)
        assert state()["steps"] == steps0 + 4
        _wait_for(lambda: js("document.getElementById('status').textContent") == "paused", 10, "the page to say paused")
        js("document.getElementById('pause').click()")
        _wait_for(lambda: state()["time"] > t_paused, 10, "resumed")
        # save as scene: a TOML in --out that loads back to the page's settings
        set_input("save-name", "bent")
        js("document.getElementById('save-scene').click()")
        _wait_for(lambda: js("document.getElementById('save-status').textContent").startswith("saved "), 10, "the scene saved")
        assert js("document.getElementById('save-status').textContent") == f"saved {out.resolve() / 'bent.toml'}"
        _check_saved(out / "bent.toml", srv, [0.005, -0.015, 0.0], [0.008, -0.02, 0.0])
        # record: frames into a run folder that magsoro render and report read
        js("document.getElementById('record').click()")
        _wait_for(lambda: ((state()["recording"] or {}).get("frames", 0)) >= 3, 30, "3 frames recorded")
        # the button follows the page's next poll of the server's state, not the server at once
        _wait_for(lambda: js("document.getElementById('record').textContent") == "Stop recording", 10, "the button to say Stop recording")
        js("document.getElementById('record').click()")
        st = _wait_for(lambda: (s := state())["record_message"] and s, 20, "the recording to close")
        _wait_for(lambda: js("document.getElementById('record-status').textContent") == st["record_message"], 10, "the page to say so")
        _check_recording(out / "record_001", int(st["record_message"].split(": ")[1].split()[0]))
        from magsoro.viz.render import render_run

        assert render_run(out / "record_001", tmp_path / "recorded.png", color="strain").frames == 1
        # orbit the view with the mouse, then look at it
        js("""(function () {
            var c = document.getElementById('view');
            c.dispatchEvent(new PointerEvent('pointerdown', {clientX: 300, clientY: 200, pointerId: 1}));
            c.dispatchEvent(new PointerEvent('pointermove', {clientX: 330, clientY: 215, pointerId: 1}));
            c.dispatchEvent(new PointerEvent('pointerup', {clientX: 330, clientY: 215, pointerId: 1}));
        })()""")
        time.sleep(0.3)
        ink = pixels((251, 252, 253), same=False)
        assert ink > 500, "the particle canvas is blank"
        shot = _artifact(tmp_path, "live.png")
        shot.write_bytes(base64.b64decode(dt.send("Page.captureScreenshot", {"format": "png"}, session=session)["data"]))
        assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 10_000
        assert js("liveProblems.length") == 0 and not js("document.getElementById('status').textContent").startswith("error")

        # a failed step stops the run with its message on the page; Reset starts again from t = 0
        def boom(t_end, callback=None):
            from magsoro.errors import SimulationError

            raise SimulationError("deliberate failure", step=3, time=1e-5)

        old_sim = srv.session.sim
        old_sim.advance_to = boom
        _wait_for(lambda: js("document.getElementById('message').className") == "failed", 10, "the failure on the page")
        assert js("document.getElementById('message').textContent").startswith("simulation stopped: step 3, t = 1e-05 s: deliberate failure")
        _wait_for(lambda: js("document.getElementById('status').textContent") == "failed", 10, "status failed")
        failed_shot = _artifact(tmp_path, "live_failed.png")
        failed_shot.write_bytes(base64.b64decode(dt.send("Page.captureScreenshot", {"format": "png"}, session=session)["data"]))
        js("document.getElementById('reset').click()")
        _wait_for(lambda: srv.session.sim is not old_sim and state()["error"] is None, 20, "the reset")
        _wait_for(lambda: js("document.getElementById('message').className") == "" and
                  js("document.getElementById('status').textContent") == "running", 10, "the page to clear the failure")
        assert state()["applied"]["B"] == [0.005, -0.015, 0.0]  # the sliders' field stays through a reset

        # closing the page stops the server (its goodbye beacon on pagehide, or else the missing heartbeat)
        dt.send("Page.close", session=session)
        reason = srv.wait(timeout=30)
        assert reason in ("the page was closed", "no request from the page for 10 s (closed or unreachable)"), reason
    finally:
        dt.close()
        srv.close()

    problems, refused = [], 0
    for ev in dt.events:
        m, p = ev.get("method"), ev.get("params", {})
        if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert", "warning"):
            problems.append(f"console.{p['type']}: " + " ".join(str(a.get("value", a.get("description"))) for a in p.get("args", [])))
        elif m == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            problems.append(f"exception: {d.get('text')} {d.get('exception', {}).get('description', '')}")
        elif m == "Log.entryAdded" and p.get("entry", {}).get("level") in ("error", "warning"):
            e = p["entry"]
            if e.get("source") == "network" and e.get("url", "").endswith("/control") and "400" in e.get("text", ""):
                refused += 1  # the deliberate bad inputs above: the browser logs every 400 answer
            else:
                problems.append(f"log {e['level']}: {e.get('text')} ({e.get('url', '')})")
        elif m == "Network.requestWillBeSent" and not p["request"]["url"].startswith((srv.url, "data:", "about:")):
            problems.append(f"request outside the server: {p['request']['url']}")
    assert problems == [], problems
    assert refused <= len(bad)
