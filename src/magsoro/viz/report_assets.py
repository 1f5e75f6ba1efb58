"""Inline CSS and JavaScript of the HTML report (kept in Python so they install with the package).

The JS is deliberately small and dependency-free: SVG line charts with hover read-out and a canvas point
viewer with mouse rotation and a time slider. The viewer starts with the camera the report computed (looking at
the plane the bodies bend in: :func:`magsoro.viz.report.default_view`) and offers views down x, y and z; the
canvas carries the camera as ``data-view`` (the preset) and ``data-towards`` (the unit vector towards the viewer).
It reads the JSON in ``<script id="report-data">`` and writes the outcome into ``#status`` ("ok: N curves, viewer
ready" or "error: ...").
"""

CSS = r"""
:root { --fg:#1d2329; --muted:#5b6670; --line:#d8dee4; --bg:#ffffff; --panel:#f6f8fa; --ok:#1a7f37; --bad:#cf222e; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg); background: var(--bg); margin: 0 auto; padding: 16px 24px 48px; max-width: 1280px; }
h1 { font-size: 22px; margin: 8px 0 2px; } h2 { font-size: 17px; margin: 28px 0 8px; border-bottom: 1px solid var(--line); padding-bottom: 4px; }
.sub, .hint { color: var(--muted); margin: 2px 0 8px; }
.badge { font-size: 12px; padding: 2px 8px; border-radius: 10px; vertical-align: middle; background: var(--panel); border: 1px solid var(--line); }
.badge.completed { color: var(--ok); border-color: var(--ok); } .badge.failed { color: var(--bad); border-color: var(--bad); }
.badge.stale, .badge.interrupted { color: var(--bad); border-style: dashed; }
#status { font-family: ui-monospace, monospace; font-size: 12px; padding: 4px 8px; border-radius: 4px; display: inline-block; margin-top: 6px; background: var(--panel); }
#status.ok { color: var(--ok); } #status.error { color: #fff; background: var(--bad); }
table { border-collapse: collapse; } th, td { text-align: left; padding: 3px 10px 3px 0; vertical-align: top; }
table.kv th { color: var(--muted); font-weight: 500; white-space: nowrap; } table.kv td { font-family: ui-monospace, monospace; font-size: 12px; word-break: break-all; }
.scroll { overflow-x: auto; } table.runs { font-size: 12px; } table.runs th { border-bottom: 1px solid var(--line); white-space: nowrap; }
table.runs td { border-bottom: 1px solid var(--panel); font-family: ui-monospace, monospace; } table.runs tr.failed td { color: var(--bad); }
.charts { display: flex; flex-wrap: wrap; gap: 16px; }
.chart { position: relative; border: 1px solid var(--line); border-radius: 6px; padding: 4px; background: #fff; }
.chart svg { display: block; } .chart text { font-size: 11px; fill: var(--fg); } .chart .title { font-size: 12px; font-weight: 600; }
.chart .grid { stroke: #eef1f4; } .chart .axis { stroke: #9aa4ad; } .chart .curve { fill: none; stroke-width: 1.6; }
.chart .legend { font-size: 11px; max-width: 460px; max-height: 64px; overflow-y: auto; padding: 0 6px 4px; }
.chart .legend span { display: inline-block; margin-right: 10px; white-space: nowrap; } .chart .legend i { display: inline-block; width: 10px; height: 3px; margin-right: 4px; vertical-align: middle; }
.tip { position: absolute; pointer-events: none; background: rgba(29,35,41,.9); color: #fff; font: 11px/1.35 ui-monospace, monospace; padding: 4px 6px; border-radius: 4px; white-space: pre; display: none; z-index: 2; }
#viewer { display: flex; flex-wrap: wrap; gap: 12px; align-items: flex-start; }
#viewer canvas { border: 1px solid var(--line); border-radius: 6px; background: #fbfcfd; cursor: grab; touch-action: none; }
#viewer .controls { display: flex; flex-direction: column; gap: 8px; min-width: 240px; }
#viewer input[type=range] { width: 100%; } #viewer .legend span { display: inline-block; margin-right: 10px; } #viewer .legend i { display: inline-block; width: 10px; height: 10px; border-radius: 5px; margin-right: 4px; vertical-align: middle; }
details summary { cursor: pointer; color: var(--muted); }
"""

JS = r"""
(function () {
  "use strict";
  var statusEl = document.getElementById("status");
  var problems = [];
  function fail(msg) {
    problems.push(String(msg));
    statusEl.textContent = "error: " + problems.join("; ");
    statusEl.className = "error";
  }
  window.addEventListener("error", function (e) { fail(e.message || "script error"); });
  window.addEventListener("unhandledrejection", function (e) { fail("unhandled rejection: " + e.reason); });

  var SVGNS = "http://www.w3.org/2000/svg";
  var PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];

  function svg(tag, attrs, parent) {
    var e = document.createElementNS(SVGNS, tag);
    for (var k in attrs) e.setAttribute(k, attrs[k]);
    if (parent) parent.appendChild(e);
    return e;
  }
  function html(tag, cls, parent, text) {
    var e = document.createElement(tag);
    if (cls) e.className = cls;
    if (text !== undefined) e.textContent = text;
    if (parent) parent.appendChild(e);
    return e;
  }
  function fmt(v) {
    if (v === null || v === undefined || !isFinite(v)) return String(v);
    var a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(3);
    return String(+v.toPrecision(6));
  }
  // Tick label with just enough digits to tell neighbouring ticks (spacing step) apart.
  function tickFmt(v, step) {
    if (v === 0) return "0";
    var a = Math.abs(v), digits = Math.max(1, Math.min(10, Math.ceil(Math.log10(a / step) + 1e-9) + 1));
    if (a < 1e-3 || a >= 1e5) return v.toExponential(digits - 1).replace(/\.?0+e/, "e");
    return String(+v.toPrecision(digits));
  }
  function b64bytes(s) {
    var bin = atob(s), out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }

  // Axis range and round tick values (1, 2, 5 x 10^k) covering [lo, hi].
  function niceScale(lo, hi, count) {
    if (!(hi > lo)) { var d = Math.abs(lo) * 0.1 || 1; lo -= d; hi += d; }
    var pad = (hi - lo) * 0.04; lo -= pad; hi += pad;
    var raw = (hi - lo) / count, step = Math.pow(10, Math.floor(Math.log10(raw))), r = raw / step;
    step *= r >= 7.5 ? 10 : r >= 3.5 ? 5 : r >= 1.5 ? 2 : 1;
    var ticks = [];
    for (var t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) ticks.push(Math.abs(t) < step * 1e-9 ? 0 : t);
    return { lo: lo, hi: hi, ticks: ticks, step: step };
  }

  // One SVG line chart; returns the number of curves drawn. spec: title, xlabel, ylabel,
  // series [{name, x, y}], optional markers (bool) and xcats (category labels; x holds their indices).
  function lineChart(host, spec) {
    var W = 470, H = 300, L = 84, R = 14, T = 26, B = 44;
    var box = html("div", "chart", host);
    var root = svg("svg", { viewBox: "0 0 " + W + " " + H, width: W, height: H }, box);
    svg("text", { x: L, y: 16, "class": "title" }, root).textContent = spec.title;
    var xs = [], ys = [];
    spec.series.forEach(function (s) {
      for (var i = 0; i < s.x.length; i++) if (isFinite(s.x[i]) && isFinite(s.y[i]) && s.x[i] !== null && s.y[i] !== null) { xs.push(s.x[i]); ys.push(s.y[i]); }
    });
    if (!xs.length) throw new Error("chart '" + spec.title + "' has no finite point");
    var xsc = spec.xcats ? { lo: -0.5, hi: spec.xcats.length - 0.5, ticks: spec.xcats.map(function (_, i) { return i; }) }
                         : niceScale(Math.min.apply(null, xs), Math.max.apply(null, xs), 6);
    var ysc = niceScale(Math.min.apply(null, ys), Math.max.apply(null, ys), 6);
    function px(x) { return L + (x - xsc.lo) / (xsc.hi - xsc.lo) * (W - L - R); }
    function py(y) { return H - B - (y - ysc.lo) / (ysc.hi - ysc.lo) * (H - T - B); }
    xsc.ticks.forEach(function (t) {
      svg("line", { x1: px(t), x2: px(t), y1: T, y2: H - B, "class": "grid" }, root);
      var lab = spec.xcats ? spec.xcats[t] : tickFmt(t, xsc.step);
      if (lab.length > 14) lab = lab.slice(0, 13) + "\u2026";
      svg("text", { x: px(t), y: H - B + 14, "text-anchor": "middle" }, root).textContent = lab;
    });
    ysc.ticks.forEach(function (t) {
      svg("line", { x1: L, x2: W - R, y1: py(t), y2: py(t), "class": "grid" }, root);
      svg("text", { x: L - 4, y: py(t) + 4, "text-anchor": "end" }, root).textContent = tickFmt(t, ysc.step);
    });
    svg("rect", { x: L, y: T, width: W - L - R, height: H - T - B, fill: "none", "class": "axis" }, root);
    svg("text", { x: (L + W - R) / 2, y: H - 8, "text-anchor": "middle" }, root).textContent = spec.xlabel;
    svg("text", { x: 11, y: (T + H - B) / 2, "text-anchor": "middle", transform: "rotate(-90 11 " + (T + H - B) / 2 + ")" }, root).textContent = spec.ylabel;
    var drawn = 0, pts = [];
    spec.series.forEach(function (s, k) {
      var color = PALETTE[k % PALETTE.length], d = "", pen = "M";
      for (var i = 0; i < s.x.length; i++) {
        if (s.x[i] === null || s.y[i] === null || !isFinite(s.x[i]) || !isFinite(s.y[i])) { pen = "M"; continue; }
        var X = px(s.x[i]), Y = py(s.y[i]);
        d += pen + X.toFixed(2) + " " + Y.toFixed(2) + " "; pen = "L";
        pts.push({ X: X, Y: Y, x: s.x[i], y: s.y[i], s: s.name, c: color });
        if (spec.markers) svg("circle", { cx: X, cy: Y, r: 3, fill: color, "class": "marker" }, root);
      }
      if (d) { svg("path", { d: d, stroke: color, "class": "curve", "data-series": s.name }, root); drawn++; }
    });
    if (spec.series.length > 1) {
      var leg = html("div", "legend", box);
      spec.series.forEach(function (s, k) {
        var it = html("span", "", leg);
        html("i", "", it).style.background = PALETTE[k % PALETTE.length];
        it.appendChild(document.createTextNode(s.name));
      });
    }
    // hover: the data point nearest to the pointer, with its series and values
    var dot = svg("circle", { r: 5, fill: "none", stroke: "#000", "stroke-width": 1.5, visibility: "hidden" }, root);
    var tip = html("div", "tip", box);
    var hit = svg("rect", { x: L, y: T, width: W - L - R, height: H - T - B, fill: "transparent" }, root);
    hit.addEventListener("mousemove", function (ev) {
      var rect = root.getBoundingClientRect(), mx = (ev.clientX - rect.left) * W / rect.width, my = (ev.clientY - rect.top) * H / rect.height;
      var best = null, bd = Infinity;
      for (var i = 0; i < pts.length; i++) { var dd = (pts[i].X - mx) * (pts[i].X - mx) + (pts[i].Y - my) * (pts[i].Y - my); if (dd < bd) { bd = dd; best = pts[i]; } }
      if (!best) return;
      dot.setAttribute("cx", best.X); dot.setAttribute("cy", best.Y); dot.setAttribute("stroke", best.c); dot.setAttribute("visibility", "visible");
      var xl = spec.xcats ? spec.xcats[best.x] : fmt(best.x);
      tip.textContent = best.s + "\n" + spec.xlabel + ": " + xl + "\n" + spec.ylabel + ": " + fmt(best.y);
      tip.style.display = "block";
      tip.style.left = Math.min(best.X * rect.width / W + 12, rect.width - 160) + "px";
      tip.style.top = Math.max(best.Y * rect.height / H - 40, 0) + "px";
    });
    hit.addEventListener("mouseleave", function () { dot.setAttribute("visibility", "hidden"); tip.style.display = "none"; });
    return drawn;
  }

  // Camera presets of the viewer (rows: screen right, screen up, towards the viewer); "bend" is the report's own.
  var VIEWS = {
    x: {right: [0, 1, 0], up: [0, 0, 1], towards: [1, 0, 0]},
    y: {right: [1, 0, 0], up: [0, 0, 1], towards: [0, -1, 0]},
    z: {right: [1, 0, 0], up: [0, 1, 0], towards: [0, 0, 1]}
  };
  function dot3(p, q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; }
  function unit3(p) { var l = Math.sqrt(dot3(p, p)) || 1; return [p[0] / l, p[1] / l, p[2] / l]; }
  // turn the camera M about a screen axis (0: right, 1: up), keeping its rows orthonormal against round-off
  function turnCamera(M, axis, angle) {
    var c = Math.cos(angle), s = Math.sin(angle), a = axis === 1 ? [0, 2] : [2, 1], r0 = M[a[0]], r1 = M[a[1]];
    M[a[0]] = [0, 1, 2].map(function (k) { return c * r0[k] + s * r1[k]; });
    M[a[1]] = [0, 1, 2].map(function (k) { return -s * r0[k] + c * r1[k]; });
    M[0] = unit3(M[0]);
    var d = dot3(M[1], M[0]);
    M[1] = unit3(M[1].map(function (v, k) { return v - d * M[0][k]; }));
    M[2] = [M[0][1] * M[1][2] - M[0][2] * M[1][1], M[0][2] * M[1][0] - M[0][0] * M[1][2], M[0][0] * M[1][1] - M[0][1] * M[1][0]];
  }

  // Canvas point viewer: orthographic projection, drag to rotate, wheel to zoom, slider over frames.
  function pointViewer(host, V) {
    var n = V.n, nf = V.frames;
    var q = new Uint16Array(b64bytes(V.pos).buffer);
    if (q.length !== nf * n * 3) throw new Error("viewer: expected " + nf * n * 3 + " coordinates, got " + q.length);
    var body = b64bytes(V.body), jq = b64bytes(V.J);
    var lo = V.lo, span = V.span, half = [span[0] / 2, span[1] / 2, span[2] / 2];
    var radius = Math.sqrt(half[0] * half[0] + half[1] * half[1] + half[2] * half[2]) || 1;
    var dpr = window.devicePixelRatio || 1, CW = 640, CH = 460;
    var canvas = html("canvas", "", host);
    canvas.width = CW * dpr; canvas.height = CH * dpr; canvas.style.width = CW + "px"; canvas.style.height = CH + "px";
    var ctx = canvas.getContext("2d");
    if (!ctx) throw new Error("viewer: no 2D canvas context");
    var panel = html("div", "controls", host);
    var label = html("div", "", panel, "");
    var slider = html("input", "", panel); slider.type = "range"; slider.min = 0; slider.max = nf - 1; slider.value = nf - 1; slider.id = "frame-slider";
    var row = html("div", "", panel);
    var play = html("button", "", row, "\u25B6 play"); play.type = "button";
    var reset = html("button", "", row, "reset view"); reset.type = "button"; reset.style.marginLeft = "6px";
    var bend = V.view || VIEWS.z;
    var viewPick = html("select", "", panel); viewPick.id = "view-preset";
    [["bend", "view: bend plane (" + (bend.plane || "?") + ")"], ["x", "view: down x"], ["y", "view: down y"], ["z", "view: down z"]]
      .forEach(function (o) { var op = html("option", "", viewPick, o[1]); op.value = o[0]; });
    viewPick.title = "the bend plane: " + (bend.why || "");
    if (V.dim === 2) viewPick.style.display = "none";  // a 2D run lies in the x-y plane: seen down z
    var pick = html("select", "", panel);
    [["body", "colour: body"], ["J", "colour: J = det F (volume change)"]].forEach(function (o) { var op = html("option", "", pick, o[1]); op.value = o[0]; });
    var legend = html("div", "legend", panel);
    var view = {}, frame = nf - 1, timer = null, mode = "body";
    function home() {
      var v = viewPick.value === "bend" ? bend : VIEWS[viewPick.value];
      view.M = [v.right.slice(), v.up.slice(), v.towards.slice()]; view.zoom = 1;
    }
    home();
    function jColor(v) {  // 0..255 -> blue (compressed) .. white (J = 1) .. red (stretched)
      var t = v / 255 * 2 - 1, a = Math.min(1, Math.abs(t));
      var r = t < 0 ? 255 * (1 - a) + 40 * a : 255, g = 255 * (1 - a) + 60 * a, b = t > 0 ? 255 * (1 - a) + 40 * a : 255;
      return "rgb(" + (r | 0) + "," + (g | 0) + "," + (b | 0) + ")";
    }
    var jColors = []; for (var c = 0; c < 256; c++) jColors.push(jColor(c));
    function drawLegend() {
      legend.textContent = "";
      if (mode === "body") {
        var seen = {};
        for (var i = 0; i < n; i++) seen[body[i]] = true;
        Object.keys(seen).forEach(function (b) { var s = html("span", "", legend); html("i", "", s).style.background = PALETTE[b % PALETTE.length]; s.appendChild(document.createTextNode((V.body_names || [])[b] || "body " + b)); });
      } else {
        legend.textContent = "J from " + fmt(V.J_range[0]) + " (blue) through 1 (white) to " + fmt(V.J_range[1]) + " (red)";
      }
    }
    var depth = new Float32Array(n), sx = new Float32Array(n), sy = new Float32Array(n), order = new Uint32Array(n);
    function draw() {
      var R = view.M[0], U = view.M[1], T = view.M[2];
      var scale = 0.45 * Math.min(CW, CH) / radius * view.zoom * dpr, base = frame * n * 3;
      for (var i = 0; i < n; i++) {
        var k = base + 3 * i;
        var dx = q[k] / 65535 * span[0] - half[0], dy = q[k + 1] / 65535 * span[1] - half[1], dz = q[k + 2] / 65535 * span[2] - half[2];
        sx[i] = CW * dpr / 2 + (R[0] * dx + R[1] * dy + R[2] * dz) * scale;
        sy[i] = CH * dpr / 2 - (U[0] * dx + U[1] * dy + U[2] * dz) * scale;
        depth[i] = T[0] * dx + T[1] * dy + T[2] * dz; order[i] = i;
      }
      order.sort(function (a, b) { return depth[a] - depth[b]; });  // far first, near drawn on top
      ctx.fillStyle = "#fbfcfd"; ctx.fillRect(0, 0, canvas.width, canvas.height);
      var size = Math.max(1.5, Math.min(5, 260 / Math.sqrt(n))) * dpr * Math.sqrt(view.zoom), h = size / 2;
      var jbase = frame * n;
      for (var j = 0; j < n; j++) {
        var p = order[j];
        ctx.fillStyle = mode === "body" ? PALETTE[body[p] % PALETTE.length] : jColors[jq[jbase + p]];
        ctx.fillRect(sx[p] - h, sy[p] - h, size, size);
      }
      // axis triad, bottom left
      var ox = 40 * dpr, oy = (CH - 40) * dpr, len = 26 * dpr;
      [[1, 0, 0, "x", "#d62728"], [0, 1, 0, "y", "#2ca02c"], [0, 0, 1, "z", "#1f77b4"]].forEach(function (a) {
        var x1 = dot3(R, a), y2 = dot3(U, a);
        ctx.strokeStyle = a[4]; ctx.lineWidth = 2 * dpr; ctx.beginPath(); ctx.moveTo(ox, oy); ctx.lineTo(ox + x1 * len, oy - y2 * len); ctx.stroke();
        ctx.fillStyle = a[4]; ctx.font = (11 * dpr) + "px sans-serif"; ctx.fillText(a[3], ox + x1 * len * 1.25 - 3 * dpr, oy - y2 * len * 1.25 + 4 * dpr);
      });
      canvas.setAttribute("data-view", viewPick.value);
      canvas.setAttribute("data-towards", T.map(function (c) { return String(Math.round(c * 1e6) / 1e6 + 0); }).join(","));
      label.textContent = (V.stamp === "level" ? "level " + fmt(V.times[frame]) : "t = " + fmt(V.times[frame]) + " s")
        + "  (frame " + (frame + 1) + " / " + nf + ")";
    }
    slider.addEventListener("input", function () { frame = +slider.value; draw(); });
    pick.addEventListener("change", function () { mode = pick.value; drawLegend(); draw(); });
    viewPick.addEventListener("change", function () { home(); draw(); });
    reset.addEventListener("click", function () { home(); draw(); });
    canvas.addEventListener("dblclick", function () { home(); draw(); });
    play.addEventListener("click", function () {
      if (timer) { clearInterval(timer); timer = null; play.textContent = "\u25B6 play"; return; }
      if (frame >= nf - 1) frame = 0;
      play.textContent = "\u275A\u275A pause";
      timer = setInterval(function () {
        frame = frame + 1; slider.value = frame; draw();
        if (frame >= nf - 1) { clearInterval(timer); timer = null; play.textContent = "\u25B6 play"; }
      }, 80);
    });
    var drag = null;
    canvas.addEventListener("pointerdown", function (ev) { drag = { x: ev.clientX, y: ev.clientY }; canvas.setPointerCapture(ev.pointerId); canvas.style.cursor = "grabbing"; });
    canvas.addEventListener("pointermove", function (ev) {
      if (!drag) return;
      turnCamera(view.M, 1, (ev.clientX - drag.x) * 0.01);
      turnCamera(view.M, 0, (ev.clientY - drag.y) * 0.01);
      drag = { x: ev.clientX, y: ev.clientY }; draw();
    });
    canvas.addEventListener("pointerup", function () { drag = null; canvas.style.cursor = "grab"; });
    canvas.addEventListener("wheel", function (ev) { ev.preventDefault(); view.zoom = Math.max(0.2, Math.min(20, view.zoom * Math.exp(-ev.deltaY * 0.001))); draw(); }, { passive: false });
    drawLegend(); draw();
    canvas.setAttribute("data-ready", "1");
    return true;
  }

  function main() {
    var data = JSON.parse(document.getElementById("report-data").textContent);
    var host = document.getElementById("charts"), curves = 0;
    data.charts.forEach(function (spec) {
      try { curves += lineChart(host, spec); } catch (e) { fail(e.message); }
    });
    if (curves !== data.expected_curves) fail("drew " + curves + " of " + data.expected_curves + " curves");
    var viewerNote = "no particle viewer";
    if (data.viewer) {
      try { pointViewer(document.getElementById("viewer"), data.viewer); viewerNote = "viewer ready"; } catch (e) { fail(e.message); }
    }
    if (!problems.length) {
      statusEl.textContent = "ok: " + curves + " curves, " + viewerNote;
      statusEl.className = "ok";
    }
  }
  try { main(); } catch (e) { fail(e.message || String(e)); }
})();
"""
