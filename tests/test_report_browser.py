"""The HTML report in a real browser: headless Chromium driven over the DevTools protocol.

Chromium is started with ``--remote-debugging-pipe`` (DevTools messages as NUL-terminated JSON on file
descriptors 3 and 4), which needs nothing beyond the standard library: no websocket client, no free port.
Console messages, uncaught exceptions, log entries and every network request are collected while the page
loads from a file:// URL. The test skips, saying why, when Chromium is not installed (.ci/run installs
Debian's ``chromium``).
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import queue
import shutil
import subprocess
import threading
import time
from pathlib import Path

import pytest

from test_report import make_run_dir, make_sweep_dir

CHROMIUM_FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-extensions", "--mute-audio", "--hide-scrollbars",
]


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


class DevTools:
    """Minimal Chrome DevTools Protocol client over --remote-debugging-pipe."""

    def __init__(self, binary: str, user_data_dir: Path):
        cmd_r, self._cmd_w = os.pipe()  # we write commands, Chromium reads them on its fd 3
        self._out_r, out_w = os.pipe()  # Chromium writes replies and events on its fd 4

        def child_fds():
            # move both ends above 3 and 4 first: either may itself be fd 3 or 4, and dup2 onto itself would
            # keep its close-on-exec flag
            hi_r = fcntl.fcntl(cmd_r, fcntl.F_DUPFD, 10)
            hi_w = fcntl.fcntl(out_w, fcntl.F_DUPFD, 10)
            os.dup2(hi_r, 3)
            os.dup2(hi_w, 4)

        self.proc = subprocess.Popen(
            [binary, *CHROMIUM_FLAGS, "--remote-debugging-pipe", f"--user-data-dir={user_data_dir}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            preexec_fn=child_fds, close_fds=False,
        )
        os.close(cmd_r)
        os.close(out_w)
        self._next = 0
        self._replies: dict[int, dict] = {}
        self._events: queue.Queue = queue.Queue()
        self.events: list[dict] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self._stderr: list[bytes] = []
        threading.Thread(target=lambda: self._stderr.extend(self.proc.stderr), daemon=True).start()

    def _read(self):
        buf = b""
        while True:
            chunk = os.read(self._out_r, 1 << 16)
            if not chunk:
                break
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                msg = json.loads(raw)
                with self._cond:
                    if "id" in msg:
                        self._replies[msg["id"]] = msg
                    else:
                        self.events.append(msg)
                    self._cond.notify_all()

    def send(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 30.0) -> dict:
        self._next += 1
        mid = self._next
        msg = {"id": mid, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        with self._cond:
            while mid not in self._replies:
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    raise TimeoutError(f"no reply to {method} (chromium stderr: {self.stderr()[-2000:]})")
                self._cond.wait(min(left, 0.5))
            reply = self._replies.pop(mid)
        if "error" in reply:
            raise RuntimeError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    def wait_event(self, method: str, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for ev in self.events:
                    if ev.get("method") == method:
                        return ev
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"no {method} event")
                self._cond.wait(min(left, 0.5))

    def stderr(self) -> str:
        return b"".join(self._stderr).decode(errors="replace")

    def close(self):
        try:
            self.send("Browser.close", timeout=5)
        except (TimeoutError, RuntimeError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._cmd_w)


def load_page(binary: str, html_file: Path, tmp: Path, screenshot: Path) -> dict:
    """Open ``html_file`` in headless Chromium; return status text, DOM checks, console problems, requests."""
    dt = DevTools(binary, tmp / "profile")
    try:
        target = dt.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = dt.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Page", "Network"):
            dt.send(f"{domain}.enable", session=session)
        dt.send("Emulation.setDeviceMetricsOverride", {"width": 1280, "height": 1800, "deviceScaleFactor": 1, "mobile": False}, session=session)
        dt.send("Page.navigate", {"url": html_file.resolve().as_uri()}, session=session)
        dt.wait_event("Page.loadEventFired")

        def evaluate(expr):
            res = dt.send("Runtime.evaluate", {"expression": expr, "returnByValue": True}, session=session)
            if "exceptionDetails" in res:
                raise RuntimeError(f"{expr}: {res['exceptionDetails']}")
            return res["result"].get("value")

        deadline = time.monotonic() + 20
        status = evaluate("document.getElementById('status').textContent")
        while status.startswith("rendering") and time.monotonic() < deadline:
            time.sleep(0.1)
            status = evaluate("document.getElementById('status').textContent")
        checks = evaluate(
            """(function () {
              var out = {curves: document.querySelectorAll('svg path.curve').length,
                         charts: document.querySelectorAll('.chart').length, viewer: null};
              var c = document.querySelector('#viewer canvas');
              if (c) {
                var ctx = c.getContext('2d'), d = ctx.getImageData(0, 0, c.width, c.height).data, bg = 0, ink = 0;
                for (var i = 0; i < d.length; i += 4) { if (d[i] === 251 && d[i+1] === 252 && d[i+2] === 253) bg++; else ink++; }
                var label = document.querySelector('#viewer .controls div').textContent;
                var camera = function () { return {view: c.getAttribute('data-view'), towards: c.getAttribute('data-towards')}; };
                out.camera_start = camera();
                var s = document.getElementById('frame-slider'); s.value = 0; s.dispatchEvent(new Event('input'));
                out.viewer = {ink: ink, background: bg, ready: c.getAttribute('data-ready'), label_last: label,
                              legend: document.querySelector('#viewer .legend').textContent,
                              label_first: document.querySelector('#viewer .controls div').textContent};
                c.dispatchEvent(new PointerEvent('pointerdown', {clientX: 100, clientY: 100, pointerId: 1}));
                c.dispatchEvent(new PointerEvent('pointermove', {clientX: 160, clientY: 130, pointerId: 1}));
                c.dispatchEvent(new PointerEvent('pointerup', {clientX: 160, clientY: 130, pointerId: 1}));
                out.camera_dragged = camera();
                var preset = document.getElementById('view-preset');
                out.presets = {shown: preset.style.display !== 'none'};
                ['x', 'y', 'z', 'bend'].forEach(function (k) {
                  preset.value = k; preset.dispatchEvent(new Event('change')); out.presets[k] = camera().towards;
                });
              }
              var hit = document.querySelector('.chart svg rect[fill="transparent"]');
              if (hit) {
                var r = hit.getBoundingClientRect();
                hit.dispatchEvent(new MouseEvent('mousemove', {clientX: r.left + r.width / 2, clientY: r.top + r.height / 2, bubbles: true}));
                out.tooltip = document.querySelector('.chart .tip').textContent;
              }
              return out;
            })()"""
        )
        status = evaluate("document.getElementById('status').textContent")  # after the interactions
        shot = dt.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True}, session=session)
        screenshot.write_bytes(base64.b64decode(shot["data"]))
        time.sleep(0.2)  # let late console events arrive
        problems = []
        requests = []
        for ev in dt.events:
            m, p = ev.get("method"), ev.get("params", {})
            if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert", "warning"):
                problems.append(f"console.{p['type']}: " + " ".join(str(a.get("value", a.get("description"))) for a in p.get("args", [])))
            elif m == "Runtime.exceptionThrown":
                d = p.get("exceptionDetails", {})
                problems.append(f"exception: {d.get('text')} {d.get('exception', {}).get('description', '')}")
            elif m == "Log.entryAdded" and p.get("entry", {}).get("level") in ("error", "warning"):
                problems.append(f"log {p['entry']['level']}: {p['entry'].get('text')} ({p['entry'].get('url', '')})")
            elif m == "Network.requestWillBeSent":
                requests.append(p["request"]["url"])
        return {"status": status, "checks": checks, "problems": problems, "requests": requests}
    finally:
        dt.close()


@pytest.fixture(scope="module")
def chromium():
    binary = find_chromium()
    if binary is None:
        pytest.skip("Chromium not installed (command -v chromium failed); .ci/run installs Debian's chromium with apt-get, "
                    "or run: apt-get update && apt-get install -y chromium")
    return binary


def _artifact(tmp_path: Path, name: str) -> Path:
    """Screenshots go to $MAGSORO_TEST_ARTIFACTS when set (kept for a look), else to the test's tmp folder."""
    folder = Path(os.environ.get("MAGSORO_TEST_ARTIFACTS", tmp_path))
    folder.mkdir(parents=True, exist_ok=True)
    return folder / name


def _assert_offline(result: dict) -> None:
    external = [u for u in result["requests"] if not u.startswith(("file:", "data:", "about:"))]
    assert not external, f"the report fetched from the network: {external}"


def test_run_report_renders_in_chromium(chromium, tmp_path):
    from magsoro.viz import build_report

    run_dir = make_run_dir(tmp_path / "run")
    page = build_report(run_dir, tmp_path / "run_report.html")
    shot = _artifact(tmp_path, "report_run.png")
    res = load_page(chromium, page, tmp_path, shot)
    assert res["problems"] == [], res["problems"]
    data = json.loads(page.read_text().split('id="report-data">', 1)[1].split("</script>", 1)[0])
    expected = data["expected_curves"]
    assert expected == 2  # tip_x and tip_y
    assert res["status"] == f"ok: {expected} curves, viewer ready", res["status"]
    assert res["checks"]["curves"] == expected
    viewer = res["checks"]["viewer"]
    assert viewer["ready"] == "1" and viewer["legend"] == "beam"
    assert viewer["ink"] > 200, "the particle canvas is blank"
    assert viewer["label_last"] != viewer["label_first"] and viewer["label_first"].startswith("t = 0 s")
    assert "tip" in res["checks"]["tooltip"] and "time (s)" in res["checks"]["tooltip"]
    # a 2D run: seen down z, no view presets
    assert res["checks"]["camera_start"] == {"view": "bend", "towards": "0,0,1"} and res["checks"]["presets"]["shown"] is False
    _assert_offline(res)
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 10_000


def test_report_of_a_bend_in_xz_starts_looking_along_y(chromium, tmp_path):
    """A 3D strip bending in the x-z plane is invisible down z: the viewer starts looking along y (the bend plane's
    normal), dragging turns it, and the presets look down x, y and z."""
    from magsoro.viz import build_report
    from test_report import make_bending_run_dir

    page = build_report(make_bending_run_dir(tmp_path / "run"), tmp_path / "bend_report.html")
    res = load_page(chromium, page, tmp_path, _artifact(tmp_path, "report_bend.png"))
    assert res["problems"] == [], res["problems"]
    assert res["status"] == "ok: 0 curves, viewer ready", res["status"]
    checks = res["checks"]
    assert checks["camera_start"] == {"view": "bend", "towards": "0,-1,0"}, checks["camera_start"]
    assert checks["camera_dragged"]["towards"] != "0,-1,0"  # a drag orbits
    assert checks["presets"] == {"shown": True, "x": "1,0,0", "y": "0,-1,0", "z": "0,0,1", "bend": "0,-1,0"}
    _assert_offline(res)


def test_sweep_report_renders_in_chromium(chromium, tmp_path):
    from magsoro.viz import build_report

    sweep_dir = make_sweep_dir(tmp_path / "sweep")
    page = build_report(sweep_dir, tmp_path / "sweep_report.html")
    shot = _artifact(tmp_path, "report_sweep.png")
    res = load_page(chromium, page, tmp_path, shot)
    assert res["problems"] == [], res["problems"]
    data = json.loads(page.read_text().split('id="report-data">', 1)[1].split("</script>", 1)[0])
    expected = data["expected_curves"]
    # final tip_x, tip_y vs the field (one series each, the failed run left out) + the two overlays of 2 runs
    assert expected == 2 + 2 * 2
    assert res["status"] == f"ok: {expected} curves, no particle viewer", res["status"]
    assert res["checks"]["curves"] == expected and res["checks"]["viewer"] is None
    _assert_offline(res)
    assert shot.stat().st_size > 10_000


def test_broken_page_is_reported(chromium, tmp_path):
    """The checks above can fail: a console error is collected, and a script error turns #status red."""
    from magsoro.viz import build_report

    run_dir = make_run_dir(tmp_path / "run")
    page = build_report(run_dir, tmp_path / "broken.html")
    text = page.read_text().replace("function main() {", "function main() { console.error('deliberate'); undefinedFunctionCall();", 1)
    page.write_text(text)
    res = load_page(chromium, page, tmp_path, tmp_path / "broken.png")
    assert res["status"].startswith("error:") and "undefinedFunctionCall" in res["status"], res["status"]
    assert any("deliberate" in p for p in res["problems"]), res["problems"]
