// delayform explorer: the certified jitter-margin layer. A toggle under "Chart window"
// asks /api/jitter_map for the margin on the chart's window and draws it as labelled contour lines
// over the stable region; the chart's own redraw (Plotly.react) drops the trace, so it is drawn
// again each time the chart is ready. Uses $, num, gains, say and fmt from explorer.js.
"use strict";

const jitterLayer = { seq: 0, name: "jitter margin (s)" };

function jitterLayerControls() {
  const host = $("tau2_max").closest("fieldset");
  const label = document.createElement("label");
  label.innerHTML = '<input id="jitter-layer" type="checkbox"> jitter margin (certified)';
  const status = document.createElement("p");
  status.id = "jitter-layer-status";
  status.className = "note";
  host.append(label, status);
  $("jitter-layer").addEventListener("change", drawJitterLayer);
  // the chart was redrawn (new gains or window): its traces were replaced, draw the layer again
  new MutationObserver(drawJitterLayer).observe(document.body, { attributes: true, attributeFilter: ["data-chart-ready"] });
}

function removeJitterTrace() {
  const gd = $("chart");
  const at = (gd.data || []).findIndex((t) => t.name === jitterLayer.name);
  if (at >= 0) Plotly.deleteTraces(gd, at);
}

async function drawJitterLayer() {
  const seq = ++jitterLayer.seq;
  const status = $("jitter-layer-status");
  if (!$("jitter-layer").checked) {
    removeJitterTrace();
    status.textContent = "";
    delete document.body.dataset.jitterReady;
    return;
  }
  if (!document.body.dataset.chartReady) return;  // the chart's first draw will call again
  status.textContent = "computing the certified margin\u2026";
  const params = { ...gains(), tau1_max: num("tau1_max"), tau2_max: num("tau2_max") };
  let m;
  try {
    m = await getJSON("/api/jitter_map", params);
  } catch (err) {
    if (seq === jitterLayer.seq) { status.textContent = `jitter margin: ${err.message}`; removeJitterTrace(); }
    return;
  }
  if (seq !== jitterLayer.seq || !$("jitter-layer").checked) return;
  removeJitterTrace();
  if (m.levels.length) {
    const size = m.levels.length > 1 ? m.levels[1] - m.levels[0] : m.levels[0];
    await Plotly.addTraces("chart", {
      type: "contour", name: jitterLayer.name, x: m.tau1, y: m.tau2, z: m.delta, connectgaps: false,
      showscale: false, colorscale: "Viridis", line: { width: 1.5 }, showlegend: true,
      contours: { coloring: "lines", showlabels: true, start: m.levels[0], end: m.levels[m.levels.length - 1], size,
                  labelfont: { size: 10 } },
      hovertemplate: "\u03b4 = %{z:.3f} s certified<extra></extra>",
    });
  }
  status.textContent = m.levels.length
    ? `largest \u00b1${fmt(m.largest, 3)} s at (${fmt(m.largest_at[0], 2)}, ${fmt(m.largest_at[1], 2)}): ${m.method}`
    : "nothing certified in this window (no stable point on the grid)";
  document.body.dataset.jitterReady = `${params.tau1_max},${params.tau2_max},${m.levels.length}`;
}

jitterLayerControls();
