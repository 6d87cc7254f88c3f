// delayform explorer: the page. Every number comes from the server's /api endpoints;
// this script only draws them (Plotly, served by the same server) and animates the robots.
"use strict";

const $ = (id) => document.getElementById(id);
const state = {
  defaults: {}, limits: {}, toggles: [], points: [],
  chartSeq: 0, pointSeq: 0, simSeq: 0,
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
  const query = new URLSearchParams(params).toString();
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
  say("");
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
    title: { text: `Exact CTCR stability chart (P = ${params.P}, D = ${params.D}); green: stable, ` +
      `red: NU > 0 (stable fraction ${(100 * chart.stable_fraction).toFixed(1)}%)`, font: { size: 13 } },
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
  // the robots' run starts once the verdict is in, so it does not slow the click's answer
  simulateAt(p);
  const ms = performance.now() - started;
  $("verdict").textContent = r.stable ? "stable" : "unstable";
  $("verdict").className = `verdict ${r.stable ? "stable" : "unstable"}`;
  $("unstable-count").textContent = String(r.unstable_count);
  $("dominant-root").textContent = complexText(r.dominant_root[0], r.dominant_root[1]);
  $("time-constant").textContent = r.time_constant === null ? "\u221e" : `${fmt(r.time_constant, 2)} s`;
  $("dominant-factor").textContent = r.dominant_factor;
  $("point-ms").textContent = `${ms.toFixed(0)} ms`;
  document.body.dataset.pointMs = ms.toFixed(1);
  document.body.dataset.point = `${p.tau1},${p.tau2}`;
  drawRoots(r);
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

// ------------------------------------------------------------------ robots
async function simulateAt(p) {
  const seq = ++state.simSeq;
  $("sim-info").textContent = "simulating\u2026";
  let sim;
  try {
    sim = await getJSON("/api/simulate", { ...p, ...gains(), duration: num("duration"), ...toggleParams() });
  } catch (err) { if (seq === state.simSeq) { $("sim-info").textContent = ""; say(`robots: ${err.message}`); } return; }
  if (seq !== state.simSeq) return;
  startAnimation(sim);
}

function startAnimation(sim) {
  const settle = sim.settling_time === null ? "not settled" : `settles at ${fmt(sim.settling_time, 1)} s`;
  const diverged = sim.diverged_at === null ? "" : `; overflowed at ${fmt(sim.diverged_at, 1)} s`;
  $("sim-info").textContent = `${sim.n} ${sim.model} robots, ${settle}${diverged}`;
  const err = sim.formation_error.map((e) => Math.max(e, 1e-12));
  Plotly.react("error", [{ type: "scatter", mode: "lines", x: sim.times, y: err, name: "formation error",
    line: { color: "#333" } }], {
    title: { text: "formation error (RMS distance from the shape)", font: { size: 12 } },
    xaxis: { title: { text: "time (s)" } }, yaxis: { type: "log" },
    shapes: [{ type: "line", x0: 0, x1: 0, yref: "paper", y0: 0, y1: 1, line: { color: "#d7301f" } }],
    margin: { l: 50, r: 5, t: 25, b: 35 }, showlegend: false,
  }, { displaylogo: false, responsive: true });
  state.anim = { sim, frame: 0, started: performance.now(), shown: -1 };
  document.body.dataset.simPoint = `${sim.tau1},${sim.tau2}`;
  drawFrame(0);
}

function drawFrame(k) {
  const a = state.anim;
  const sim = a.sim;
  const n = sim.n;
  const px = [], py = [];
  for (let i = 0; i < n; i++) {
    for (let j = 0; j <= k; j++) { px.push(sim.x[j][i]); py.push(sim.y[j][i]); }
    px.push(null); py.push(null);
  }
  // heading theta is counter-clockwise from +x; Plotly turns markers clockwise from "up"
  const angle = sim.heading[k].map((th) => 90 - (th * 180) / Math.PI);
  const data = [
    { type: "scatter", mode: "lines", x: px, y: py, name: "paths", line: { color: "#9ab", width: 1 }, hoverinfo: "skip" },
    { type: "scatter", mode: "markers", x: sim.desired_final.map((q) => q[0]), y: sim.desired_final.map((q) => q[1]),
      name: "formation (final offset)", marker: { symbol: "circle-open", size: 14, color: "#2a2" }, hoverinfo: "skip" },
    { type: "scatter", mode: "markers+text", x: sim.x[k], y: sim.y[k], text: sim.labels, textposition: "top center",
      name: "robots", marker: { symbol: "triangle-up", size: 15, angle, color: "#d7301f" }, hoverinfo: "skip" },
  ];
  const layout = {
    title: { text: `robots (unicycles with headings) at t = ${fmt(sim.times[k], 1)} s`, font: { size: 12 } },
    xaxis: { title: { text: "x" }, autorange: true }, yaxis: { title: { text: "y" }, scaleanchor: "x", autorange: true },
    margin: { l: 45, r: 5, t: 25, b: 35 }, showlegend: true, legend: { font: { size: 9 } },
  };
  Plotly.react("robots", data, layout, { displaylogo: false, responsive: true });
  Plotly.relayout("error", { "shapes[0].x0": sim.times[k], "shapes[0].x1": sim.times[k] });
  $("sim-time").textContent = `t = ${fmt(sim.times[k], 1)} s`;
  document.body.dataset.simTime = String(sim.times[k]);
  a.shown = k;
}

// about ten seconds per run, then it starts again; ~20 drawn frames per second
const PLAY_SECONDS = 10;
function tick(now) {
  const a = state.anim;
  if (a && state.playing) {
    const frames = a.sim.times.length;
    // rAF's timestamp can precede the moment the run arrived: clamp at the first frame
    const elapsed = Math.max(0, now - a.started) / 1000;
    const k = Math.floor((elapsed / PLAY_SECONDS) * frames) % (frames + 20);
    const target = Math.min(k, frames - 1);
    if (target !== a.shown && now - (a.lastDraw || 0) > 45) { a.lastDraw = now; drawFrame(target); }
  }
  requestAnimationFrame(tick);
}

// ------------------------------------------------------------------ controls
function downloadParams() {
  return new URLSearchParams({ ...point(), ...gains(), duration: num("duration"),
    tau1_max: num("tau1_max"), tau2_max: num("tau2_max") }).toString();
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

function bindGain(name) {
  const redraw = debounce(() => { drawChart(); selectPoint(point()); }, 250);
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
  state.toggles = info.toggles || [];
  for (const t of state.toggles) {
    const label = document.createElement("label");
    label.innerHTML = `<input type="checkbox" id="toggle-${t}"> ${t === "limits" ? "actuator limits" : "network imperfections"}`;
    $("toggles").appendChild(label);
    label.querySelector("input").addEventListener("change", () => simulateAt(point()));
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
