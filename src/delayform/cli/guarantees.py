"""Guarantees for real networks: links, box, jitter.

Each command prints its certificate (text, or JSON with ``--json``) and writes
no file, so a rejected input leaves nothing behind. Per-link delays come from
``--tau1-file`` / ``--tau2-file``: an N x N matrix as CSV (comma-separated) or
``.npy``, entry ``[i, k]`` for what agent i receives from agent k.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click
import numpy as np

from delayform.cli._common import NON_NEGATIVE, FloatTuple, _scenario, cli, team_options, without_actuation

__all__ = ["links_command", "box_command", "jitter_command"]


def _matrix_file(path: Path | None, name: str) -> Any:
    """An N x N delay matrix from CSV or .npy, or None; one-line errors."""
    if path is None:
        return None
    import numpy as np

    from delayform.errors import DelayError

    if not path.is_file():
        raise DelayError(f"{name}: {path} is not a file")
    try:
        arr = np.load(path) if path.suffix == ".npy" else np.loadtxt(path, delimiter=",", ndmin=2)
    except (ValueError, OSError, EOFError) as exc:
        raise DelayError(f"{name}: {path} is not a matrix of numbers ({str(exc).splitlines()[0]})") from None
    from delayform._validation import real_numbers

    # a .npy of booleans (True read as 1 s) or of complex numbers (the imaginary part dropped) is refused
    return real_numbers(f"{name} {path}", arr, DelayError, "a matrix of real delays (seconds)")


def _delays(overrides: dict[str, Any], tau1_file: Path | None, tau2_file: Path | None) -> tuple[Any, Any, Any]:
    """The scenario and the delays each link has: a file, else --tau1 / --tau2, else the scenario's per-link ones."""
    for name, file in (("tau1", tau1_file), ("tau2", tau2_file)):
        if file is not None and overrides.get(name) is not None:  # one of the two would be ignored
            raise click.UsageError(f"--{name} and --{name}-file are two values of the same delays: give one")
    sc = _scenario(None if overrides.get("scenario") is None else overrides["scenario"],
                   **{k: v for k, v in overrides.items() if k != "scenario"})  # fmt: skip
    sc = without_actuation(sc, "the per-link and jitter certificates")
    files = (_matrix_file(tau1_file, "--tau1-file"), _matrix_file(tau2_file, "--tau2-file"))
    scenario_links = sc.link_delays
    out = []
    for k, name in enumerate(("tau1", "tau2")):
        if files[k] is not None:
            out.append(files[k])
        elif overrides.get(name) is not None:  # --tau1 puts one delay on every link
            out.append(overrides[name])
        else:
            out.append(scenario_links[k])
    spread_streams = [name for k, name in enumerate(("tau1", "tau2"))
                      if files[k] is None and overrides.get(name) is None and not np.ndim(scenario_links[k])]  # fmt: skip
    if sc.link_spread and spread_streams:
        from delayform.errors import ScenarioError

        raise ScenarioError(
            f"the scenario has network.delay_spread = {sc.link_spread:g}: its per-link {' and '.join(spread_streams)} "
            "are drawn per run, not one constant matrix; certify the whole spread with delayform box, or give "
            "--tau1-file / --tau2-file"
        )
    return sc, out[0], out[1]


def _not_covered(sc: Any) -> str | None:
    """What the scenario's network does beyond constant per-link delays (which these certificates do not model)."""
    net = sc.network
    if net is None or not (net.packets or (net.variation is not None and not net.variation.is_off)):
        return None
    from dataclasses import replace

    return replace(net, delays=None).describe(sc.topology.adjacency)


def _delay_options(func: Any) -> Any:
    for option in reversed([
        click.option("--tau1", type=NON_NEGATIVE, help="Position delay on every link (overrides the scenario)."),
        click.option("--tau2", type=NON_NEGATIVE, help="Velocity delay on every link (overrides the scenario)."),
        click.option("--tau1-file", type=click.Path(path_type=Path), help="Per-link position delays: N x N CSV or .npy."),
        click.option("--tau2-file", type=click.Path(path_type=Path), help="Per-link velocity delays: N x N CSV or .npy."),
    ]):  # fmt: skip
        func = option(func)
    return func


@cli.command("links")
@team_options
@_delay_options
def links_command(scenario: Path | None, as_json: bool, tau1_file: Path | None, tau2_file: Path | None,
                  **overrides: Any) -> None:  # fmt: skip
    """The certified dominant root with per-link constant delays (det of the N x N matrix)."""
    from delayform.analysis.network import link_dominant_root

    sc, t1, t2 = _delays({"scenario": scenario, **overrides}, tau1_file, tau2_file)
    r = link_dominant_root(sc.topology, sc.P, sc.D, t1, t2)
    extra = _not_covered(sc)
    summary = {"dominant_root": [r.root.real, r.root.imag], "stable": r.is_stable, "time_constant_s": r.time_constant if r.is_stable else None,
               "certified_line": r.line, "roots_right_of_line": r.count, "drift": r.drift, "not_covered": extra}  # fmt: skip
    if as_json:
        click.echo(json.dumps(summary, indent=2))
        return
    verdict = "stable" if r.is_stable else "UNSTABLE"
    click.echo(f"dominant root {r.root.real:.6f} {r.root.imag:+.6f}j: {verdict} "
               f"(certified: {r.count} roots right of Re s = {r.line:.4f}, the centroid's zero included)")  # fmt: skip
    if extra is not None:
        click.echo(f"for constant delays only: the scenario's network also has {extra} (see delayform montecarlo)")


@cli.command("box")
@team_options
@click.option("--tau1-box", type=FloatTuple(2, minimum=0.0), required=True, help="LO,HI of every position delay.")
@click.option("--tau2-box", type=FloatTuple(2, minimum=0.0), required=True, help="LO,HI of every velocity delay.")
def box_command(scenario: Path | None, as_json: bool, tau1_box: tuple[float, float], tau2_box: tuple[float, float],
                **overrides: Any) -> None:  # fmt: skip
    """Is the team stable for every constant per-link assignment in the box? (certified / unstable / undecided)."""
    from delayform.analysis.network import robust_stability

    sc = without_actuation(_scenario(scenario, **overrides), "the delay-box certificate")
    for name, (lo, hi) in (("--tau1-box", tau1_box), ("--tau2-box", tau2_box)):
        if lo > hi:
            raise click.BadParameter(f"LO = {lo:g} > HI = {hi:g}", param_hint=name)
    _require_inside(sc, tau1_box, tau2_box)
    r = robust_stability(sc.topology, sc.P, sc.D, tau1_box, tau2_box)
    if as_json:
        click.echo(json.dumps({"status": r.status, "method": r.method, "reason": r.reason, "margin": r.margin,
                               "checked": r.checked,
                               "witness_root": None if r.witness_root is None else [r.witness_root.real, r.witness_root.imag]},
                              indent=2))  # fmt: skip
        return
    click.echo(f"{r.status}: {r.method}" + (f"; {r.reason}" if r.reason else ""))


def _require_inside(sc: Any, tau1_box: tuple[float, float], tau2_box: tuple[float, float]) -> None:
    """Refuse a box that leaves out the scenario's own per-link delays: its certificate would not be about them."""
    from delayform.errors import ScenarioError

    for name, t, (lo, hi) in zip(("tau1", "tau2"), sc.link_delays, (tau1_box, tau2_box), strict=True):
        if np.ndim(t):
            on_links = sc.link_values(t, name)
            if on_links.size and (on_links.min() < lo or on_links.max() > hi):
                raise ScenarioError(
                    f"the scenario's per-link network.{name} ({on_links.min():g} to {on_links.max():g} s) is not "
                    f"inside --{name}-box [{lo:g}, {hi:g}]: that box's certificate would not be about this scenario"
                )


@cli.command("jitter")
@team_options
@_delay_options
@click.option("--method", type=click.Choice(["small-gain", "per-mode", "best"]), default="small-gain", show_default=True,
              help="small-gain: every link's delays varying on their own; per-mode: the same delays on every link "
                   "varying together (Lyapunov-Krasovskii per mode, slower); best: the larger of the two.")  # fmt: skip
@click.option("--certify", "certify", type=float, default=None, metavar="DELTA",
              help="Instead of the margin, certify this deviation (s): is every delay in [tau - DELTA, tau + DELTA], "
                   "varying arbitrarily fast, safe? Answered per link (small gain) and for the same delays on every "
                   "link (per mode, the richest certificate). One delay pair on every link.")  # fmt: skip
@click.pass_context
def jitter_command(ctx: click.Context, scenario: Path | None, as_json: bool, tau1_file: Path | None,
                   tau2_file: Path | None, method: str, certify: float | None, **overrides: Any) -> None:  # fmt: skip
    """The certified jitter margin: every delay may vary in [tau - delta, tau + delta], arbitrarily fast."""
    from delayform.analysis.certificates.team import COVERS
    from delayform.analysis.network import jitter_margin
    from delayform.errors import DelayError, InputError

    if certify is not None and ctx.get_parameter_source("method") is not click.core.ParameterSource.DEFAULT:
        raise click.UsageError("--certify answers for both kinds of variation: --method chooses a margin's search, give one")
    sc, t1, t2 = _delays({"scenario": scenario, **overrides}, tau1_file, tau2_file)
    if certify is not None:
        _certify_jitter(sc, t1, t2, certify, as_json)
        return
    if method != "small-gain" and (np.ndim(t1) or np.ndim(t2)):
        raise InputError(f"--method {method} needs one delay pair on every link (--tau1, --tau2): per-link delays "
                         "have the small-gain margin only")  # fmt: skip
    m = jitter_margin(sc.topology, sc.P, sc.D, t1, t2, method=method)
    if not m.nominal_stable:
        raise DelayError(f"the nominal delays are unstable (dominant root {m.nominal_root.real:.4g} "
                         f"{m.nominal_root.imag:+.4g}j): there is no jitter margin to certify")  # fmt: skip
    extra = _not_covered(sc)
    if as_json:
        click.echo(json.dumps({"delta_s": m.delta, "gain": None if m.reason else m.gain,
                               "peak_frequency": m.peak_frequency, "scaled": m.scaled, "method": m.method,
                               "covers": m.covers, "per_link_delta_s": m.per_link_delta,
                               "together_delta_s": None if m.together_delta != m.together_delta else m.together_delta,
                               "reason": m.reason, "not_covered": extra}, indent=2))  # fmt: skip
        return
    if m.reason:
        click.echo(f"jitter margin delta = 0 s: {m.reason}")
        return
    small = m.per_link_delta == m.delta and m.covers != COVERS
    gain = f"; loop gain <= {m.gain:.4g}" if small else ""
    click.echo(f"jitter margin delta = {m.delta:.4g} s ({m.method}{gain})")
    click.echo(f"covers {m.covers}")
    if not small:  # the per-mode margin proves more, but only for delays varying together
        click.echo(f"per link, each delay varying on its own: {m.per_link_delta:.4g} s (small gain, loop gain "
                   f"<= {m.gain:.4g}); the per-mode margin does not cover independent per-link variations")  # fmt: skip
    if extra is not None:
        click.echo(f"the margin is around the constant per-link delays; the scenario's network has {extra}")


def _certify_jitter(sc: Any, t1: Any, t2: Any, delta: float, as_json: bool) -> None:
    """``jitter --certify``: the deviation checked per link (small gain) and per mode (the same delays on every link).

    Per link the small-gain margin is computed and compared (its certificate covers every smaller
    deviation); per mode :func:`~delayform.analysis.certificates.team.certify_team_delays` certifies
    delta itself with the richest functional (the windows over the delays' intervals, used only for
    a mode the cheaper ones do not certify).
    """
    import math

    from delayform.analysis.certificates.team import COVERS, certify_team_delays
    from delayform.analysis.network import jitter_margin
    from delayform.analysis.network.jitter import PER_LINK
    from delayform.errors import DelayError, InputError

    if np.ndim(t1) or np.ndim(t2):
        raise InputError("--certify needs one delay pair on every link (--tau1, --tau2): per-link delays have the "
                         "small-gain margin only (delayform jitter without --certify)")  # fmt: skip
    if not (math.isfinite(delta) and 0.0 < delta < float(t1)):
        raise DelayError(f"--certify must be a deviation in (0, tau1 = {float(t1):g}) s, got {delta:g}")
    small = jitter_margin(sc.topology, sc.P, sc.D, t1, t2)
    if not small.nominal_stable:
        raise DelayError(f"the nominal delays are unstable (dominant root {small.nominal_root.real:.4g} "
                         f"{small.nominal_root.imag:+.4g}j): no deviation of them is safe")  # fmt: skip
    per_link = small.delta >= delta
    team = None
    if not per_link:  # the same delays on every link: a smaller class, per mode
        team = certify_team_delays(sc.topology, sc.P, sc.D, float(t1), float(t2), delta, cover_intervals=True)
    together = per_link or (team is not None and team.delta == delta)
    limiting = None if team is None or team.limiting is None else next(
        (md.functional for md in team.modes if md.lam == team.limiting), None)  # fmt: skip
    if as_json:
        click.echo(json.dumps({"delta_s": delta, "per_link": per_link, "per_link_margin_s": small.delta,
                               "together": together, "together_method": limiting,
                               "together_reason": None if team is None else team.reason,
                               "covers": {"per_link": PER_LINK, "together": COVERS}}, indent=2))  # fmt: skip
        return
    verdict = "certified" if per_link else "not certified"
    click.echo(f"+-{delta:g} s per link, each delay varying on its own: {verdict} "
               f"(small-gain margin {small.delta:.4g} s)")  # fmt: skip
    if per_link:
        click.echo(f"+-{delta:g} s with the same delays on every link: certified (a special case)")
    elif together:
        click.echo(f"+-{delta:g} s with the same delays on every link, varying together: certified, every mode "
                   f"re-checked exactly (the limiting mode by {limiting})")  # fmt: skip
    else:
        click.echo(f"+-{delta:g} s with the same delays on every link, varying together: not certified "
                   f"({team.reason}); a certificate is a sufficient condition, so not unsafe either")  # type: ignore[union-attr]  # fmt: skip
