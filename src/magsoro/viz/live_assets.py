"""The page of ``magsoro live`` (HTML, CSS and JavaScript in one string, so it installs with the package).

No library and no network: a <canvas> point renderer (orthographic, a camera that starts looking at the plane the
robot bends in, mouse orbit, pan and zoom, points sorted by depth in 3D), the colliders and the floor, the magnet
sources as markers, and a control panel that polls ``/state``, ``/frame`` and ``/probe`` (:mod:`magsoro.viz.live`).
The page writes its own health into ``#status`` ("running", "paused", "failed", "server stopped", or "error: ..."
when its script fails) and the server's answers to refused input or a failed step into ``#message``. What it drew
is left on the canvas as data attributes (``data-points``, ``data-color``, ``data-colliders``, ``data-floor``,
``data-markers``) and on the probe plot (``data-samples``), for scripts and tests.
"""

CSS = r"""
:root { --fg:#1d2329; --muted:#5b6670; --line:#d8dee4; --panel:#f6f8fa; --ok:#1a7f37; --bad:#cf222e; --warn:#9a6700; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg); margin: 0; padding: 12px 18px; }
header { display: flex; align-items: baseline; gap: 14px; flex-wrap: wrap; }
h1 { font-size: 20px; margin: 0 0 8px; } h1 small { color: var(--muted); font-weight: 400; }
h2 { font-size: 14px; margin: 0 0 6px; } h3 { font-size: 12px; margin: 8px 0 2px; color: var(--muted); font-weight: 600; }
#status { font-family: ui-monospace, monospace; font-size: 12px; padding: 2px 8px; border-radius: 4px; background: var(--panel); }
#status.running { color: var(--ok); } #status.paused, #status.starting, #status.stepping { color: var(--warn); }
#status.failed, #status.stopped { color: var(--bad); } #status.error { color: #fff; background: var(--bad); }
main { display: flex; gap: 16px; align-items: flex-start; flex-wrap: wrap; }
#view-wrap { flex: 1 1 640px; min-width: 320px; }
#view { width: 100%; border: 1px solid var(--line); border-radius: 6px; background: #fbfcfd; cursor: grab; touch-action: none; display: block; }
.hint { color: var(--muted); font-size: 12px; margin-top: 4px; }
.toolbar { display: flex; gap: 12px; align-items: center; flex-wrap: wrap; margin: 6px 0; font-size: 13px; }
#colorbar { display: none; align-items: center; gap: 6px; font-size: 12px; font-family: ui-monospace, monospace; }
#colorbar i { display: inline-block; width: 140px; height: 10px; border-radius: 2px; }
aside { flex: 0 0 350px; display: flex; flex-direction: column; gap: 12px; }
section { border: 1px solid var(--line); border-radius: 6px; padding: 10px; background: #fff; }
#time { font: 600 22px/1.2 ui-monospace, monospace; }
#readout { font-family: ui-monospace, monospace; font-size: 12px; color: var(--muted); margin: 4px 0 8px; white-space: pre; }
button { font: inherit; padding: 3px 12px; border: 1px solid var(--line); border-radius: 5px; background: var(--panel); cursor: pointer; }
button:hover { background: #eaeef2; } button:disabled { color: #9aa4ad; cursor: default; }
input[type=number] { width: 78px; font: inherit; } input[type=text] { width: 150px; font: inherit; }
select { font: inherit; }
.row { display: grid; grid-template-columns: 74px 1fr 82px; gap: 6px; align-items: center; margin: 3px 0; }
.row output { font-family: ui-monospace, monospace; font-size: 12px; text-align: right; }
.row input[type=range] { width: 100%; }
details { margin: 4px 0 6px; } summary { cursor: pointer; font-size: 12px; color: var(--muted); }
.applied, .note { font-family: ui-monospace, monospace; font-size: 12px; color: var(--muted); margin-top: 6px; white-space: pre-wrap; }
#probe-plot { width: 100%; height: 150px; border: 1px solid var(--line); border-radius: 4px; display: block; margin-top: 6px; }
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
  var DISPLAY = {m: [1e3, "mm"], T: [1e3, "mT"], N: [1e3, "mN"]};  // probe units as plotted

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
      if (res.data.controls) {
        $("follow").checked = res.data.controls.follow_scene;  // the server's word, not a stale poll's
        syncSliders(res.data.controls);
      }
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
  function kind(f) {
    return "magnitude" in f || "azimuth" in f || "elevation" in f ? "polar" : ("Bx" in f || "By" in f || "Bz" in f ? "components" : "");
  }
  function sendControl(change) {
    var a = pending && pending.field ? kind(pending.field) : "", b = change.field ? kind(change.field) : "";
    if (a && b && a !== b) {
      delete pending.field;  // components and magnitude/direction do not mix in one request: the latest edit wins
    }
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
  // for scripts and tests: send a control or command as is and resolve once its answer is shown
  window.liveControl = function (payload) { return post("/control", payload).then(answer); };
  window.liveCommand = function (payload) { return post("/command", payload).then(answer); };

  // ------------------------------------------------------------------ colours
  var COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
  var HELD = "#3d444d", NOVALUE = "#b4bac0", FLOOR = "#d5dbe1", COLLIDER = "#708090", MAGNET = "#6a3d9a";
  var MAPS = {
    viridis: ["#440154", "#482878", "#3e4989", "#31688e", "#26828e", "#1f9e89", "#35b779", "#6ece58", "#b5de2b", "#fde725"],
    magma: ["#000004", "#180f3d", "#440f76", "#721f81", "#9e2f7f", "#cd4071", "#f1605d", "#fd9668", "#feca8d", "#fcfdbf"],
    plasma: ["#0d0887", "#46039f", "#7201a8", "#9c179e", "#bd3786", "#d8576b", "#ed7953", "#fb9f3a", "#fdca26", "#f0f921"],
    coolwarm: ["#3b4cc0", "#6788ee", "#9abbff", "#c9d7f0", "#edd1c2", "#f7a889", "#e26952", "#b40426"]
  };
  var LUT_N = 48, luts = {};
  function hexRGB(h) { return [1, 3, 5].map(function (i) { return parseInt(h.substr(i, 2), 16); }); }
  function lut(name) {
    if (luts[name]) return luts[name];
    var stops = MAPS[name].map(hexRGB), out = [];
    for (var i = 0; i < LUT_N; i++) {
      var f = i / (LUT_N - 1) * (stops.length - 1), k = Math.min(stops.length - 2, Math.floor(f)), w = f - k;
      out.push("#" + [0, 1, 2].map(function (c) { var v = Math.round(stops[k][c] * (1 - w) + stops[k + 1][c] * w); return (v < 16 ? "0" : "") + v.toString(16); }).join(""));
    }
    luts[name] = out;
    return out;
  }
  var SHADES = 8, shadeCache = {};
  function shade(hex, level) {  // level SHADES - 1: the colour itself; 0: mixed halfway with the background
    var key = hex + level;
    if (!shadeCache[key]) {
      var f = 0.55 * (1 - level / (SHADES - 1)), c = hexRGB(hex);
      shadeCache[key] = "rgb(" + c.map(function (v) { return Math.round(v + (251 - v) * f); }).join(",") + ")";
    }
    return shadeCache[key];
  }
  // what each colour mode shows, as magsoro render --color
  var MODES = {
    part: {label: "part"},
    speed: {label: "speed", unit: "mm/s", map: "viridis"},
    strain: {label: "equivalent strain", unit: "%", map: "magma"},
    magnetisation: {label: "magnetisation turned", unit: "\u00b0", map: "plasma", map2d: "coolwarm"}
  };
  var colorTop = {};  // the largest value seen per mode: the scale only grows, so colours keep their meaning

  // ------------------------------------------------------------------ view
  var canvas = $("view"), ctx = canvas.getContext("2d");
  var info = null, positions = null, values = null, frameColor = "part", engineB = [0, 0, 0], lastTime = 0;
  var drawn = {markers: [], colliders: []};
  var cam = {M: [[1, 0, 0], [0, 1, 0], [0, 0, 1]], zoom: 1, panX: 0, panY: 0}, center = [0, 0, 0], extent = 1;
  var drawQueued = false;

  var PRESETS = {
    x: {right: [0, 1, 0], up: [0, 0, 1], towards: [1, 0, 0]},
    y: {right: [1, 0, 0], up: [0, 0, 1], towards: [0, -1, 0]},
    z: {right: [1, 0, 0], up: [0, 1, 0], towards: [0, 0, 1]}
  };
  function setCamera(name) {
    var v = name === "bend" || !PRESETS[name] ? info.view : PRESETS[name];
    cam.M = [v.right.slice(), v.up.slice(), v.towards.slice()];
  }
  function turn(axis, angle) {  // rotate the view about a screen axis (0: right, 1: up)
    var c = Math.cos(angle), s = Math.sin(angle), M = cam.M, a = axis === 1 ? [0, 2] : [2, 1], r0 = M[a[0]], r1 = M[a[1]];
    var n0 = [0, 1, 2].map(function (k) { return c * r0[k] + s * r1[k]; }), n1 = [0, 1, 2].map(function (k) { return -s * r0[k] + c * r1[k]; });
    M[a[0]] = n0; M[a[1]] = n1;
    // keep the rows orthonormal (Gram-Schmidt) against round-off over many drags
    var dot = function (p, q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; };
    var norm = function (p) { var l = Math.sqrt(dot(p, p)); return p.map(function (v) { return v / l; }); };
    M[0] = norm(M[0]);
    var d = dot(M[1], M[0]); M[1] = norm(M[1].map(function (v, k) { return v - d * M[0][k]; }));
    M[2] = [M[0][1] * M[1][2] - M[0][2] * M[1][1], M[0][2] * M[1][0] - M[0][0] * M[1][2], M[0][0] * M[1][1] - M[0][1] * M[1][0]];
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
    var M = cam.M, scale = 0.9 * Math.min(canvas.width, canvas.height) / extent * cam.zoom;
    var ox = canvas.width / 2 + cam.panX, oy = canvas.height / 2 + cam.panY;
    return {
      scale: scale,
      dir: function (x, y, z) {  // rotate only: for directions (field arrow, axes): screen right, up, towards the viewer
        return [M[0][0] * x + M[0][1] * y + M[0][2] * z, M[1][0] * x + M[1][1] * y + M[1][2] * z, M[2][0] * x + M[2][1] * y + M[2][2] * z];
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
    if (info.dim === 2) { lo.push(info.plane_z); hi.push(info.plane_z); }
    var c = [];
    for (var k = 0; k < 8; k++) c.push(P.at(k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]));
    var edges = [[0, 1], [2, 3], [0, 2], [1, 3], [4, 5], [6, 7], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];
    ctx.strokeStyle = "#c9d1d9"; ctx.lineWidth = 1; ctx.setLineDash([4, 4]);
    ctx.beginPath();
    edges.forEach(function (e) { ctx.moveTo(c[e[0]][0], c[e[0]][1]); ctx.lineTo(c[e[1]][0], c[e[1]][1]); });
    ctx.stroke(); ctx.setLineDash([]);
  }

  function drawColliders(P) {
    var shapes = 0, floor = 0;
    if (!info) return [0, 0];
    info.colliders.forEach(function (col, i) {
      var off = drawn.colliders[i] || [0, 0, 0], any = false;
      col.loops.forEach(function (loop) {
        if (loop.length < 2) return;
        var pts = loop.map(function (p) { return P.at(p[0] + off[0], p[1] + off[1], p[2] + off[2]); });
        ctx.beginPath(); ctx.moveTo(pts[0][0], pts[0][1]);
        for (var k = 1; k < pts.length; k++) ctx.lineTo(pts[k][0], pts[k][1]);
        if (loop.length > 2) ctx.closePath();
        if (col.fill && loop.length > 2) { ctx.fillStyle = FLOOR; ctx.fill(); }
        ctx.strokeStyle = COLLIDER; ctx.lineWidth = 1.5; ctx.stroke();
        any = true;
      });
      if (any) { shapes += 1; if (col.kind === "half_space") floor += 1; }
    });
    return [shapes, floor];
  }

  function arrow(x0, y0, x1, y1, colour, width) {
    var ang = Math.atan2(y1 - y0, x1 - x0);
    ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(x1, y1);
    ctx.lineTo(x1 - 9 * Math.cos(ang - 0.4), y1 - 9 * Math.sin(ang - 0.4));
    ctx.lineTo(x1 - 9 * Math.cos(ang + 0.4), y1 - 9 * Math.sin(ang + 0.4)); ctx.closePath(); ctx.fill();
  }

  function drawMarkers(P) {  // the magnet sources: a square where each is, an arrow along its moment or axis
    var n = 0, W = canvas.width, H = canvas.height;
    drawn.markers.forEach(function (m) {
      var q = P.at(m.position[0], m.position[1], m.position[2]);
      var inside = q[0] >= 0 && q[0] <= W && q[1] >= 0 && q[1] <= H;
      var x = Math.max(14, Math.min(W - 14, q[0])), y = Math.max(14, Math.min(H - 14, q[1]));
      var half = Math.max(5, Math.min(40, 0.5 * m.size * P.scale));
      ctx.strokeStyle = MAGNET; ctx.lineWidth = 2; ctx.setLineDash(inside ? [] : [3, 3]);
      ctx.strokeRect(x - half, y - half, 2 * half, 2 * half); ctx.setLineDash([]);
      var d = P.dir(m.direction[0], m.direction[1], m.direction[2]), L = Math.hypot(d[0], d[1]);
      if (L > 1e-6) arrow(x, y, x + d[0] / L * (half + 16), y - d[1] / L * (half + 16), MAGNET, 2);
      ctx.fillStyle = MAGNET; ctx.font = "12px system-ui, sans-serif";
      var label = m.name + (inside ? "" : " (out of view)");
      ctx.fillText(label, Math.min(x + half + 4, W - 7 * label.length), Math.min(y + half + 12, H - 4));
      n += 1;
    });
    return n;
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
      var bx = canvas.width - 90, by = canvas.height - 80;
      arrow(bx - d[0] * len * 0.5, by + d[1] * len * 0.5, bx + d[0] * len * 0.5, by - d[1] * len * 0.5, "#b0007a", 3);
      ctx.font = "12px ui-monospace, monospace";
      ctx.fillText("B " + si(mag, "T"), canvas.width - 150, canvas.height - 14);
    }
  }

  function colourScale(mode, n) {  // [lo, hi] of the colour map for this frame (the top only grows)
    var top = colorTop[mode] || 0, lo = Infinity, hi = -Infinity;
    for (var i = 0; i < n; i++) { var v = values[i]; if (v === v) { if (v < lo) lo = v; if (v > hi) hi = v; } }
    if (mode === "magnetisation" && info.dim === 2) {
      top = Math.max(top, Math.abs(lo), Math.abs(hi), 1); colorTop[mode] = top; return [-top, top];
    }
    top = Math.max(top, hi > -Infinity ? hi : 0, mode === "magnetisation" ? 1 : 1e-9); colorTop[mode] = top;
    return [0, top];
  }

  function draw() {
    ctx.fillStyle = "#fbfcfd"; ctx.fillRect(0, 0, canvas.width, canvas.height);
    var P = projector();
    drawDomain(P);
    var cols = drawColliders(P);
    canvas.setAttribute("data-colliders", String(cols[0]));
    canvas.setAttribute("data-floor", String(cols[1]));
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
      var mode = frameColor, spec = MODES[mode] || MODES.part, table = null, range = null;
      if (mode !== "part" && values) { table = lut(info.dim === 2 && spec.map2d ? spec.map2d : spec.map); range = colourScale(mode, n); }
      showColourBar(mode, range);
      var r = Math.max(1.5, Math.min(8, info.dx * P.scale * (info.dim === 3 ? 0.9 : 0.75)));
      var h = r / 2, last = "";
      for (var k = 0; k < n; k++) {
        var p = order[k], hex;
        if (info.clamped[p]) hex = HELD;
        else if (!table) hex = COLORS[info.body[p] % COLORS.length];
        else {
          var v = values[p];
          hex = v === v ? table[Math.max(0, Math.min(LUT_N - 1, Math.round((v - range[0]) / (range[1] - range[0]) * (LUT_N - 1))))] : NOVALUE;
        }
        var level = shaded ? Math.round((SHADES - 1) * (depth[p] - dmin) / (dmax - dmin)) : SHADES - 1;  // far: paler
        var col = shade(hex, level);
        if (col !== last) { ctx.fillStyle = col; last = col; }
        ctx.fillRect(sx[p] - h, sy[p] - h, r, r);
      }
      canvas.setAttribute("data-points", String(n));
      canvas.setAttribute("data-color", mode);
    }
    canvas.setAttribute("data-markers", String(drawMarkers(P)));
    drawGizmo(P);
  }

  function showColourBar(mode, range) {
    var bar = $("colorbar"), spec = MODES[mode];
    $("legend").style.display = mode === "part" ? "" : "none";
    if (mode === "part" || !range) { bar.style.display = "none"; return; }
    var stops = lut(info.dim === 2 && spec.map2d ? spec.map2d : spec.map);
    bar.style.display = "flex";
    $("colorbar-map").style.background = "linear-gradient(to right, " + [0, 12, 24, 36, 47].map(function (i) { return stops[i]; }).join(", ") + ")";
    var fmt = function (v) { return Math.abs(v) >= 100 || v === 0 ? num(v, 0) : Number(v.toPrecision(3)).toString(); };
    $("colorbar-lo").textContent = fmt(range[0]);
    $("colorbar-hi").textContent = fmt(range[1]) + " " + spec.unit;
    $("colorbar-title").textContent = spec.label + (mode === "magnetisation" ? (info.dim === 2 ? " (ccw +)" : "") : "");
  }

  // mouse: drag orbits, shift-drag or right-drag pans, wheel zooms, double-click goes back to the chosen view
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
    else { turn(1, dx * 0.01); turn(0, dy * 0.01); }
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
  canvas.addEventListener("dblclick", function () { setCamera($("view-mode").value); fit(); queueDraw(); });
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
  function setSlider(id, value) {  // from the server's answer; never the slider under the user's hand
    var s = sliders[id];
    if (!s || document.activeElement === s.input || !isFinite(value)) return;
    s.input.value = value; s.show();
  }
  function syncSliders(c) {
    setSlider("Bx", c.B[0] * 1e3); setSlider("By", c.B[1] * 1e3); setSlider("Bz", c.B[2] * 1e3);
    setSlider("magnitude", c.magnitude * 1e3); setSlider("azimuth", c.azimuth); setSlider("elevation", c.elevation);
    Object.keys(c.gains || {}).forEach(function (n) { setSlider("gain-" + n, c.gains[n]); });
    Object.keys(c.poses || {}).forEach(function (n) {
      var p = c.poses[n];
      ["x", "y", "z"].forEach(function (k) { setSlider("pose-" + n + "-" + k, p[k] * 1e3); });
      ["rx", "ry", "rz"].forEach(function (k) { setSlider("pose-" + n + "-" + k, p[k]); });
    });
  }

  function buildControls(st) {
    var c = st.controls, lim = info.limits, fieldBox = $("field-rows");
    var maxmT = lim.magnitude[1] * 1e3, mT = function (v) { return num(v, 2) + " mT"; }, deg = function (v) { return num(v, 0) + "\u00b0"; };
    var h = document.createElement("h3"); h.textContent = "components"; fieldBox.appendChild(h);
    row(fieldBox, "Bx", "Bx", -maxmT, maxmT, maxmT / 1000, c.B[0] * 1e3, mT);
    row(fieldBox, "By", "By", -maxmT, maxmT, maxmT / 1000, c.B[1] * 1e3, mT);
    if (info.dim === 3) row(fieldBox, "Bz", "Bz", -maxmT, maxmT, maxmT / 1000, c.B[2] * 1e3, mT);
    h = document.createElement("h3"); h.textContent = "magnitude and direction"; fieldBox.appendChild(h);
    row(fieldBox, "magnitude", "|B|", 0, maxmT, maxmT / 1000, c.magnitude * 1e3, mT);
    row(fieldBox, "azimuth", "azimuth", -180, 180, 1, c.azimuth, deg);
    if (info.dim === 3) row(fieldBox, "elevation", "elevation", -90, 90, 1, c.elevation, deg);
    ["Bx", "By", "Bz", "magnitude", "azimuth", "elevation"].forEach(function (k) {
      if (!sliders[k]) return;
      sliders[k].input.addEventListener("input", function () {
        sliders[k].show();
        $("follow").checked = false;
        var f = {}, v = Number(sliders[k].input.value);
        f[k] = k === "azimuth" || k === "elevation" ? v : v / 1e3;
        sendControl({field: f});
      });
    });
    $("follow").checked = c.follow_scene;
    $("follow").addEventListener("change", function () { sendControl({field: {follow_scene: $("follow").checked}}); });
    $("follow-note").textContent = info.has_scene_uniform ? "" : "(the scene has no uniform field: following it means none)";

    var gainBox = $("gain-rows");
    if (!info.sources.length) $("gain-panel").style.display = "none";
    var off = lim.offset[1] * 1e3, mm = function (v) { return num(v, 2) + " mm"; };
    info.sources.forEach(function (name) {
      var s = row(gainBox, "gain-" + name, name, lim.gain[0], lim.gain[1], 0.01, c.gains[name], function (v) { return "\u00d7 " + num(v, 2); });
      s.input.addEventListener("input", function () {
        s.show();
        var g = {}; g[name] = Number(s.input.value);
        sendControl({gains: g});
      });
      var det = document.createElement("details"), sum = document.createElement("summary");
      sum.textContent = "move and turn " + name; det.appendChild(sum); det.id = "pose-" + name;
      var pose = (c.poses || {})[name] || {x: 0, y: 0, z: 0, rx: 0, ry: 0, rz: 0};
      ["x", "y", "z", "rx", "ry", "rz"].forEach(function (k) {
        var lin = k.length === 1, id = "pose-" + name + "-" + k;
        var p = row(det, id, lin ? "\u0394" + k : "turn " + k.substr(1), lin ? -off : -180, lin ? off : 180, lin ? off / 1000 : 1,
                    lin ? pose[k] * 1e3 : pose[k], lin ? mm : deg);
        p.input.addEventListener("input", function () {
          p.show();
          var ch = {}; ch[name] = {}; ch[name][k] = lin ? Number(p.input.value) / 1e3 : Number(p.input.value);
          sendControl({poses: ch});
        });
      });
      gainBox.appendChild(det);
    });

    var legend = $("legend");
    info.bodies.forEach(function (b, i) {
      var span = document.createElement("span"), dot = document.createElement("i");
      dot.style.background = COLORS[i % COLORS.length];
      span.appendChild(dot); span.appendChild(document.createTextNode(b)); legend.appendChild(span);
    });
    if (info.clamped.some(function (v) { return v; })) {
      var span = document.createElement("span"), dot = document.createElement("i");
      dot.style.background = HELD; span.appendChild(dot); span.appendChild(document.createTextNode("clamped")); legend.appendChild(span);
    }

    var viewSel = $("view-mode");
    viewSel.options[0].textContent = "bend plane (" + info.view.plane + ")";
    viewSel.title = "the default camera looks at " + info.view.why;
    if (info.dim === 2) $("view-mode-wrap").style.display = "none";
    viewSel.addEventListener("change", function () { setCamera(viewSel.value); fit(); queueDraw(); });
    $("color-mode").addEventListener("change", function () {
      post("/view", {color: $("color-mode").value}).then(answer);
    });

    var probeSel = $("probe-column");
    if (!info.probes.length) {
      probeSel.style.display = "none";
      $("probe-note").textContent = "the scene has no [[probes]]: add one (a tip, centroid, field or collider_force probe) to plot it here";
    }
    info.probes.forEach(function (p) {
      var o = document.createElement("option"); o.value = p.column; o.textContent = p.column + " (" + (DISPLAY[p.unit] || [1, p.unit])[1] + ")";
      probeSel.appendChild(o);
    });
    probeSel.addEventListener("change", function () { probe.column = probeSel.value; probe.t = []; probe.v = []; probe.seq = 0; drawProbe(); });
    probe.column = info.probes.length ? info.probes[0].column : null;

    $("step-count").max = lim.steps[1];
    if (!info.out_dir) {
      $("save-scene").disabled = true; $("record").disabled = true;
      $("save-note").textContent = "start with --out DIR to save scenes and record runs into DIR";
    } else {
      $("save-note").textContent = "writes into " + info.out_dir;
    }
  }

  var paused = false, recording = null;
  $("pause").addEventListener("click", function () { post("/command", {action: paused ? "resume" : "pause"}).then(answer); });
  $("step").addEventListener("click", function () {
    var n = Math.max(1, Math.min(Number($("step-count").max) || 1, Math.round(Number($("step-count").value) || 1)));
    post("/command", {action: "step", steps: n}).then(answer);
  });
  $("reset").addEventListener("click", function () { post("/command", {action: "reset"}).then(answer); });
  $("save-scene").addEventListener("click", function () {
    post("/command", {action: "save_scene", name: $("save-name").value || "live_scene"}).then(answer).then(function (res) {
      if (res.ok) $("save-status").textContent = "saved " + res.data.path;
    });
  });
  $("record").addEventListener("click", function () {
    post("/command", {action: recording ? "record_stop" : "record_start"}).then(answer);
  });
  window.addEventListener("pagehide", function () { if (navigator.sendBeacon) navigator.sendBeacon("/bye", ""); });

  // ------------------------------------------------------------------ probe plot
  var probe = {column: null, t: [], v: [], seq: 0, busy: false};
  var plot = $("probe-plot"), pctx = plot.getContext("2d");
  function drawProbe() {
    var W = plot.width = Math.max(200, plot.clientWidth), H = plot.height = 150;
    pctx.fillStyle = "#fff"; pctx.fillRect(0, 0, W, H);
    var n = probe.t.length;
    plot.setAttribute("data-samples", String(n));
    plot.setAttribute("data-column", probe.column || "");
    if (!probe.column || !n) return;
    var unit = (info.probes.filter(function (p) { return p.column === probe.column; })[0] || {}).unit;
    var disp = DISPLAY[unit] || [1, unit], k = disp[0];
    var t0 = probe.t[0], t1 = probe.t[n - 1], lo = Infinity, hi = -Infinity;
    for (var i = 0; i < n; i++) { var v = probe.v[i] * k; if (v < lo) lo = v; if (v > hi) hi = v; }
    if (!(hi > lo)) { hi = lo + 1e-9 + Math.abs(lo) * 1e-3; lo -= 1e-9 + Math.abs(lo) * 1e-3; }
    if (!(t1 > t0)) t1 = t0 + 1e-9;
    var L = 58, R = 8, T = 8, B = 22;
    var X = function (t) { return L + (t - t0) / (t1 - t0) * (W - L - R); }, Y = function (v) { return T + (hi - v) / (hi - lo) * (H - T - B); };
    pctx.strokeStyle = "#d8dee4"; pctx.lineWidth = 1; pctx.strokeRect(L, T, W - L - R, H - T - B);
    pctx.strokeStyle = "#1f77b4"; pctx.lineWidth = 1.5; pctx.beginPath();
    for (var j = 0; j < n; j++) { var x = X(probe.t[j]), y = Y(probe.v[j] * k); if (j) pctx.lineTo(x, y); else pctx.moveTo(x, y); }
    pctx.stroke();
    pctx.fillStyle = "#5b6670"; pctx.font = "11px ui-monospace, monospace";
    pctx.fillText(hi.toPrecision(3), 2, T + 9); pctx.fillText(lo.toPrecision(3), 2, H - B);
    pctx.fillText(disp[1], 2, (H - B + T) / 2 + 4);
    pctx.fillText("t = " + si(t0, "s"), L, H - 6);
    var end = si(t1, "s"); pctx.fillText(end, W - R - 7 * end.length, H - 6);
  }
  function pollProbe(st) {
    if (!probe.column || probe.busy || st.probe_seq === probe.seq) return null;
    if (st.probe_seq < probe.seq) { probe.t = []; probe.v = []; probe.seq = 0; }  // a reset started a new run
    probe.busy = true;
    var col = probe.column;
    return getJSON("/probe?column=" + encodeURIComponent(col) + "&since=" + probe.seq).then(function (d) {
      probe.busy = false;
      if (col !== probe.column) return;
      if (probe.t.length && d.t.length && d.t[0] < probe.t[probe.t.length - 1]) { probe.t = []; probe.v = []; }
      probe.t = probe.t.concat(d.t); probe.v = probe.v.concat(d.v); probe.seq = d.seq;
      if (probe.t.length > 4000) { probe.t = probe.t.slice(-4000); probe.v = probe.v.slice(-4000); }
      drawProbe();
    }, function (e) { probe.busy = false; throw e; });
  }

  // ------------------------------------------------------------------ state
  function showState(st) {
    paused = st.paused;
    $("pause").textContent = st.paused ? "Resume" : "Pause";
    $("time").textContent = "t = " + si(st.time, "s");
    if (st.time < lastTime) colorTop = {};  // a reset: the colour scales start again
    lastTime = st.time;
    var speed = st.speed > 0 ? si(st.speed, "s") + "/s" + (st.speed < 1 ? " (1/" + (1 / st.speed).toPrecision(3) + " real time)" : " (" + st.speed.toPrecision(3) + "x real time)") : "-";
    $("readout").textContent = "speed  " + speed + "\nsteps  " + st.steps + " (" + Math.round(st.steps_per_s) + " steps/s)\ndt     " + si(st.dt, "s");
    engineB = st.engine_field;
    var mag = Math.hypot(engineB[0], engineB[1], engineB[2]);
    var az = Math.atan2(engineB[1], engineB[0]) * 180 / Math.PI, el = mag > 0 ? Math.asin(engineB[2] / mag) * 180 / Math.PI : 0;
    $("applied").textContent = "engine: B = (" + engineB.map(function (v) { return num(v * 1e3, 3); }).join(", ") + ") mT\n        |B| = " + num(mag * 1e3, 3) + " mT, azimuth " + num(mag > 0 ? az : 0, 1) + "\u00b0" + (info && info.dim === 3 ? ", elevation " + num(el, 1) + "\u00b0" : "") + (st.applied.follow_scene ? ", the scene's" : ", set here");
    drawn = {markers: st.markers, colliders: st.colliders};
    recording = st.recording;
    $("record").textContent = recording ? "Stop recording" : "Record";
    $("record-status").textContent = recording ? "recording into " + recording.folder + ": " + recording.frames + " frames (every " + si(recording.every, "s") + ")" : (st.record_message || "");
    $("probe-note").textContent = st.probe_error ? "probes stopped: " + st.probe_error : (info && info.probes.length ? "" : $("probe-note").textContent);
    simError = st.error || "";
    showMessage();
    var phase = st.stopping ? "stopped" : st.phase;
    var text = {starting: "starting (the first steps compile the kernels)", running: "running", paused: "paused", stepping: "stepping", failed: "failed", resetting: "resetting", stopped: "server stopping: " + st.stopping}[phase] || phase;
    setStatus(text, phase);
  }

  var lastFrame = -1, failures = 0;
  function poll() {
    getJSON("/state").then(function (st) {
      failures = 0;
      showState(st);
      queueDraw();
      return Promise.all([pollProbe(st), st.frame === lastFrame ? null : fetch("/frame", {cache: "no-store"}).then(function (r) {
        var id = Number(r.headers.get("X-Frame")), colour = r.headers.get("X-Color") || "part";
        return r.arrayBuffer().then(function (buf) {
          var first = positions === null, n = buf.byteLength / 16;
          positions = new Float32Array(buf, 0, 3 * n); values = new Float32Array(buf, 12 * n, n);
          frameColor = colour; lastFrame = id;
          if (first) fit();
          queueDraw();
        });
      })]);
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
    return {frame: lastFrame, points: n, mean_y: n ? sy / n : null, color: frameColor, camera: cam.M,
            probe: {column: probe.column, samples: probe.t.length, last: probe.v.length ? probe.v[probe.v.length - 1] : null}};
  };

  getJSON("/info").then(function (inf) {
    info = inf;
    $("scene").textContent = inf.scene + " \u00b7 " + inf.dim + "D \u00b7 " + inf.particles + " particles" + (inf.shown < inf.particles ? " (" + inf.shown + " shown)" : "");
    document.title = "magsoro live: " + inf.scene;
    setCamera("bend");
    return getJSON("/state");
  }).then(function (st) {
    buildControls(st);
    showState(st);
    resize();
    drawProbe();
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
    <div class="toolbar">
      <label>colour <select id="color-mode">
        <option value="part">part</option><option value="speed">speed</option>
        <option value="strain">strain</option><option value="magnetisation">magnetisation</option>
      </select></label>
      <span id="view-mode-wrap"><label>view <select id="view-mode">
        <option value="bend">bend plane</option><option value="x">down x</option>
        <option value="y">down y</option><option value="z">down z</option>
      </select></label></span>
      <span id="colorbar"><span id="colorbar-title"></span><span id="colorbar-lo"></span><i id="colorbar-map"></i><span id="colorbar-hi"></span></span>
      <span class="legend" id="legend"></span>
    </div>
    <canvas id="view" width="800" height="520"></canvas>
    <div class="hint">drag: orbit &middot; shift-drag or right-drag: pan &middot; wheel: zoom &middot; double-click: back to the view chosen &middot; grey: colliders and floor &middot; purple: magnet sources</div>
  </div>
  <aside>
    <section>
      <div id="time">t = 0 s</div>
      <div id="readout"></div>
      <button id="pause" type="button">Pause</button>
      <button id="step" type="button" title="pause and advance this many time steps">Step</button>
      <input id="step-count" type="number" min="1" value="1" step="1" aria-label="time steps per Step">
      <button id="reset" type="button">Reset</button>
    </section>
    <section id="field-panel">
      <h2>Uniform field</h2>
      <label><input type="checkbox" id="follow"> follow the scene's field</label> <small id="follow-note"></small>
      <div id="field-rows"></div>
      <div class="applied" id="applied"></div>
    </section>
    <section id="gain-panel">
      <h2>Field sources</h2>
      <div id="gain-rows"></div>
    </section>
    <section id="probe-panel">
      <h2>Probe</h2>
      <select id="probe-column"></select>
      <canvas id="probe-plot" width="320" height="150"></canvas>
      <div class="note" id="probe-note"></div>
    </section>
    <section id="save-panel">
      <h2>Save and record</h2>
      <input id="save-name" type="text" value="live_scene" maxlength="64" aria-label="scene name">
      <button id="save-scene" type="button" title="write a scene file with the settings of this page">Save as scene</button>
      <button id="record" type="button" title="write frames into a run folder that magsoro render and report read">Record</button>
      <div class="note" id="save-status"></div>
      <div class="note" id="record-status"></div>
      <div class="note" id="save-note"></div>
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
