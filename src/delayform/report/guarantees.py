"""What is guaranteed beside what was observed.

:func:`network_guarantees` lists the certificates of
:mod:`delayform.analysis.network` that apply to a scenario's network: the exact
per-link dominant root for per-link constant delays, the jitter margin for jitter
and smooth variations, exact mean-square stability for independent loss with
sampling and delays that are whole multiples of the period, and for bursty
(Gilbert-Elliott) loss on small teams (:mod:`delayform.analysis.network.bursty`). :func:`contradictions`
sets them against Monte Carlo runs: a run that diverges where a certificate says
stable is a bug (of the certificate or of the simulator), never an accepted outcome.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Guarantee", "network_guarantees", "contradictions", "guarantee_rows", "summary_of", "with_actuator_limits",
           "with_actuation_delay", "bug_rows"]


@dataclass(frozen=True)
class Guarantee:
    """One certificate about the scenario's network.

    Attributes
    ----------
    name
        What is certified.
    holds
        True when it guarantees the runs converge; False when it proves
        instability; None when it does not cover this network.
    detail
        One sentence with the numbers.
    """

    name: str
    holds: bool | None
    detail: str


def _link_delays(net: Any, tau1: float, tau2: float) -> tuple[Any, Any]:
    d = getattr(net, "delays", None)
    if d is None or (d.tau1 is None and d.tau2 is None):
        return tau1, tau2
    return (tau1 if d.tau1 is None else d.tau1), (tau2 if d.tau2 is None else d.tau2)


def network_guarantees(topology: Any, P: float, D: float, tau1: float, tau2: float, network: Any,
                       *, dt: float = 0.0) -> tuple[Guarantee, ...]:  # fmt: skip
    """The certificates that apply to ``network`` (a :class:`~delayform.model.network.Network` or None).

    Parameters
    ----------
    topology, P, D, tau1, tau2
        The team, its gains and its nominal delays.
    network
        The simulated network; None is the ideal one.
    dt
        The simulation's step: without sampling, packets (jitter, loss, noise) are sent every
        step, so a held value can be one step older than its delay; the jitter margin is then
        asked for the widened interval.
    """
    from delayform.errors import NotConvergedError

    try:
        return _guarantees(topology, P, D, tau1, tau2, network, dt)
    except NotConvergedError as exc:  # a certificate that did not converge certifies nothing
        return (Guarantee("certificates", None, f"could not be computed: {exc}"),)


def _on(network: Any, part: str) -> bool:
    value = getattr(network, part, None)
    return value is not None and not value.is_off


def _guarantees(topology: Any, P: float, D: float, tau1: float, tau2: float, network: Any,
                dt: float) -> tuple[Guarantee, ...]:  # fmt: skip
    from delayform.analysis.network import link_dominant_root

    out: list[Guarantee] = []
    t1, t2 = _link_delays(network, tau1, tau2)
    delays = getattr(network, "delays", None)
    spread = (getattr(delays, "spread", 0.0) or 0.0) if delays is not None else 0.0
    # the simulator spreads only the streams without a delay matrix
    spreads = (spread if delays is None or delays.tau1 is None else 0.0, spread if delays is None or delays.tau2 is None else 0.0)
    sampling = getattr(network, "sampling", None)
    lossy, noisy = _on(network, "loss"), _on(network, "noise")
    timed = _on(network, "jitter") or _on(network, "variation")
    constant = not (any(spreads) or timed or lossy or noisy or sampling is not None)
    root = link_dominant_root(topology, P, D, t1, t2)
    # the nominal root covers the runs only when their delays are those constants; instability it proves anyway
    out.append(Guarantee("constant delays (exact, per link)", root.is_stable if constant else (None if root.is_stable else False),
                         f"dominant root {root.root.real:.4g} {root.root.imag:+.4g}j, certified"
                         + ("" if constant else " (covers the nominal constant delays only)")))  # fmt: skip
    if any(spreads):
        out.append(_box(topology, P, D, t1, t2, spreads, covers=not (timed or lossy or noisy or sampling is not None)))
    if timed and root.is_stable:
        out.append(_jitter(topology, P, D, t1, t2, network, spreads, dt))
    if sampling is not None or lossy:
        if sampling is None or timed or any(spreads) or noisy:
            out.append(Guarantee("sampling and loss (mean square)", None,
                                 "exact only for Sampling with independent (Bernoulli) or Gilbert-Elliott loss, "
                                 "without jitter, variation, spread or noise"))  # fmt: skip
        else:
            out.append(_mean_square(topology, P, D, t1, t2, sampling.rate, getattr(network, "loss", None)))
    return tuple(out)


def _box(topology: Any, P: float, D: float, t1: Any, t2: Any, spreads: tuple[float, float], *, covers: bool) -> Guarantee:
    """The box certificate for per-link delays drawn in tau (1 +- spread) (constant within a run)."""
    import numpy as np

    from delayform.analysis.network import robust_stability

    boxes = [(np.asarray(t) * (1.0 - s), np.asarray(t) * (1.0 + s)) if s else (t, t) for t, s in zip((t1, t2), spreads, strict=True)]
    r = robust_stability(topology, P, D, boxes[0], boxes[1])
    where = f"every per-link delay in tau (1 +- {max(spreads):g})"
    if r.status == "certified":
        return Guarantee("per-link delays in a box (certified)", True if covers else None,
                         f"{where}: stable for every assignment ({r.method})"
                         + ("" if covers else "; covers constant per-link delays only"))  # fmt: skip
    why = r.reason or r.status
    return Guarantee("per-link delays in a box", None, f"{where}: {r.status} ({why})")


def _jitter(topology: Any, P: float, D: float, t1: Any, t2: Any, network: Any, spreads: tuple[float, float], dt: float) -> Guarantee:
    """The jitter margin against the network's whole deviation from the nominal delays.

    A held value's age lies in ``[tau - b - a, tau + b + a + hold]`` (jitter b, variation a, hold:
    the packet period when streams are packets, else 0) and a spread per-link delay is a constant
    deviation of up to ``spread tau``: all of it is within +-delta of ``tau + hold / 2`` when
    ``spread tau + b + a + hold / 2 <= delta`` there (constant deviations are time-varying ones).
    """
    import numpy as np

    from delayform.analysis.network import jitter_margin

    jit, var = getattr(network, "jitter", None), getattr(network, "variation", None)
    own = [(getattr(jit, f"bound{k}", 0.0) if _on(network, "jitter") else 0.0)
           + (getattr(var, f"amplitude{k}", 0.0) if _on(network, "variation") else 0.0) for k in (1, 2)]  # fmt: skip
    sampling = getattr(network, "sampling", None)
    hold = 1.0 / sampling.rate if sampling is not None else (dt if network.packets else 0.0)
    offsets = [s * float(np.max(t)) for t, s in zip((t1, t2), spreads, strict=True)]
    size = max(o + b for o, b in zip(offsets, own, strict=True)) + hold / 2.0
    m = jitter_margin(topology, P, D, np.asarray(t1) + hold / 2.0, np.asarray(t2) + hold / 2.0)
    lossy, noisy = _on(network, "loss"), _on(network, "noise")
    covered = size <= m.delta and not lossy and not noisy
    why = ("covered" if covered else "not covered (loss: a held value can age without bound)" if lossy
           else "not covered (measurement noise is outside the certificate)" if noisy else "not covered")
    return Guarantee("time-varying delays (jitter margin)", True if covered else None,
                     f"certified for any variation within +-{m.delta:.4g} s about tau + {hold / 2:.3g} s; this network "
                     f"deviates by up to +-{size:.4g} s (jitter and variation"
                     + (", spread" if any(offsets) else "") + (f", half the {hold:g} s packet period" if hold else "")
                     + f"): {why}")  # fmt: skip


def _mean_square(topology: Any, P: float, D: float, t1: Any, t2: Any, rate: float, loss: Any) -> Guarantee:
    """The exact mean-square certificate for sampled links with Bernoulli or Gilbert-Elliott loss."""
    from delayform.analysis.network import bursty_mean_square_stability, mean_square_stability
    from delayform.model import BernoulliLoss, GilbertElliott

    bursty = isinstance(loss, GilbertElliott) and not loss.is_off
    name = "sampling and bursty loss (mean square, exact)" if bursty else "sampling and loss (mean square, exact)"
    try:
        if bursty:
            ms = bursty_mean_square_stability(topology, P, D, t1, t2, rate=rate, loss=loss)
        else:
            ms = mean_square_stability(topology, P, D, t1, t2, rate=rate,
                                       loss=loss if isinstance(loss, BernoulliLoss) else 0.0)  # an idle chain loses nothing
    except ValueError as exc:  # delays not whole multiples of the period; too many chains (ResourceLimitError)
        return Guarantee(name.replace(", exact", ""), None, str(exc))
    decay = f"expected decay rate {ms.decay_rate:.4g} 1/s" if ms.stable else "not mean-square stable"
    return Guarantee(name, ms.stable, f"rho = {ms.rho:.6f} per period, {decay}")


def with_actuator_limits(guarantees: tuple[Guarantee, ...]) -> tuple[Guarantee, ...]:
    """The certificates for robots whose commands saturate or pass a safety filter: none covers the runs.

    Every certificate is for the linear protocol; saturation is outside it, so a
    holding certificate becomes "not covered" (a proof of instability stays: the
    linearisation about the formation is the protocol itself).

    Parameters
    ----------
    guarantees
        The certificates of :func:`network_guarantees`.
    """
    return tuple(Guarantee(g.name, None if g.holds else g.holds,
                           g.detail + ("; robots with actuator limits or a safety filter: not covered" if g.holds else ""))
                 for g in guarantees)  # fmt: skip


def contradictions(guarantees: tuple[Guarantee, ...], statuses: tuple[str, ...]) -> list[str]:
    """Runs that diverged although a certificate guarantees convergence (each one a bug).

    ``statuses`` are the runs' :attr:`~delayform.simulation.Trajectory.status` values.
    Only the certificates that cover the whole network count: the constant-delay
    root alone does not, when jitter, variation or loss are present.
    """
    covering = [g for g in guarantees if g.holds is True]
    # "stopped": the state overflowed and integration stopped, a divergence too
    diverged = [k for k, s in enumerate(statuses) if s in ("diverging", "stopped")]
    if not diverged:
        return []
    return [f"run {k} diverged although '{g.name}' holds ({g.detail})" for g in covering for k in diverged]


def guarantee_rows(guarantees: tuple[Guarantee, ...]) -> tuple[tuple[str, str], ...]:
    """Table rows ``(certificate, verdict: detail)``, one per entry of ``guarantees``."""
    word = {True: "guaranteed", False: "proven unstable", None: "not covered"}
    return tuple((f"certificate: {g.name}", f"{word[g.holds]}: {g.detail}") for g in guarantees)


def summary_of(guarantees: tuple[Guarantee, ...]) -> list[dict[str, Any]]:
    """JSON-ready list of ``guarantees``."""
    return [{"name": g.name, "holds": g.holds, "detail": g.detail} for g in guarantees]


def with_actuation_delay(guarantees: tuple[Guarantee, ...], actuation_delay: float) -> tuple[Guarantee, ...]:
    """The certificates for robots that apply their commands ``actuation_delay`` s late: none covers the runs.

    Every certificate here is for the paper's eq. 1 without actuation delay; with one the
    characteristic function changes, so neither stability nor instability carries over.

    Parameters
    ----------
    guarantees
        The certificates of :func:`network_guarantees`.
    actuation_delay
        tau_a (s); 0 leaves the certificates as they are.
    """
    if not actuation_delay:
        return guarantees
    return tuple(Guarantee(g.name, None, g.detail + f"; actuation delay {actuation_delay:g} s: not covered")
                 for g in guarantees)  # fmt: skip


def bug_rows(bugs: list[str]) -> tuple[tuple[str, str], ...]:
    """Table rows that put contradictions first and in capitals: each one is a bug to report.

    Parameters
    ----------
    bugs
        The sentences of :func:`contradictions`.
    """
    if not bugs:
        return ()
    return (("BUG", f"{len(bugs)} contradiction(s) between a certificate and the runs: {bugs[0]}"
                    + (f" (and {len(bugs) - 1} more)" if len(bugs) > 1 else "")),)  # fmt: skip
