// delayform explorer: what is guaranteed beside what the robots' run observed. After each
// run (explorer.js sets data-sim-point) it asks /api/guarantees with the run's own parameters and
// lists the certificates for its network, the run's status, and in red any contradiction: a run
// that diverged where a certificate holds is a bug. Uses $, gains, num, toggleParams from explorer.js.
"use strict";

const sideBySide = { seq: 0 };

function sideBySideControls() {
  const panel = $("point-panel");
  const box = document.createElement("div");
  box.id = "side-by-side";
  box.innerHTML = '<h3>Guaranteed vs observed (robots\u2019 run)</h3><table id="side-by-side-table"></table>';
  panel.insertBefore(box, $("roots"));
  new MutationObserver(drawSideBySide).observe(document.body, { attributes: true, attributeFilter: ["data-sim-point"] });
}

function sideRow(table, head, text, cls) {
  const tr = table.insertRow();
  const th = document.createElement("th");
  th.textContent = head;
  tr.append(th);
  const td = tr.insertCell();
  td.textContent = text;
  if (cls) { td.style.color = "#b00"; td.style.fontWeight = cls === "bug" ? "700" : "400"; }
}

async function drawSideBySide() {
  const seq = ++sideBySide.seq;
  const where = (document.body.dataset.simPoint || "").split(",").map(Number);
  if (where.length !== 2) return;
  const table = $("side-by-side-table");
  let r;
  try {
    r = await getJSON("/api/guarantees", { tau1: where[0], tau2: where[1], ...gains(), duration: num("duration"),
                                           ...toggleParams() });
  } catch (err) {
    if (seq === sideBySide.seq) { table.innerHTML = ""; sideRow(table, "certificates", err.message); }
    return;
  }
  if (seq !== sideBySide.seq) return;
  table.innerHTML = "";
  const word = { true: "guaranteed", false: "proven unstable", null: "not covered" };
  for (const bug of r.contradictions) sideRow(table, "BUG", bug, "bug");
  if (!r.guarantees.length) sideRow(table, "certificates", "not computed for a team this large");
  for (const g of r.guarantees) sideRow(table, g.name, `${word[g.holds]}: ${g.detail}`, g.holds === false ? "unstable" : "");
  const o = r.observed;
  sideRow(table, "observed", o.status + (o.settling_time === null ? "" : `, settled at ${o.settling_time.toFixed(1)} s`)
    + `, final error ${o.final_error.toPrecision(3)}`);
  document.body.dataset.sideBySide = `${where[0]},${where[1]},${r.guarantees.length},${r.contradictions.length}`;
}

sideBySideControls();
