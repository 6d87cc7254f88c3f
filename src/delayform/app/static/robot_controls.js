// delayform explorer: the robot controls (actuation delay, safety filter, slot assignment).
// Loaded before explorer.js; explorer.js calls initRobotControls(info) once /api/scenario has
// answered and merges robotParams(path) into every request. The server checks every value
// (delayform/app/robot_controls.py): the analysis endpoints take the actuation delay only,
// runs and downloads take all three.
"use strict";

const ROBOT_RUN_PATHS = ["/api/simulate", "/api/guarantees", "/download/scenario.toml", "/download/figures.zip"];

function robotParams(path) {
  const box = document.getElementById("robot-actuation");
  if (!box) return {};
  const out = { actuation_delay: Number(box.value) };
  if (ROBOT_RUN_PATHS.includes(path)) {
    out.safety = document.getElementById("robot-safety").checked ? 1 : 0;
    out.assignment = document.getElementById("robot-assignment").checked ? 1 : 0;
  }
  return out;
}

function initRobotControls(info) {
  const host = document.getElementById("robot-controls");
  const rc = info.robot_controls;
  if (!host || !rc) return;
  host.innerHTML =
    `<label>actuation delay &tau;<sub>a</sub> (s) <input id="robot-actuation" type="number" min="0" ` +
    `max="${rc.max_actuation_delay}" step="0.01"></label>` +
    `<label><input type="checkbox" id="robot-safety"> safety filter (barrier)</label>` +
    `<label><input type="checkbox" id="robot-assignment"> optimal slot assignment</label>`;
  document.getElementById("robot-actuation").value = rc.defaults.actuation_delay;
  document.getElementById("robot-safety").checked = Boolean(rc.defaults.safety);
  document.getElementById("robot-assignment").checked = Boolean(rc.defaults.assignment);
  // the actuation delay changes the analysis: chart first, then the point (its verdict reads the chart's map)
  document.getElementById("robot-actuation").addEventListener("change", async () => {
    await drawChart(); selectPoint(point());
  });
  for (const id of ["robot-safety", "robot-assignment"]) {
    document.getElementById(id).addEventListener("change", () => { simulateAt(point()); updateDownloads(); });
  }
}
