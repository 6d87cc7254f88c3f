"""What is guaranteed beside what the robots' run observed, in the explorer.

``GET /api/guarantees`` takes the parameters of ``/api/simulate`` and answers with
the certificates of :func:`delayform.report.guarantees.network_guarantees` that
apply to the run's network (the exact per-link root at nominal delays, the jitter
margin where delays jitter, the exact mean-square verdict for sampled Bernoulli or
Gilbert-Elliott loss), the run's observed status (the explorer's own cached run:
the same simulation the page animates) and any contradiction: a run that
diverged where a certificate holds, which the page shows as a BUG. Robots with
actuator limits, a safety filter or an actuation delay are outside every
certificate (they are listed as not covered); teams beyond the explorer's ``GUARANTEE_AGENTS`` get no certificates.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any
from weakref import WeakKeyDictionary

from delayform.app.explorer import GUARANTEE_AGENTS, Explorer
from delayform.app.params import Param
from delayform.report.guarantees import (
    Guarantee,
    contradictions,
    network_guarantees,
    summary_of,
    with_actuation_delay,
    with_actuator_limits,
)

__all__ = ["SideBySide", "SideBySideReport"]

#: certificate lists kept per explorer
_CACHE = 16
#: each explorer's cache, dropped with the explorer
_CACHES: WeakKeyDictionary[Explorer, OrderedDict[Any, Any]] = WeakKeyDictionary()


@dataclass(frozen=True, eq=False)
class SideBySideReport:
    """Certificates and the observed run at one point.

    Attributes
    ----------
    guarantees
        The certificates that apply (empty for a team too large).
    status, settling_time, final_error
        What the run observed.
    bugs
        Contradictions: the run diverged although a certificate holds.
    """

    guarantees: tuple[Guarantee, ...]
    status: str
    settling_time: float | None
    final_error: float
    bugs: tuple[str, ...]

    def as_json(self) -> dict[str, Any]:
        """The certificates (name, holds, detail), the observation and the contradictions."""
        return {"guarantees": summary_of(self.guarantees),
                "observed": {"status": self.status, "settling_time": self.settling_time, "final_error": self.final_error},
                "contradictions": list(self.bugs)}  # fmt: skip


class SideBySide:
    """The explorer's side-by-side answers, cached.

    Parameters
    ----------
    explorer
        Whose scenario, switches and cached runs are used.
    """

    def __init__(self, explorer: Explorer) -> None:
        self.explorer = explorer
        # the cache lives as long as its explorer, whichever object asks (one per setting is cheap)
        self._lists: OrderedDict[tuple[Any, ...], tuple[Guarantee, ...]] = _CACHES.setdefault(explorer, OrderedDict())

    def params(self) -> tuple[Param, ...]:
        """The parameters of ``/api/simulate``: the run compared is the page's own."""
        return self.explorer.animation_params()

    def compute(self, P: float, D: float, tau1: float, tau2: float, duration: float, frames: int,
                limits: bool = False, network: bool = False, loss: float = 0.0, jitter: float = 0.0) -> SideBySideReport:  # fmt: skip
        """Certificates for the run's network beside the run (see the module docstring).

        Parameters
        ----------
        P, D, tau1, tau2, duration, frames, limits, network, loss, jitter
            As for :meth:`Explorer.animation`.
        """
        ex = self.explorer
        run = ex.animation(P, D, tau1, tau2, duration, frames, limits, network, loss, jitter)
        tr = run.trajectory
        team = ex.scenario.topology
        key = (P, D, tau1, tau2, tr.dt, limits, network, loss if network else 0.0, jitter if network else 0.0)

        def certify() -> tuple[Guarantee, ...]:
            if team.n > GUARANTEE_AGENTS:
                return ()
            gs = network_guarantees(team, P, D, tau1, tau2, ex.network(loss, jitter) if network else None, dt=tr.dt)
            gs = with_actuator_limits(gs) if limits or ex.scenario.safety else gs
            return with_actuation_delay(gs, ex.scenario.actuation_delay)

        gs = ex._cached(self._lists, key, _CACHE, certify)
        settle = None if tr.settling_time == float("inf") else float(tr.settling_time)
        return SideBySideReport(gs, tr.status, settle, float(tr.formation_error[-1]), tuple(contradictions(gs, (tr.status,))))
