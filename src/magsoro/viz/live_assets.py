"""The page of ``magsoro live`` (HTML, CSS and JavaScript in one string, so it installs with the package).

No library and no network: a <canvas> point renderer (orthographic, mouse orbit, pan and zoom, points sorted
by depth in 3D) and a control panel that polls ``/state`` and ``/frame`` (:mod:`magsoro.viz.live`). The page
writes its own health into ``#status`` ("running", "paused", "failed", "server stopped", or "error: ..." when
its script fails) and the server's answers to refused input or a failed step into ``#message``.
"""

CSS = r"""
:root { --fg:#1d2329; --muted:#5b6670; --line:#d8dee4; --panel:#f6f8fa; --ok:#1a7f37; --bad:#cf222e; --warn:#9a6700; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg); margin: 0; padding: 12px 18px; }
header { display: flex; align-items: baseline; gap: 14px; flex-wrap: wrap; }
h1 { font-size: 20px; margin: 0 0 8px; } h1 small { color: var(--muted); font-weight: 400; }
h2 { font-size: 14px; margin: 0 0 6px; }
#status { font-family: ui-monospace, monospace; font-size: 12px; padding: 2px 8px; border-radius: 4px; background: var(--panel); }
#status.running { color: var(--ok); } #status.paused, #status.starting { color: var(--warn); }
#status.failed, #status.stopped { color: var(--bad); } #status.error { color: #fff; background: var(--bad); }
main { display: flex; gap: 16px; align-items: flex-start; flex-wrap: wrap; }
#view-wrap { flex: 1 1 640px; min-width: 320px; }
#view { width: 100%; border: 1px solid var(--line); border-radius: 6px; background: #fbfcfd; cursor: grab; touch-action: none; display: block; }
.hint { color: var(--muted); font-size: 12px; margin-top: 4px; }
aside { flex: 0 0 330px; display: flex; flex-direction: column; gap: 12px; }
section { border: 1px solid var(--line); border-radius: 6px; padding: 10px; background: #fff; }
#time { font: 600 22px/1.2 ui-monospace, monospace; }
#readout { font-family: ui-monospace, monospace; font-size: 12px; color: var(--muted); margin: 4px 0 8px; white-space: pre; }
button { font: inherit; padding: 3px 14px; border: 1px solid var(--line); border-radius: 5px; background: var(--panel); cursor: pointer; }
button:hover { background: #eaeef2; }
.row { display: grid; grid-template-columns: 78px 1fr 74px; gap: 6px; align-items: center; margin: 4px 0; }
.row output { font-family: ui-monospace, monospace; font-size: 12px; text-align: right; }
.row input[type=range] { width: 100%; }
.applied { font-family: ui-monospace, monospace; font-size: 12px; color: var(--muted); margin-top: 6px; }
#message { font-size: 13px; padding: 6px 8px; border-radius: 5px; display: none; white-space: pre-wrap; word-break: break-word; }
#message.refused { display: block; background: #fff8c5; border: 1px solid #d4a72c; }
#message.failed { display: block; background: #ffebe9; border: 1px solid var(--bad); color: var(--bad); }
.legend span { display: inline-block; margin-right: 10px; font-size: 12px; }
.legend i { display: inline-block; width: 10px; height: 10px; border-radius: 5px; margin-right: 4px; vertical-align: middle; }
"""

JS = r"""
(function () {
  "use strict";
  var $ = function (id) { return document.getElementById(id); };
  var statusEl = $("status"), messageEl = $("message");
  var problems = [];
  window.liveProblems = problems;
  function setStatus(text, cls) { if (problems.length) return; statusEl.textContent = text; statusEl.className = cls; }
  function fail(msg) {
    problems.push(String(msg));
    statusEl.textContent = "error: " + problems.join("; ");
    statusEl.className = "error";
  }
  window.addEventListener("error", function (e) { fail(e.message || "script error"); });
  window.addEventListener("unhandledrejection", function (e) { fail("unhandled rejection: " + (e.reason && e.reason.message || e.reason)); });

  var refusal = "", simError = "";
  function showMessage() {
    var text = simError ? "simulation stopped: " + simError + "\nPress Reset to start again." : refusal;
    messageEl.textContent = text;
    messageEl.className = simError ? "failed" : (refusal ? "refused" : "");
  }

  // ------------------------------------------------------------------ formatting
  function si(v, unit) {
    if (!isFinite(v)) return String(v) + " " + unit;
    var a = Math.abs(v);
    if (a === 0) return "0 " + unit;
    if (a >= 1) return v.toPrecision(4).replace(/\.?0+$/, "") + " " + unit;
    if (a >= 1e-3) return (v * 1e3).toPrecision(4).replace(/\.?0+$/, "") + " m" + unit;
    if (a >= 1e-6) return (v * 1e6).toPrecision(4).replace(/\.?0+$/, "") + " \u00b5" + unit;
    return v.toExponential(3) + " " + unit;
  }
  function num(v, d) { return Number(v).toFixed(d); }

  // ------------------------------------------------------------------ server
  function getJSON(path) {
    return fetch(path, {cache: "no-store"}).then(function (r) {
      return r.json().then(function (d) { if (!r.ok) throw new Error(d.error || r.statusText); return d; });
    });
  }
  function post(path, body) {
    return fetch(path, {method: "POST", headers: {"Content-Type": "application/json"}, body: JSON.stringify(body)})
      .then(function (r) {
        return r.json().catch(function () { return {error: r.status + " " + r.statusText}; })
          .then(function (d) { return {ok: r.ok, data: d}; });
      });
  }
  function answer(res) {
    if (res.ok) {
      refusal = "";
      if (res.data.controls) $("follow").checked = res.data.controls.follow_scene;  // the server's word, not a stale poll's
    } else { refusal = "refused: " + (res.data.error || "unknown error"); }
    showMessage();
    return res;
  }

  // controls: changes merge while a request is in flight; the latest value wins
  var pending = null, inflight = null;
  function merge(a, b) {
    var out = {}, k;
    for (k in a) out[k] = a[k];
    for (k in b) out[k] = (b[k] && typeof b[k] === "object" && out[k] && typeof out[k] === "object") ? merge(out[k], b[k]) : b[k];
    return out;
  }
  function sendControl(change) {
    pending = pending ? merge(pending, change) : change;
    if (!inflight) flush();
    return inflight;
  }
  function flush() {
    var body = pending; pending = null;
    inflight = post("/control", body).then(answer, function (e) { refusal = "server unreachable: " + e.message; showMessage(); })
      .then(function (res) { inflight = null; if (pending) return flush(); return res; });
    return inflight;
  }
  // for scripts and tests: send a control as is and resolve once its answer is shown
  window.liveControl = function (payload) { return post("/control", payload).then(answer); };

  // ------------------------------------------------------------------ view
  var canvas = $("view"), ctx = canvas.getContext("2d");
  var info = null, positions = null, engineB = [0, 0, 0];
  var cam = {yaw: 0, pitch: 0, zoom: 1, panX: 0, panY: 0}, center = [0, 0, 0], extent = 1;
  var COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
  var drawQueued = false, SHADES = 8, shadeCache = {};
  function shade(hex, level) {  // level SHADES - 1: the colour itself; 0: mixed halfway with the background
    var key = hex + level;
    if (!shadeCache[key]) {
      var f = 0.55 * (1 - level / (SHADES - 1)), c = [1, 3, 5].map(function (i) { return parseInt(hex.substr(i, 2), 16); });
      shadeCache[key] = "rgb(" + c.map(function (v) { return Math.round(v + (251 - v) * f); }).join(",") + ")";
    }
    return shadeCache[key];
  }

  function fit() {
    if (!positions || !positions.length) return;
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (var i = 0; i < positions.length; i += 3) {
      for (var a = 0; a < 3; a++) { var v = positions[i + a]; if (v < lo[a]) lo[a] = v; if (v > hi[a]) hi[a] = v; }
    }
    for (var b = 0; b < 3; b++) center[b] = 0.5 * (lo[b] + hi[b]);
    var body = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], info ? 4 * info.dx : 1e-3);
    extent = 3 * body;  // room to move; the whole domain when it is smaller than that
    if (info) {
      var dlo = info.domain_lo, dhi = info.domain_hi, dom = 0;
      for (var d = 0; d < info.dim; d++) dom = Math.max(dom, dhi[d] - dlo[d]);
      if (dom < extent) {
        extent = dom;
        for (var e = 0; e < info.dim; e++) center[e] = 0.5 * (dlo[e] + dhi[e]);
      }
    }
    cam.zoom = 1; cam.panX = 0; cam.panY = 0;
  }
  function resize() {
    var w = Math.max(320, Math.round(canvas.parentElement.clientWidth));
    var h = Math.round(Math.min(720, Math.max(300, w * 0.66)));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    queueDraw();
  }
  function queueDraw() { if (!drawQueued) { drawQueued = true; requestAnimationFrame(function () { drawQueued = false; draw(); }); } }

  function projector() {
    var cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw), cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch);
    var scale = 0.9 * Math.min(canvas.width, canvas.height) / extent * cam.zoom;
    var ox = canvas.width / 2 + cam.panX, oy = canvas.height / 2 + cam.panY;
    return {
      scale: scale,
      dir: function (x, y, z) {  // rotate only: for directions (field arrow, axes)
        var x1 = cy * x + sy * z, z1 = -sy * x + cy * z;
        return [x1, cp * y - sp * z1, sp * y + cp * z1];
      },
      at: function (x, y, z) {
        var d = this.dir(x - center[0], y - center[1], z - center[2]);
        return [ox + d[0] * scale, oy - d[1] * scale, d[2]];
      }
    };
  }

  function drawDomain(P) {
    if (!info) return;
    var lo = info.domain_lo.slice(), hi = info.domain_hi.slice();
    if (info.dim === 2) { lo.push(0); hi.push(0); }
    var c = [];
    for (var k = 0; k < 8; k++) c.push(P.at(k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]));
    var edges = [[0, 1], [2, 3], [0, 2], [1, 3], [4, 5], [6, 7], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];
    ctx.strokeStyle = "#c9d1d9"; ctx.lineWidth = 1; ctx.setLineDash([4, 4]);
    ctx.beginPath();
    edges.forEach(function (e) { ctx.moveTo(c[e[0]][0], c[e[0]][1]); ctx.lineTo(c[e[1]][0], c[e[1]][1]); });
    ctx.stroke(); ctx.setLineDash([]);
  }

  function drawGizmo(P) {
    var ox = 46, oy = canvas.height - 46, L = 30;
    var axes = [[1, 0, 0, "#d62728", "x"], [0, 1, 0, "#2ca02c", "y"], [0, 0, 1, "#1f77b4", "z"]];
    ctx.lineWidth = 2; ctx.font = "11px system-ui, sans-serif";
    axes.forEach(function (a) {
      var d = P.dir(a[0], a[1], a[2]);
      ctx.strokeStyle = a[3]; ctx.fillStyle = a[3];
      ctx.beginPath(); ctx.moveTo(ox, oy); ctx.lineTo(ox + d[0] * L, oy - d[1] * L); ctx.stroke();
      ctx.fillText(a[4], ox + d[0] * (L + 8) - 3, oy - d[1] * (L + 8) + 4);
    });
    var mag = Math.hypot(engineB[0], engineB[1], engineB[2]);
    if (mag > 0 && info) {
      var d = P.dir(engineB[0] / mag, engineB[1] / mag, engineB[2] / mag);
      var len = 20 + 60 * Math.min(1, mag / info.limits.magnitude[1]);
      var bx = canvas.width - 90, by = canvas.height - 80, ex = bx + d[0] * len * 0.5, ey = by - d[1] * len * 0.5;
      var sx = bx - d[0] * len * 0.5, sy = by + d[1] * len * 0.5, ang = Math.atan2(ey - sy, ex - sx);
      ctx.strokeStyle = "#b0007a"; ctx.fillStyle = "#b0007a"; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.moveTo(sx, sy); ctx.lineTo(ex, ey); ctx.stroke();
      ctx.beginPath(); ctx.moveTo(ex, ey);
      ctx.lineTo(ex - 10 * Math.cos(ang - 0.4), ey - 10 * Math.sin(ang - 0.4));
      ctx.lineTo(ex - 10 * Math.cos(ang + 0.4), ey - 10 * Math.sin(ang + 0.4)); ctx.closePath(); ctx.fill();
      ctx.font = "12px ui-monospace, monospace";
      ctx.fillText("B " + si(mag, "T"), canvas.width - 150, canvas.height - 14);
    }
  }

  function draw() {
    ctx.fillStyle = "#fbfcfd"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    var P = projector();
    drawDomain(P);
    if (positions && info) {
      var n = positions.length / 3, sx = new Float32Array(n), sy = new Float32Array(n), depth = new Float32Array(n);
      for (var i = 0; i < n; i++) {
        var q = P.at(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
        sx[i] = q[0]; sy[i] = q[1]; depth[i] = q[2];
      }
      var order = new Uint32Array(n), dmin = Infinity, dmax = -Infinity;
      for (var j = 0; j < n; j++) { order[j] = j; if (depth[j] < dmin) dmin = depth[j]; if (depth[j] > dmax) dmax = depth[j]; }
      var shaded = info.dim === 3 && dmax > dmin;
      if (shaded) order.sort(function (a, b) { return depth[a] - depth[b]; });
      var r = Math.max(1.5, Math.min(8, info.dx * P.scale * (info.dim === 3 ? 0.9 : 0.75)));
      var h = r / 2, last = "";
      for (var k = 0; k < n; k++) {
        var p = order[k];
        var level = shaded ? Math.round((SHADES - 1) * (depth[p] - dmin) / (dmax - dmin)) : SHADES - 1;  // far: paler
        var col = info.clamped[p] ? shade("#3d444d", level) : shade(COLORS[info.body[p] % COLORS.length], level);
        if (col !== last) { ctx.fillStyle = col; last = col; }
        ctx.fillRect(sx[p] - h, sy[p] - h, r, r);
      }
      canvas.setAttribute("data-points", String(n));
    }
    drawGizmo(P);
  }

  // mouse: drag orbits, shift-drag or right-drag pans, wheel zooms, double-click refits
  var drag = null;
  canvas.addEventListener("pointerdown", function (e) {
    drag = {x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2};
    if (canvas.setPointerCapture && e.pointerId !== undefined) { try { canvas.setPointerCapture(e.pointerId); } catch (err) { /* synthetic pointer */ } }
    canvas.style.cursor = "grabbing";
  });
  canvas.addEventListener("pointermove", function (e) {
    if (!drag) return;
    var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) { cam.panX += dx; cam.panY += dy; }
    else { cam.yaw += dx * 0.01; cam.pitch = Math.max(-1.55, Math.min(1.55, cam.pitch + dy * 0.01)); }
    queueDraw();
  });
  function endDrag() { drag = null; canvas.style.cursor = "grab"; }
  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  canvas.addEventListener("contextmenu", function (e) { e.preventDefault(); });
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    cam.zoom = Math.max(0.05, Math.min(50, cam.zoom * Math.exp(-e.deltaY * 0.0015)));
    queueDraw();
  }, {passive: false});
  canvas.addEventListener("dblclick", function () { cam.yaw = 0; cam.pitch = 0; fit(); queueDraw(); });
  window.addEventListener("resize", resize);

  // ------------------------------------------------------------------ controls
  var sliders = {};
  function row(parent, id, label, min, max, step, value, fmt) {
    var div = document.createElement("div"); div.className = "row";
    var lab = document.createElement("label"); lab.htmlFor = id; lab.textContent = label;
    var inp = document.createElement("input"); inp.type = "range"; inp.id = id;
    inp.min = min; inp.max = max; inp.step = step; inp.value = value;
    var out = document.createElement("output"); out.id = id + "-out";
    div.appendChild(lab); div.appendChild(inp); div.appendChild(out); parent.appendChild(div);
    var s = {input: inp, out: out, fmt: fmt, show: function () { out.textContent = fmt(Number(inp.value)); }};
    s.show(); sliders[id] = s;
    return s;
  }

  function buildControls(st) {
    var c = st.controls, lim = info.limits, fieldBox = $("field-rows");
    var maxmT = lim.magnitude[1] * 1e3;
    row(fieldBox, "magnitude", "|B|", 0, maxmT, maxmT / 1000, c.magnitude * 1e3, function (v) { return num(v, 2) + " mT"; });
    row(fieldBox, "azimuth", "azimuth", -180, 180, 1, c.azimuth, function (v) { return num(v, 0) + "\u00b0"; });
    if (info.dim === 3) row(fieldBox, "elevation", "elevation", -90, 90, 1, c.elevation, function (v) { return num(v, 0) + "\u00b0"; });
    ["magnitude", "azimuth", "elevation"].forEach(function (k) {
      if (!sliders[k]) return;
      sliders[k].input.addEventListener("input", function () {
        sliders[k].show();
        $("follow").checked = false;
        var f = {};
        f[k] = k === "magnitude" ? Number(sliders[k].input.value) / 1e3 : Number(sliders[k].input.value);
        sendControl({field: f});
      });
    });
    $("follow").checked = c.follow_scene;
    $("follow").addEventListener("change", function () { sendControl({field: {follow_scene: $("follow").checked}}); });
    $("follow-note").textContent = info.has_scene_uniform ? "" : "(the scene has no uniform field: following it means none)";
    var gainBox = $("gain-rows");
    if (!info.sources.length) {
      $("gain-panel").style.display = "none";
    }
    info.sources.forEach(function (name) {
      var s = row(gainBox, "gain-" + name, name, lim.gain[0], lim.gain[1], 0.01, c.gains[name], function (v) { return "\u00d7 " + num(v, 2); });
      s.input.addEventListener("input", function () {
        s.show();
        var g = {}; g[name] = Number(s.input.value);
        sendControl({gains: g});
      });
    });
    var legend = $("legend");
    info.bodies.forEach(function (b, i) {
      var span = document.createElement("span"), dot = document.createElement("i");
      dot.style.background = COLORS[i % COLORS.length];
      span.appendChild(dot); span.appendChild(document.createTextNode(b)); legend.appendChild(span);
    });
    if (info.clamped.some(function (v) { return v; })) {
      var span = document.createElement("span"), dot = document.createElement("i");
      dot.style.background = "#3d444d"; span.appendChild(dot); span.appendChild(document.createTextNode("clamped")); legend.appendChild(span);
    }
  }

  var paused = false;
  $("pause").addEventListener("click", function () {
    post("/command", {action: paused ? "resume" : "pause"}).then(answer);
  });
  $("reset").addEventListener("click", function () { post("/command", {action: "reset"}).then(answer); });
  window.addEventListener("pagehide", function () { if (navigator.sendBeacon) navigator.sendBeacon("/bye", ""); });

  function showState(st) {
    paused = st.paused;
    $("pause").textContent = st.paused ? "Resume" : "Pause";
    $("time").textContent = "t = " + si(st.time, "s");
    var speed = st.speed > 0 ? si(st.speed, "s") + "/s" + (st.speed < 1 ? " (1/" + (1 / st.speed).toPrecision(3) + " real time)" : " (" + st.speed.toPrecision(3) + "x real time)") : "-";
    $("readout").textContent = "speed  " + speed + "\nsteps  " + st.steps + " (" + Math.round(st.steps_per_s) + " steps/s)\ndt     " + si(st.dt, "s");
    engineB = st.engine_field;
    var mag = Math.hypot(engineB[0], engineB[1], engineB[2]);
    $("applied").textContent = "engine: B = (" + engineB.map(function (v) { return num(v * 1e3, 3); }).join(", ") + ") mT, |B| = " + num(mag * 1e3, 3) + " mT" + (st.applied.follow_scene ? ", the scene's" : ", set here");
    simError = st.error || "";
    showMessage();
    var phase = st.stopping ? "stopped" : st.phase;
    var text = {starting: "starting (the first steps compile the kernels)", running: "running", paused: "paused", failed: "failed", resetting: "resetting", stopped: "server stopping: " + st.stopping}[phase] || phase;
    setStatus(text, phase);
  }

  var lastFrame = -1, failures = 0;
  function poll() {
    getJSON("/state").then(function (st) {
      failures = 0;
      showState(st);
      if (st.frame === lastFrame) return;
      return fetch("/frame", {cache: "no-store"}).then(function (r) {
        var id = Number(r.headers.get("X-Frame"));
        return r.arrayBuffer().then(function (buf) {
          var first = positions === null;
          positions = new Float32Array(buf); lastFrame = id;
          if (first) fit();
          queueDraw();
        });
      });
    }).then(function () { setTimeout(poll, 120); }, function (e) {
      failures += 1;
      if (failures >= 3) {
        setStatus("server stopped", "stopped");
        simError = ""; refusal = "The live server has stopped (" + e.message + "): run magsoro live again.";
        showMessage();
        return;
      }
      setTimeout(poll, 500);
    });
  }
  window.liveView = function () {
    var n = positions ? positions.length / 3 : 0, sy = 0;
    for (var i = 0; i < n; i++) sy += positions[3 * i + 1];
    return {frame: lastFrame, points: n, mean_y: n ? sy / n : null};
  };

  getJSON("/info").then(function (inf) {
    info = inf;
    $("scene").textContent = inf.scene + " \u00b7 " + inf.dim + "D \u00b7 " + inf.particles + " particles" + (inf.shown < inf.particles ? " (" + inf.shown + " shown)" : "");
    document.title = "magsoro live: " + inf.scene;
    return getJSON("/state");
  }).then(function (st) {
    buildControls(st);
    showState(st);
    resize();
    poll();
  }).catch(function (e) { fail("could not start: " + e.message); });
})();
"""

PAGE = (
    """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>magsoro live</title>
<link rel="icon" href="data:,">
<style>"""
    + CSS
    + """</style>
</head>
<body>
<header><h1>magsoro live <small id="scene"></small></h1><div id="status" class="starting">connecting</div></header>
<main>
  <div id="view-wrap">
    <canvas id="view" width="800" height="520"></canvas>
    <div class="hint">drag: orbit &middot; shift-drag or right-drag: pan &middot; wheel: zoom &middot; double-click: fit &middot; <span class="legend" id="legend"></span></div>
  </div>
  <aside>
    <section>
      <div id="time">t = 0 s</div>
      <div id="readout"></div>
      <button id="pause" type="button">Pause</button>
      <button id="reset" type="button">Reset</button>
    </section>
    <section id="field-panel">
      <h2>Uniform field</h2>
      <label><input type="checkbox" id="follow"> follow the scene's field</label> <small id="follow-note"></small>
      <div id="field-rows"></div>
      <div class="applied" id="applied"></div>
    </section>
    <section id="gain-panel">
      <h2>Field sources (strength)</h2>
      <div id="gain-rows"></div>
    </section>
    <div id="message" role="alert"></div>
  </aside>
</main>
<script>"""
    + JS
    + """</script>
</body>
</html>
"""
)
