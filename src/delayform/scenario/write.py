"""A :class:`~delayform.scenario.Scenario` written back as a TOML scenario file, beside where it is read.

The explorer's "download scenario" button saves what the user is looking at
(gains, delays, chart window, simulation length) as a file that
:func:`delayform.scenario.load_scenario` reads back to the same scenario, so
``delayform report scenario.toml`` reproduces the explorer's view. Only the
schema of :mod:`delayform.scenario` is written; every table is explicit, so
no default of a later version can change the meaning of a saved file.

Examples
--------
>>> import tomllib
>>> from delayform.scenario import paper_scenario, parse_scenario
>>> s = paper_scenario().with_changes(P=2.0, tau1=1.5)
>>> again = parse_scenario(tomllib.loads(scenario_toml(s)))
>>> again.summary()["P"], again.tau1, again.chart.points == s.chart.points
(2.0, 1.5, True)
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import fields

from delayform._validation import validated
from delayform.scenario.model import TOPOLOGY_NAMES, Scenario

__all__ = ["scenario_toml"]


def _string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = []
    for ch in text:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _number(value: float | int) -> str:
    # repr() of a float round-trips and always has "." or an exponent, as TOML wants
    return repr(int(value)) if isinstance(value, int) else repr(float(value))


def _array(values: Iterable[float | int]) -> str:
    return "[" + ", ".join(_number(v) for v in values) + "]"


def _rows(rows: Iterable[Iterable[float | int]]) -> str:
    return "[" + ", ".join(_array(r) for r in rows) + "]"


def _topology_lines(s: Scenario) -> list[str]:
    spec = s.topology_spec
    if spec.adjacency is not None:
        return [f"adjacency = {_rows(spec.adjacency)}"]
    if spec.edges is not None:
        return [f"edges = {_rows(spec.edges)}", f"n = {s.topology.n}"]
    if spec.name not in TOPOLOGY_NAMES:  # a topology built in Python: keep it as its adjacency matrix
        return [f"adjacency = {_rows(s.topology.adjacency_sparse.toarray().astype(int).tolist())}"]
    lines = [f"name = {_string(spec.name)}"]
    if spec.name != "paper_six":
        lines.append(f"n = {s.topology.n}")
    if spec.p is not None:
        lines.append(f"p = {_number(spec.p)}")
    if spec.seed is not None:
        lines.append(f"seed = {spec.seed}")
    return lines


def _network_lines(s: Scenario) -> list[str]:
    """The ``[network]`` table (delayform.scenario.parse_network_table reads it back)."""
    from delayform.model import BernoulliLoss, GilbertElliott

    net = s.network
    if net is None:
        return []
    out = ["", "[network]", f"seed = {net.seed}"]
    if net.delays is not None:
        if net.delays.spread:
            out.append(f"delay_spread = {_number(net.delays.spread)}")
        for key in ("tau1", "tau2"):
            matrix = getattr(net.delays, key)
            if matrix is not None:
                out.append(f"{key} = {_rows(matrix.tolist())}")
    if net.variation is not None:
        v = net.variation
        out.append(f"variation = {{ amplitude = {_array((v.amplitude1, v.amplitude2))}, period = {_number(v.period)} }}")
    if net.jitter is not None:
        out.append(f"jitter = {_array((net.jitter.bound1, net.jitter.bound2))}")
    if isinstance(net.loss, BernoulliLoss):
        p = net.loss.probability
        out.append(f"loss = {_number(p) if isinstance(p, float) else _rows(p.tolist())}")
    elif isinstance(net.loss, GilbertElliott):
        ge = net.loss
        fields = ("p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad")
        out.append("loss = { " + ", ".join(f"{k} = {_number(getattr(ge, k))}" for k in fields) + " }")
    if net.sampling is not None:
        out.append(f"rate = {_number(net.sampling.rate)}")
    if net.noise is not None:
        out.append(f"noise = {_array((net.noise.position, net.noise.velocity))}")
    return out


@validated()
def scenario_toml(scenario: Scenario) -> str:
    """The scenario as the text of a TOML scenario file.

    Parameters
    ----------
    scenario
        Any validated scenario (file, paper default, or with changes applied).

    Returns
    -------
    str
        A file that :func:`delayform.scenario.parse_scenario` reads back to
        the same gains, delays, team, formation and settings.
    """
    s = scenario
    out = [f"name = {_string(s.name)}", f"description = {_string(s.description)}", "", "[topology]"]
    out += _topology_lines(s)
    out += ["", "[gains]", f"P = {_number(s.P)}", f"D = {_number(s.D)}"]
    out += ["", "[delays]", f"tau1 = {_number(s.tau1)}", f"tau2 = {_number(s.tau2)}"]
    out += ["", "[formation]"]
    if s.formation.positions is not None:
        out.append(f"positions = {_rows(s.formation.positions)}")
    else:
        out += [f"shape = {_string(str(s.formation.shape))}", f"spacing = {_number(s.formation.spacing)}"]
    sim = s.simulation
    out += ["", "[simulation]", f"model = {_string(sim.model)}",
            f"duration = {_number(sim.duration)}", f"dt = {_number(sim.dt)}"]  # fmt: skip
    if sim.assignment != "given":
        out.append(f"assignment = {_string(sim.assignment)}")
    ini = s.initial
    out += ["", "[initial]", f"seed = {ini.seed}", f"speed = {_number(ini.speed)}"]
    if ini.positions is not None:
        out.append(f"positions = {_rows(ini.positions)}")
    if ini.headings is not None:
        out.append(f"headings = {_array(ini.headings)}")
    if s.robot is not None:  # actuator limits (delayform.simulation.RobotLimits)
        values = {f.name: getattr(s.robot, f.name) for f in fields(s.robot)}
        if s.radius is not None:  # the body's radius, which may be 0 (points) unlike a limit
            values["radius"] = s.radius
        out += ["", "[robot]"] + ([f"profile = {_string(s.robot_profile)}"] if s.robot_profile else [])
        out += [f"{k} = {_number(v)}" for k, v in values.items()]
    elif s.radius is not None or s.safety is not None or s.actuation_delay:
        out += ["", "[robot]", "limits = false"]
        if s.radius is not None:
            out.append(f"radius = {_number(s.radius)}")
    if s.safety is not None:
        out.append(f"safety = {_string(s.safety)}")
    if s.actuation_delay:  # [robot] actuation_delay: each robot applies its command that late
        out.append(f"actuation_delay = {_number(s.actuation_delay)}")
    chart = s.chart
    out += ["", "[chart]", f"tau1_max = {_number(chart.tau1_max)}", f"tau2_max = {_number(chart.tau2_max)}"]
    if chart.points:
        pts = ", ".join(f"{_string(label)} = {_array((a, b))}" for label, a, b in chart.points)
        out.append(f"points = {{ {pts} }}")
    grid = s.map
    out += ["", "[map]", f"tau1 = {_array(grid.tau1)}", f"tau2 = {_array(grid.tau2)}",
            f"size = {_array(grid.size)}"]  # fmt: skip
    sched = s.schedule
    out += ["", "[schedule]", f"tau_min = {_array(sched.tau_min)}", f"tau_max = {_array(sched.tau_max)}"]
    out += _network_lines(s)
    return "\n".join(out) + "\n"
