"""``magsoro live``: the server's input checks and life cycle without a browser, then the page in headless
Chromium (driven over the DevTools protocol as in test_report_browser.py; skipped, saying why, without Chromium):
a slider moves, the field the engine uses changes, the particles follow, bad input is refused on the page, no
console errors, and the server stops when the page closes."""

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


def test_parse_command():
    assert [parse_command({"action": a}) for a in ("pause", "resume", "reset")] == ["pause", "resume", "reset"]
    for bad, message in (({"action": "stop"}, "unknown action \"stop\""), ({}, "a command must be"), ("reset", "a command must be"),
                         ({"action": "reset", "x": 1}, "a command must be")):
        with pytest.raises(ControlError, match=message):
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


# ------------------------------------------------------------------------------------------ the server
def test_server_endpoints_and_refusals(tmp_path):
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
        x = np.frombuffer(frame, dtype="<f4").reshape(-1, 3)
        assert len(x) == info["shown"] and np.all(x[:, 2] == 0) and int(hdrs["X-Frame"]) >= 1

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


# ------------------------------------------------------------------------------------------ the page in Chromium
@pytest.fixture(scope="module")
def chromium():
    from test_report_browser import find_chromium

    binary = find_chromium()
    if binary is None:
        pytest.skip("Chromium not installed (command -v chromium failed); .ci/run installs Debian's chromium with apt-get, "
                    "or run: apt-get update && apt-get install -y chromium")
    return binary


def test_live_page_in_chromium(chromium, strip, tmp_path):
    from test_report_browser import DevTools, _artifact

    srv = _server(strip, idle_timeout=10)
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
            return float(np.frombuffer(srv.session.frame()[1], dtype="<f4").reshape(-1, 3)[:, 1].mean())

        # the page runs: status, time and particles drawn; the strip bends up in the scene's +y field
        _wait_for(lambda: js("document.getElementById('status').textContent") == "running", 120, "the page to say running")
        _wait_for(lambda: js("document.getElementById('view').getAttribute('data-points')") == "270", 20, "particles drawn")
        _wait_for(lambda: frame_mean_y() > 3e-4, 30, "the strip to bend up")
        assert js("document.getElementById('time').textContent").startswith("t = ")
        assert "steps/s" in js("document.getElementById('readout').textContent")
        np.testing.assert_allclose(state()["engine_field"], [0.0, 0.01, 0.0])

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

        # bad input from the page is refused, with the server's message shown on the page
        bad = [({"field": {"magnitude": "strong"}}, 'field.magnitude: must be a number (T), got "strong"'),
               ({"field": {"magnitude": 1.0}}, "field.magnitude: 1 T is out of range [0, 0.02] T"),
               ({"gains": {"coil": 1.0}}, "gains: no field source named 'coil'")]
        for payload, message in bad:
            js(f"liveControl({json.dumps(payload)})", await_promise=True)
            shown = js("document.getElementById('message').textContent")
            assert shown.startswith("refused: " + message), shown
            assert js("document.getElementById('message').className") == "refused"
        np.testing.assert_allclose(state()["engine_field"], [0.0, -0.015, 0.0], atol=1e-12)  # unchanged

        # pause and resume from the buttons
        js("document.getElementById('pause').click()")
        _wait_for(lambda: js("document.getElementById('status').textContent") == "paused", 10, "paused")
        t_paused = state()["time"]
        time.sleep(0.4)
        assert state()["time"] == t_paused and js("document.getElementById('pause').textContent") == "Resume"
        js("document.getElementById('pause').click()")
        _wait_for(lambda: state()["time"] > t_paused, 10, "resumed")
        # orbit the view with the mouse, then look at it
        js("""(function () {
            var c = document.getElementById('view');
            c.dispatchEvent(new PointerEvent('pointerdown', {clientX: 300, clientY: 200, pointerId: 1}));
            c.dispatchEvent(new PointerEvent('pointermove', {clientX: 330, clientY: 215, pointerId: 1}));
            c.dispatchEvent(new PointerEvent('pointerup', {clientX: 330, clientY: 215, pointerId: 1}));
        })()""")
        time.sleep(0.3)
        ink = js("""(function () {
            var c = document.getElementById('view'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, n = 0;
            for (var i = 0; i < d.length; i += 4) if (!(d[i] === 251 && d[i+1] === 252 && d[i+2] === 253)) n++;
            return n; })()""")
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
        assert state()["applied"]["magnitude"] == 0.015  # the sliders' field stays through a reset

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
