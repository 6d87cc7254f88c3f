"""The page of a fleet run: what happened beside what was promised (``summary.json``, ``summary.txt``, a figure)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from delayform._files import write_text
from delayform.fleet.outcome import FIT_WINDOW, FLOOR_MARGIN, FLOOR_TAIL, LATE_FRACTION, FleetRun
from delayform.report._common import Figure, Section, _fmt, _pyplot, _save, jsonable

__all__ = ["fleet_section", "fleet_text"]


def _window_span(w: dict[str, Any]) -> str:
    """A fit window as ``t0-t1 s (e0 -> e1 m)``, or why there is none."""
    if not w["samples"]:
        return "none: the error never fell in the linear phase above its floor"
    return (f"{_fmt(w['start_s'])}-{_fmt(w['stop_s'])} s ({_fmt(w['start_error_m'])} -> "
            f"{_fmt(w['stop_error_m'])} m)")


def _window_sentence(t: dict[str, Any]) -> str:
    """How the decay was fitted, with the fleet's window."""
    w = t["decay_window"]
    sat = w["saturated_until_s"]
    after = "no command was ever saturated" if sat is None or not math.isfinite(sat) else \
        f"the last saturated command at {_fmt(sat)} s"
    return (f"The decay is fitted to log error over the linear phase: after the last control tick a robot's limits "
            f"changed ({after}), below {FIT_WINDOW[0]:g} of the initial error, above {FLOOR_MARGIN:g} x the floor "
            f"(the error over the run's last {FLOOR_TAIL:.0%}: {_fmt(w['floor_m'])} m) and above "
            f"{FIT_WINDOW[1]:g} of the initial error; fleet: {_window_span(w)}, simulator: "
            f"{_window_span(t['simulator_decay_window'])}." + _short_window(t))


def _short_window(t: dict[str, Any]) -> str:
    """The warning of a fit window too short for its slope to be the dominant root's decay ('' when long enough)."""
    w, need = t["decay_window"], t["decay_window_needed_s"]
    if not w["samples"] or need is None or not math.isfinite(need) or w["stop_s"] - w["start_s"] >= need:
        return ""
    return (f" The window ({_fmt(w['stop_s'] - w['start_s'], 3)} s) is shorter than the {_fmt(need, 3)} s (one time "
            "constant and half an oscillation of the dominant root) over which a slope measures the root: the "
            "ratio does not test it; start nearer the shape for a measurable linear phase.")

def _ms(value: float | None) -> str:
    return "n/a" if value is None else _fmt(1e3 * value, 3) + " ms"


def fleet_text(run: FleetRun, name: str) -> str:
    """The one-page summary of a run as plain text (the tables of :func:`fleet_section`, every link and robot).

    Parameters
    ----------
    run
        The measured run.
    name
        The scenario's name, for the title.
    """
    s = jsonable(run.summary)
    r, t = s["run"], s["team"]
    h = r["period"]
    lines = [f"delayform fleet: {name}", "",
             f"{r['robots']} robot processes and a {r['world']} world over Zenoh ({r['endpoint']}"
             + (f"; also as rmw_zenoh on ROS domain {r['ros_domain']}" if r.get("ros_domain") is not None else "")
             + "), "
             f"P = {r['P']:g}, D = {r['D']:g}, (tau1, tau2) = ({r['tau1']:g}, {r['tau2']:g}) s, "
             f"control period {h:g} s, {r['duration']:g} s of wall clock; network: {r['network']}; "
             f"robots: {r['limits'] or 'ideal'}.", "",
             "Promised (exact analysis at the same delays) beside measured", ""]  # fmt: skip
    nominal = " (nominal pair; the links have their own delays)" if t.get("per_link_delays") else ""
    rows = [("chart's verdict at (tau1, tau2)", t["chart_verdict"] + nominal, ""),
            ("decay rate of the formation error (1/s)", _fmt(t["dominant_decay_rate"]) + " (dominant root)",
             _fmt(t["measured_decay_rate"]) + f" (fleet, linear phase; ratio {_fmt(t['decay_ratio'])}); "
             f"simulator {_fmt(t['simulator_decay_rate'])}"),
            ("formation error (m)", f"from {_fmt(t['initial_error_m'])}", f"to {_fmt(t['final_error_m'])}"),
            ("settling time (s)", _fmt(t["simulator_settling_time_s"]) + " (simulator)", _fmt(t["settling_time_s"])),
            ("closest approach (m)", _fmt(t["simulator_closest_approach_m"]) + " (simulator)", _fmt(t["closest_approach_m"])),
            ("control ticks missed / late", "0", f"{t['ticks_missed']} / {t['ticks_late']}"),
            ("state messages dropped by the network", f"rate {_fmt(t['network_loss_rate'])}",
             f"{t['messages_dropped_by_network']} (rate {_fmt(t['network_drop_rate'])})"),
            ("state messages lost in transport", "0", str(t["messages_lost_in_transport"]))]  # fmt: skip
    width = max(len(a) for a, _, _ in rows)
    lines += [f"  {a:<{width}}  {b:<28}  {c}" for a, b, c in rows]
    lines += ["", _window_sentence(t), f"A tick is late when it wakes more than {LATE_FRACTION:g} period after its deadline.", "",
              "Per link (receiver <- informer): network latency, delays applied by the playout buffer "
              "(median / max), messages sent, received, dropped", ""]  # fmt: skip
    for link in s["links"]:
        lines.append(f"  {link['receiver']} <- {link['informer']}: design ({_ms(link['design_tau1_s'])}, "
                     f"{_ms(link['design_tau2_s'])}); latency {_ms(link['latency_s']['median'])} "
                     f"(p99 {_ms(link['latency_s']['p99'])}); tau1 {_ms(link['applied_tau1_s']['median'])} / "
                     f"{_ms(link['applied_tau1_s']['max'])}, tau2 {_ms(link['applied_tau2_s']['median'])} / "
                     f"{_ms(link['applied_tau2_s']['max'])}; {link['sent']} sent, {link['received']} received, "
                     f"{link['dropped_by_network']} dropped")  # fmt: skip
    lines += ["", "Per robot: ticks run / expected, missed, late; lateness median / p99 / max; tick compute p99", ""]
    for rb in s["robots"]:
        lines.append(f"  robot {rb['robot']}: {rb['ticks_run']} / {rb['ticks_expected']}, {rb['ticks_missed']} missed, "
                     f"{rb['ticks_late']} late; {_ms(rb['lateness_s']['median'])} / {_ms(rb['lateness_s']['p99'])} / "
                     f"{_ms(rb['lateness_s']['max'])}; {_ms(rb['compute_s']['p99'])}"
                     + (f"; stopped: {rb['error']}" if rb["error"] else ""))  # fmt: skip
    lines += _fault_lines(s)
    w = r["world_lateness_s"]
    lines += ["", f"World: {r['commands_applied']} commands applied; odometry lateness median {_ms(w['median'])}, "
                  f"p99 {_ms(w['p99'])}, max {_ms(w['max'])}. Recording: {Path(r['recording']).name}."]  # fmt: skip
    return "\n".join(lines) + "\n"


def _fault_lines(s: dict[str, Any]) -> list[str]:
    """The faults of a run and, per robot they silenced, for how long (none: no lines)."""
    faults = s["run"].get("faults") or []
    if not faults:
        return []
    lines = ["", "Faults (robot processes killed by SIGKILL, started again): "
             + "; ".join(f"{f['action']} robot {f['robot']} at {_fmt(f['at_s'], 4)} s" for f in faults), ""]  # fmt: skip
    for rb in s["robots"]:
        for gap in rb["silent"]:
            again = gap["heard_again_s"]
            lines.append(f"  robot {rb['robot']} silent from {_fmt(gap['last_heard_s'], 4)} s to "
                         + (f"{_fmt(again, 4)} s" if again is not None else "the end")
                         + f": {_fmt(gap['silent_s'], 4)} s (killed at {_fmt(gap['killed_at_s'], 4)} s"
                         + (f", restarted at {_fmt(gap['restarted_at_s'], 4)} s" if gap["restarted_at_s"] is not None else "")
                         + "); its neighbours held its last message")  # fmt: skip
        if rb["rejoin_waits_for"]:
            lines.append(f"  robot {rb['robot']} restarted but never ticked: it never heard from "
                         + ", ".join(f"robot {k}" for k in rb["rejoin_waits_for"]))  # fmt: skip
    stopped = s["team"].get("stopped_by_command_timeout") or []
    if stopped:
        lines.append("  stopped by the world's command timeout: "
                     + ", ".join(f"robot {int(a)} at {_fmt(b, 4)} s" for a, b in stopped))  # fmt: skip
    return lines


def fleet_section(run: FleetRun, name: str, out: Path) -> Section:
    """Write ``summary.json``, ``summary.txt`` and ``fleet_error.png/.svg`` of a run; its section for the command line.

    Parameters
    ----------
    run
        The measured run.
    name
        The scenario's name.
    out
        The output folder (where the run wrote ``fleet.mcap``).
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    run.plot(ax=ax)
    ax.set_title(f"Formation error: {name}, fleet and simulator")
    files = list(_save(fig, out, "fleet_error"))
    summary = jsonable(run.summary)
    write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    write_text(out / "summary.txt", fleet_text(run, name))
    files += ["summary.json", "summary.txt", Path(run.summary["run"]["recording"]).name]
    t = run.summary["team"]
    table = (("chart's verdict", t["chart_verdict"]),
             ("decay rate: dominant root / fleet / simulator", f"{_fmt(t['dominant_decay_rate'])} / "
              f"{_fmt(t['measured_decay_rate'])} / {_fmt(t['simulator_decay_rate'])} 1/s"),
             ("decay fitted over (linear phase)", _window_span(t["decay_window"])),
             ("formation error", f"{_fmt(t['initial_error_m'])} m -> {_fmt(t['final_error_m'])} m"),
             ("settling time: fleet / simulator", f"{_fmt(t['settling_time_s'])} / {_fmt(t['simulator_settling_time_s'])} s"),
             ("closest approach: fleet / simulator", f"{_fmt(t['closest_approach_m'])} / {_fmt(t['simulator_closest_approach_m'])} m"),
             ("ticks missed / late", f"{t['ticks_missed']} / {t['ticks_late']}"),
             ("messages dropped by the network / lost in transport", f"{t['messages_dropped_by_network']} / {t['messages_lost_in_transport']}"))  # fmt: skip
    silent = [f"robot {rb['robot']}: " + ", ".join(f"{_fmt(g['silent_s'], 3)} s" for g in rb["silent"])
              for rb in run.summary["robots"] if rb["silent"]]  # fmt: skip
    if silent:
        table += (("silent robots (faults)", "; ".join(silent)),)
    figure = Figure("fleet_error", "Formation error, fleet and simulator",
                    "The formation error of the robots' true states (world process) and of the simulator at the same "
                    "delays, with the dominant root's decay.")  # fmt: skip
    return Section(key="fleet", title=f"Fleet run: {name}", text="", figures=(figure,), table=table,
                   summary=summary, files=tuple(files))  # fmt: skip
