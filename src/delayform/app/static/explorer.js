// delayform explorer: the page. Every number comes from the server's /api endpoints;
// this script only draws them (Plotly, served by the same server) and animates the robots.
"use strict";

const $ = (id) => document.getElementById(id);
const state = {
  defaults: {}, limits: {}, toggles: [], points: [],
  chartSeq: 0, pointSeq: 0, simBusy: false, simPending: null,
  anim: null, playing: true,
};

function fmt(x, digits = 4) {
  return x === null || x === undefined ? "\u2013" : Number(x).toFixed(digits);
}

function complexText(re, im) {
  return `${fmt(re)} ${im < 0 ? "\u2212" : "+"} ${fmt(Math.abs(im))}j`;
}

function say(text) { $("message").textContent = text || ""; }

async function getJSON(path, params) {
  // the robot controls (robot_controls.js) ride along with every request that takes them
  const query = new URLSearchParams(params ? { ...params, ...robotParams(path) } : params).toString();
  const res = await fetch(query ? `${path}?${query}` : path);
  const body = await res.json();
  if (!res.ok) throw new Error(body.error || `HTTP ${res.status}`);
  return body;
}

function num(id) { return Number($(id).value); }
function gains() { return { P: num("P"), D: num("D") }; }
function point() { return { tau1: num("tau1"), tau2: num("tau2") }; }
function toggleParams() {
  const out = {};
  for (const name of state.toggles) out[name] = $(`toggle-${name}`).checked ? 1 : 0;
  // loss and jitter only with the network on: the server refuses them otherwise, never ignores them
  if (out.network === 1) { out.loss = num("loss"); out.jitter = num("jitter"); }
  return out;
}

// ------------------------------------------------------------------ chart
const CHART_TRACE = { shading: 0, offspring: 1, kernel: 2, points: 3, here: 4 };

async function drawChart() {
  const seq = ++state.chartSeq;
  const params = { ...gains(), tau1_max: num("tau1_max"), tau2_max: num("tau2_max") };
  let chart;
  try {
    chart = await getJSON("/api/chart", params);
  } catch (err) { say(`chart: ${err.message}`); return; }
  if (seq !== state.chartSeq) return;
  if ($("message").textContent.startsWith("chart:")) say("");
  const top = Math.max(2, ...chart.grid.unstable_count.map((row) => Math.max(...row)));
  const cut = 0.5 / top;
  const here = point();
  const data = [
    { type: "heatmap", x: chart.grid.tau1, y: chart.grid.tau2, z: chart.grid.unstable_count,
      zmin: 0, zmax: top, showscale: false, hoverinfo: "skip",
      colorscale: [[0, "#e3f2df"], [cut, "#e3f2df"], [cut, "#fde3e1"], [1, "#d7301f"]] },
    { type: "scatter", mode: "lines", name: "offspring", x: chart.curves.offspring.tau1,
      y: chart.curves.offspring.tau2, line: { color: "blue", width: 1 }, hoverinfo: "skip" },
    { type: "scatter", mode: "lines", name: "kernel", x: chart.curves.kernel.tau1,
      y: chart.curves.kernel.tau2, line: { color: "red", width: 2 }, hoverinfo: "skip" },
    { type: "scatter", mode: "markers+text", name: "paper points", x: chart.points.map((p) => p.tau1),
      y: chart.points.map((p) => p.tau2), text: chart.points.map((p) => p.label),
      textposition: "top right", marker: { color: "black", size: 6 }, hoverinfo: "skip" },
    { type: "scatter", mode: "markers", name: "selected", x: [here.tau1], y: [here.tau2],
      marker: { symbol: "star", size: 15, color: "gold", line: { color: "black", width: 1 } }, hoverinfo: "skip" },
  ];
  const layout = {
    title: { text: `Exact CTCR chart, P = ${params.P}, D = ${params.D}: green stable ` +
      `(${(100 * chart.stable_fraction).toFixed(1)}%), red NU > 0; click a point`, font: { size: 13 },
      x: 0.01, xanchor: "left" },
    xaxis: { title: { text: "\u03c4\u2081 (s), position delay" }, range: [0, chart.tau1_max], constrain: "domain" },
    yaxis: { title: { text: "\u03c4\u2082 (s), velocity delay" }, range: [0, chart.tau2_max] },
    margin: { l: 55, r: 10, t: 40, b: 45 }, dragmode: false, showlegend: true,
    legend: { x: 1, xanchor: "right", y: 1, bgcolor: "rgba(255,255,255,0.7)" },
  };
  await Plotly.react("chart", data, layout, { displaylogo: false, responsive: true });
  document.body.dataset.chartReady = String(state.chartSeq);
}

// pixel of the click -> delays, through the axes Plotly drew
function clickedDelays(ev) {
  const gd = $("chart");
  const full = gd._fullLayout;
  if (!full) return null;
  const xa = full.xaxis, ya = full.yaxis;
  const box = gd.getBoundingClientRect();
  const px = ev.clientX - box.left - xa._offset;
  const py = ev.clientY - box.top - ya._offset;
  if (px < 0 || py < 0 || px > xa._length || py > ya._length) return null;
  return { tau1: xa.p2l(px), tau2: ya.p2l(py) };
}

function markPoint(p) {
  if ($("chart").data) Plotly.restyle("chart", { x: [[p.tau1]], y: [[p.tau2]] }, [CHART_TRACE.here]);
}

// ------------------------------------------------------------------ a point
async function selectPoint(p) {
  const round = (x) => Math.round(x * 1e4) / 1e4;
  p = { tau1: round(Math.max(0, p.tau1)), tau2: round(Math.max(0, p.tau2)) };
  $("tau1").value = p.tau1;
  $("tau2").value = p.tau2;
  markPoint(p);
  updateDownloads();
  const seq = ++state.pointSeq;
  $("verdict").textContent = "computing\u2026";
  $("verdict").className = "verdict";
  $("point-label").textContent = `(${p.tau1}, ${p.tau2})`;
  const started = performance.now();
  let r;
  try {
    r = await getJSON("/api/point", { ...p, ...gains() });
  } catch (err) {
    if (seq === state.pointSeq) { $("verdict").textContent = "error"; say(err.message); simulateAt(p); }
    return;
  }
  if (seq !== state.pointSeq) return;
  const ms = performance.now() - started;
  $("verdict").textContent = r.stable ? "stable" : "unstable";
  $("verdict").className = `verdict ${r.stable ? "stable" : "unstable"}`;
  $("unstable-count").textContent = String(r.unstable_count);
  $("dominant-root").textContent = complexText(r.dominant_root[0], r.dominant_root[1]);
  $("time-constant").textContent = r.time_constant === null
    ? `\u221e (grows at ${fmt(r.growth_rate, 3)} 1/s)` : `${fmt(r.time_constant, 2)} s`;
  $("dominant-factor").textContent = r.dominant_factor;
  $("point-ms").textContent = `${ms.toFixed(0)} ms`;
  document.body.dataset.pointMs = ms.toFixed(1);
  document.body.dataset.point = `${p.tau1},${p.tau2}`;
  // what is certified beyond the chart: any per-link delay variation within +-delta
  $("jitter-margin").textContent = "\u2026";
  getJSON("/api/guarantee", { ...p, ...gains() }).then((g) => {
    if (seq !== state.pointSeq) return;
    $("jitter-margin").textContent = g.jitter_margin === null ? "not computed (team too large)"
      : g.jitter_margin === 0 ? "0 (unstable)" : `\u00b1${fmt(g.jitter_margin, 3)} s, any variation`;
  }).catch((err) => { if (seq === state.pointSeq) $("jitter-margin").textContent = err.message; });
  // then the roots near the axis (a certified count per factor), the eigenvalue plane and the robots' run
  try {
    const roots = await getJSON("/api/roots", { ...p, ...gains() });
    if (seq === state.pointSeq) drawRoots(roots);
  } catch (err) { if (seq === state.pointSeq) say(`roots: ${err.message}`); }
  try {
    const plane = await getJSON("/api/region", { ...p, ...gains() });
    if (seq === state.pointSeq) drawRegion(plane);
  } catch (err) { if (seq === state.pointSeq) say(`eigenvalue plane: ${err.message}`); }
  if (seq === state.pointSeq) simulateAt(p);
}

function drawRoots(r) {
  const [x0, x1, y0, y1] = r.region;
  const groups = new Map();
  r.roots_near_axis.forEach(([re, im], i) => {
    const f = r.root_factors[i];
    if (!groups.has(f)) groups.set(f, { x: [], y: [] });
    groups.get(f).x.push(re);
    groups.get(f).y.push(im);
  });
  const data = [...groups.entries()].map(([f, g]) => ({
    type: "scatter", mode: "markers", x: g.x, y: g.y, name: r.factors[f], marker: { size: 7 },
    hovertemplate: "%{x:.4f} %{y:+.4f}j<extra></extra>",
  }));
  data.push({ type: "scatter", mode: "markers", name: "dominant", x: [r.dominant_root[0]],
    y: [r.dominant_root[1]], marker: { symbol: "circle-open", size: 15, color: "black", line: { width: 2 } } });
  const layout = {
    title: { text: `roots near the imaginary axis${r.roots_certified ? "" : " (count not certified)"}`, font: { size: 12 } },
    xaxis: { title: { text: "Re s" }, range: [x0, x1], zeroline: false },
    yaxis: { title: { text: "Im s" }, range: [y0, y1] },
    shapes: [{ type: "line", x0: 0, x1: 0, y0: y0, y1: y1, line: { color: "#b00", width: 1, dash: "dot" } }],
    margin: { l: 45, r: 5, t: 25, b: 35 }, showlegend: true, legend: { font: { size: 9 } },
  };
  Plotly.react("roots", data, layout, { displaylogo: false, responsive: true });
}

// The eigenvalue plane: NU(lam) shaded (green where 0), the boundary curve L(j omega) where roots
// cross the imaginary axis, the unit circle, and the team's eigenvalues of C coloured by their NU.
function drawRegion(r) {
  const R = r.radius;
  const top = Math.max(2, ...r.grid.unstable_count.map((row) => Math.max(...row)));
  const cut = 0.5 / top;
  const circle = Array.from({ length: 129 }, (_, k) => (2 * Math.PI * k) / 128);
  const eig = { stable: { x: [], y: [], n: [] }, unstable: { x: [], y: [], n: [] } };
  r.eigenvalues.re.forEach((re, i) => {
    const g = eig[r.eigenvalue_stable[i] ? "stable" : "unstable"];
    g.x.push(re); g.y.push(r.eigenvalues.im[i]); g.n.push(r.eigenvalue_unstable_count[i]);
  });
  const marker = (color) => ({ size: 10, color, line: { color: "black", width: 1 } });
  const data = [
    { type: "heatmap", x: r.grid.values, y: r.grid.values, z: r.grid.unstable_count, zmin: 0, zmax: top,
      showscale: false, hovertemplate: "\u03bb = %{x:.3f} %{y:+.3f}j: NU = %{z}<extra></extra>",
      colorscale: [[0, "#e3f2df"], [cut, "#e3f2df"], [cut, "#fde3e1"], [1, "#d7301f"]] },
    { type: "scatter", mode: "lines", name: "L(j\u03c9)", x: r.boundary.re, y: r.boundary.im,
      line: { color: "blue", width: 1.5 }, hoverinfo: "skip" },
    { type: "scatter", mode: "lines", name: "|\u03bb| = 1", x: circle.map(Math.cos), y: circle.map(Math.sin),
      line: { color: "#555", width: 1, dash: "dot" }, hoverinfo: "skip" },
    { type: "scatter", mode: "markers", name: "stable eigenvalues", x: eig.stable.x, y: eig.stable.y,
      customdata: eig.stable.n, marker: marker("#2e7d32"), hovertemplate: "%{x:.4f} %{y:+.4f}j: NU = %{customdata}<extra></extra>" },
    { type: "scatter", mode: "markers", name: "unstable eigenvalues", x: eig.unstable.x, y: eig.unstable.y,
      customdata: eig.unstable.n, marker: marker("#d32f2f"), hovertemplate: "%{x:.4f} %{y:+.4f}j: NU = %{customdata}<extra></extra>" },
  ];
  const verdict = r.stable ? "every eigenvalue in the stable region" : `team NU = ${r.unstable_count}`;
  const layout = {
    title: { text: `eigenvalue plane of C (green: stable region): ${verdict}`, font: { size: 12 } },
    xaxis: { title: { text: "Re \u03bb" }, range: [-R, R], zeroline: false, constrain: "domain" },
    yaxis: { title: { text: "Im \u03bb" }, range: [-R, R], scaleanchor: "x", zeroline: false },
    margin: { l: 45, r: 5, t: 25, b: 35 }, showlegend: true, legend: { font: { size: 9 } },
  };
  Plotly.react("region", data, layout, { displaylogo: false, responsive: true });
  document.body.dataset.region = `${r.tau1},${r.tau2}`;
  document.body.dataset.regionStable = String(r.stable);
}

// ------------------------------------------------------------------ robots
// One run in flight per page: a click during a run waits, and only the newest waiting point
// runs next, so quick clicks never queue runs on the server that nobody will watch.
async function simulateAt(p) {
  if (state.simBusy) { state.simPending = p; $("sim-info").textContent = "simulating\u2026"; return; }
  state.simBusy = true;
  state.simPending = null;
  $("sim-info").textContent = "simulating\u2026";
  try {
    const sim = await getJSON("/api/simulate", { ...p, ...gains(), duration: num("duration"), ...toggleParams() });
    if (!state.simPending) startAnimation(sim);
  } catch (err) {
    if (!state.simPending) { $("sim-info").textContent = ""; say(`robots: ${err.message}`); }
  } finally {
    state.simBusy = false;
    if (state.simPending) simulateAt(state.simPending);
  }
}

function startAnimation(sim) {
  const settle = sim.settling_time === null ? "not settled" : `settles at ${fmt(sim.settling_time, 1)} s`;
  const diverged = sim.diverged_at === null ? "" : `; overflowed at ${fmt(sim.diverged_at, 1)} s`;
  const limits = sim.limits !== null ? ", with actuator limits"
    : sim.network !== null ? `, network: ${sim.network}` : "";
  const touched = sim.contacts.length ? `; COLLIDED: ${sim.contacts.length} contact(s)` : "";
  $("sim-info").textContent = `${sim.n} ${sim.model} robots${limits}, ${settle}${diverged}${touched}`;
  $("sim-info").title = [sim.limits || sim.network || "", ...sim.warnings].join("\n");
  const err = sim.formation_error.map((e) => Math.max(e, 1e-12));
  Plotly.react("error", [{ type: "scatter", mode: "lines", x: sim.times, y: err, name: "formation error",
    line: { color: "#333" }, hovertemplate: "t = %{x:.1f} s: %{y:.3g}<extra></extra>" }], {
    title: { text: "formation error (RMS distance from the shape)", font: { size: 12 } },
    xaxis: { title: { text: "time (s)" } }, yaxis: { type: "log" },
    margin: { l: 50, r: 5, t: 25, b: 35 }, showlegend: false,
  }, { displaylogo: false, responsive: true });
  state.anim = { sim, frame: 0, started: performance.now(), shown: -1, box: null };
  document.body.dataset.simPoint = `${sim.tau1},${sim.tau2}`;
  drawFrame(0);
}

// The robots are drawn on a plain canvas: a Plotly redraw per frame would keep the
// page's only thread busy and slow down the answer to the next click.
const PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];

function niceStep(span) {
  const raw = span / 6, mag = 10 ** Math.floor(Math.log10(raw));
  return [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
}

function widenBox(a, k) {
  // fixed axes, widened only when a robot leaves them
  const sim = a.sim, xs = sim.x[k], ys = sim.y[k], b = a.box;
  if (b && Math.min(...xs) >= b[0] && Math.max(...xs) <= b[1] && Math.min(...ys) >= b[2] && Math.max(...ys) <= b[3]) return;
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  const take = (x, y) => { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); };
  for (let j = 0; j <= k; j++) for (let i = 0; i < sim.n; i++) take(sim.x[j][i], sim.y[j][i]);
  for (const q of sim.desired_final) take(q[0], q[1]);
  const pad = 0.12 * Math.max(x1 - x0, y1 - y0, 1e-6);
  a.box = [x0 - pad, x1 + pad, y0 - pad, y1 + pad];
}

function drawFrame(k) {
  const a = state.anim, sim = a.sim, n = sim.n;
  widenBox(a, k);
  const canvas = $("robots"), ratio = window.devicePixelRatio || 1;
  const W = canvas.clientWidth, H = canvas.clientHeight;
  if (canvas.width !== Math.round(W * ratio)) { canvas.width = Math.round(W * ratio); canvas.height = Math.round(H * ratio); }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  ctx.clearRect(0, 0, W, H);
  const [bx0, bx1, by0, by1] = a.box, m = { l: 45, r: 10, t: 26, b: 30 };
  const scale = Math.min((W - m.l - m.r) / (bx1 - bx0), (H - m.t - m.b) / (by1 - by0));
  const cx = (bx0 + bx1) / 2, cy = (by0 + by1) / 2, px0 = m.l + (W - m.l - m.r) / 2, py0 = m.t + (H - m.t - m.b) / 2;
  const X = (x) => px0 + (x - cx) * scale, Y = (y) => py0 - (y - cy) * scale;
  // axes: a frame with ticks every "nice" step
  ctx.strokeStyle = "#ccc"; ctx.fillStyle = "#555"; ctx.font = "11px sans-serif"; ctx.lineWidth = 1;
  ctx.strokeRect(m.l, m.t, W - m.l - m.r, H - m.t - m.b);
  const step = niceStep(Math.max((W - m.l - m.r) / scale, (H - m.t - m.b) / scale));
  const lx = cx - (W / 2) / scale, hx = cx + (W / 2) / scale, ly = cy - (H / 2) / scale, hy = cy + (H / 2) / scale;
  ctx.textAlign = "center";
  for (let v = Math.ceil(lx / step) * step; v <= hx; v += step) {
    if (X(v) < m.l || X(v) > W - m.r) continue;
    ctx.beginPath(); ctx.moveTo(X(v), m.t); ctx.lineTo(X(v), H - m.b); ctx.strokeStyle = "#eee"; ctx.stroke();
    ctx.fillText(Number(v.toPrecision(6)).toString(), X(v), H - m.b + 13);
  }
  ctx.textAlign = "right";
  for (let v = Math.ceil(ly / step) * step; v <= hy; v += step) {
    if (Y(v) < m.t || Y(v) > H - m.b) continue;
    ctx.beginPath(); ctx.moveTo(m.l, Y(v)); ctx.lineTo(W - m.r, Y(v)); ctx.strokeStyle = "#eee"; ctx.stroke();
    ctx.fillText(Number(v.toPrecision(6)).toString(), m.l - 4, Y(v) + 4);
  }
  ctx.save();
  ctx.beginPath(); ctx.rect(m.l, m.t, W - m.l - m.r, H - m.t - m.b); ctx.clip();
  for (let i = 0; i < n; i++) {  // paths so far
    ctx.beginPath(); ctx.strokeStyle = PALETTE[i % PALETTE.length]; ctx.globalAlpha = 0.45;
    for (let j = 0; j <= k; j++) { const x = X(sim.x[j][i]), y = Y(sim.y[j][i]); if (j) ctx.lineTo(x, y); else ctx.moveTo(x, y); }
    ctx.stroke();
  }
  ctx.globalAlpha = 1; ctx.strokeStyle = "#2a2"; ctx.lineWidth = 1.5;
  for (const q of sim.desired_final) { ctx.beginPath(); ctx.arc(X(q[0]), Y(q[1]), 8, 0, 2 * Math.PI); ctx.stroke(); }
  // bodies to scale (radius sim.radius m); red while the robot touches another (sim.contacts)
  const t = sim.times[k], touching = new Set();
  for (const [i, j, t0, t1] of sim.contacts) if (t0 <= t && t <= t1) { touching.add(i); touching.add(j); }
  if (sim.radius > 0) {
    for (let i = 0; i < n; i++) {
      ctx.beginPath(); ctx.arc(X(sim.x[k][i]), Y(sim.y[k][i]), sim.radius * scale, 0, 2 * Math.PI);
      ctx.strokeStyle = touching.has(i) ? "#d00" : "#888"; ctx.lineWidth = touching.has(i) ? 2.5 : 0.8; ctx.stroke();
    }
  }
  ctx.textAlign = "center"; ctx.fillStyle = "#222";
  for (let i = 0; i < n; i++) {  // unicycles: a triangle along the heading
    const x = X(sim.x[k][i]), y = Y(sim.y[k][i]), th = sim.heading[k][i], c = Math.cos(th), s = Math.sin(th);
    const tip = [x + 11 * c, y - 11 * s], left = [x - 6 * c - 5 * s, y + 6 * s - 5 * c], right = [x - 6 * c + 5 * s, y + 6 * s + 5 * c];
    ctx.beginPath(); ctx.moveTo(...tip); ctx.lineTo(...left); ctx.lineTo(...right); ctx.closePath();
    ctx.fillStyle = PALETTE[i % PALETTE.length]; ctx.fill(); ctx.strokeStyle = "#000"; ctx.lineWidth = 0.8; ctx.stroke();
    if (n <= 20) { ctx.fillStyle = "#222"; ctx.fillText(sim.labels[i], x, y - 12); }
  }
  ctx.restore();
  ctx.fillStyle = "#222"; ctx.font = "12px sans-serif"; ctx.textAlign = "center";
  const bodies = sim.radius > 0 ? `; circles: bodies to scale, red: in contact${touching.size ? " NOW" : ""}` : "";
  ctx.fillText(`robots (unicycles with headings; green: the formation at its final offset${bodies}), t = ${fmt(sim.times[k], 1)} s`, W / 2, 16);
  moveCursor(sim.times[k]);
  $("sim-time").textContent = `t = ${fmt(sim.times[k], 1)} s`;
  document.body.dataset.simTime = String(sim.times[k]);
  a.shown = k;
}

// the time cursor on the error plot is a positioned line, not a Plotly relayout
function moveCursor(t) {
  const gd = $("error"), full = gd._fullLayout, line = $("error-cursor");
  if (!full || !full.xaxis || !full.xaxis._length) { line.style.display = "none"; return; }
  const xa = full.xaxis, ya = full.yaxis;
  line.style.display = "block";
  line.style.left = `${gd.offsetLeft + xa._offset + xa.l2p(t)}px`;
  line.style.top = `${gd.offsetTop + ya._offset}px`;
  line.style.height = `${ya._length}px`;
}

// about ten seconds per run, then it starts again; at most ~15 drawn frames per second
const PLAY_SECONDS = 10;
function tick(now) {
  const a = state.anim;
  if (a && state.playing) {
    const frames = a.sim.times.length;
    // rAF's timestamp can precede the moment the run arrived: clamp at the first frame
    const elapsed = Math.max(0, now - a.started) / 1000;
    const k = Math.floor((elapsed / PLAY_SECONDS) * frames) % (frames + 20);
    const target = Math.min(k, frames - 1);
    if (target !== a.shown && now - (a.lastDraw || 0) > 60) { a.lastDraw = now; drawFrame(target); }
  }
  requestAnimationFrame(tick);
}

// ------------------------------------------------------------------ controls
function downloadParams() {
  return new URLSearchParams({ ...point(), ...gains(), duration: num("duration"),
    tau1_max: num("tau1_max"), tau2_max: num("tau2_max"), ...toggleParams(),
    ...robotParams("/download/scenario.toml") }).toString();
}

function updateDownloads() {
  const q = downloadParams();
  $("download-scenario").href = `/download/scenario.toml?${q}`;
  $("download-figures").href = `/download/figures.zip?${q}`;
}

function debounce(fn, ms) {
  let timer = null;
  return (...args) => { clearTimeout(timer); timer = setTimeout(() => fn(...args), ms); };
}

// the server refuses windows beyond delay x crossing-frequency bound; shrink the window first
function fitWindow() {
  const { P, D } = gains();
  const omega = (D + Math.sqrt(D * D + 8 * P)) / 2;
  const side = Math.min(state.limits.max_delay, state.limits.max_delay_bandwidth / omega);
  for (const key of ["tau1_max", "tau2_max"]) {
    if (num(key) > side) {
      $(key).value = Math.floor(side * 100) / 100;
      say(`chart window reduced to ${$(key).value} s (explorer limit max_delay_bandwidth)`);
    }
  }
}

function bindGain(name) {
  // the point after the chart: its verdict then reads the map the chart just computed
  const redraw = debounce(async () => { fitWindow(); await drawChart(); selectPoint(point()); }, 250);
  $(`${name}-range`).addEventListener("input", () => { $(name).value = $(`${name}-range`).value; redraw(); });
  $(name).addEventListener("change", () => { $(`${name}-range`).value = $(name).value; redraw(); });
}

async function init() {
  const info = await getJSON("/api/scenario");
  const s = info.scenario;
  state.defaults = info.defaults;
  state.limits = info.limits;
  $("scenario-name").textContent = `${s.name}: ${s.agents} agents, ${s.topology}, ${s.model}`;
  $("out-dir").textContent = info.out_dir;
  for (const key of ["P", "D", "tau1", "tau2", "tau1_max", "tau2_max", "duration"]) $(key).value = info.defaults[key];
  $("P-range").value = info.defaults.P;
  $("D-range").value = info.defaults.D;
  initRobotControls(info);
  state.toggles = Object.keys(info.toggles || {});
  const names = { limits: "actuator limits", network: "network imperfections" };
  for (const t of state.toggles) {
    const label = document.createElement("label");
    label.innerHTML = `<input type="checkbox" id="toggle-${t}"> ${names[t] || t}`;
    $("toggles").appendChild(label);
    const box = label.querySelector("input");
    box.checked = Boolean(info.toggles[t]);
    box.addEventListener("change", () => {
      $("network-fields").hidden = !(state.toggles.includes("network") && $("toggle-network").checked);
      simulateAt(point()); updateDownloads();
    });
  }
  if (state.toggles.includes("network")) {
    $("loss").value = info.defaults.loss;
    $("jitter").value = info.defaults.jitter;
    $("network-fields").hidden = !$("toggle-network").checked;
    for (const key of ["loss", "jitter"]) $(key).addEventListener("change", () => { simulateAt(point()); updateDownloads(); });
  }
  bindGain("P");
  bindGain("D");
  for (const key of ["tau1", "tau2"]) $(key).addEventListener("change", () => selectPoint(point()));
  for (const key of ["tau1_max", "tau2_max"]) $(key).addEventListener("change", () => { drawChart(); updateDownloads(); });
  $("duration").addEventListener("change", () => { simulateAt(point()); updateDownloads(); });
  $("play").addEventListener("click", () => {
    state.playing = !state.playing;
    $("play").textContent = state.playing ? "pause" : "play";
    if (state.playing && state.anim) state.anim.started = performance.now() - (state.anim.shown / state.anim.sim.times.length) * PLAY_SECONDS * 1000;
  });
  $("chart").addEventListener("click", (ev) => {
    const p = clickedDelays(ev);
    if (p) selectPoint(p);
  });
  await drawChart();
  selectPoint({ tau1: info.defaults.tau1, tau2: info.defaults.tau2 });
  requestAnimationFrame(tick);
}

init().catch((err) => say(err.message));
