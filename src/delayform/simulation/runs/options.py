"""How a run is carried out, beside what is simulated: saving stride, slot assignment, executor, progress.

:func:`~delayform.simulation.simulate` and
:func:`~delayform.simulation.monte_carlo` take the problem's nouns (team,
delays, formation, robot, network, start) and these rarely changed options
as one small object, as diffrax takes its ``SaveAt``.

Executors
---------
The runs of a Monte Carlo are handed to an *executor*: any object with
``map(fn, tasks, progress=None) -> list`` returning the results in the order
of ``tasks`` (:class:`SerialExecutor` here; Dask ones in :mod:`delayform.simulation.experiments.sweeps`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from delayform._validation import validated
from delayform.errors import SimulationInputError
from delayform.simulation.bodies.assignment import check_assignment

__all__ = ["RunOptions", "Executor", "SerialExecutor", "Progress"]

#: Called with (done, total): steps of a run, or runs of a Monte Carlo.
Progress = Callable[[int, int], None]


@runtime_checkable  # so that monte_carlo(executor="dask") is refused up front (delayform._validation)
class Executor(Protocol):
    """Runs tasks somewhere and returns their results in the order of the tasks."""

    def map(self, fn: Callable[[Any], Any], tasks: Sequence[Any], progress: Progress | None = None) -> list[Any]:
        """``[fn(t) for t in tasks]``, calling ``progress(done, total)`` as results arrive."""
        ...


@validated()
class SerialExecutor:
    """Runs every task in this process, one after another."""

    def map(self, fn: Callable[[Any], Any], tasks: Sequence[Any], progress: Progress | None = None) -> list[Any]:
        """``[fn(t) for t in tasks]``, calling ``progress(done, total)`` after each.

        Parameters
        ----------
        fn
            A function of one task.
        tasks
            The tasks.
        progress
            Optional callback ``(done, total)``.
        """
        out = []
        for task in tasks:
            out.append(fn(task))
            if progress is not None:
                progress(len(out), len(tasks))
        return out


@validated(SimulationInputError)
@dataclass(frozen=True)
class RunOptions:
    """The rarely changed options of a simulation or a Monte Carlo.

    Parameters
    ----------
    save_every
        Keep every ``save_every``-th step; None (default): every step while
        ``samples x n <= 2e6``, else the smallest stride that fits.
    assignment
        ``"given"`` (default): robot i takes slot i of the formation.
        ``"optimal"``: the slots that minimise the total squared distance from
        each robot's start to its predicted final position
        (:func:`~delayform.simulation.bodies.assignment.assign_slots`). It relabels
        the slots only: the stability analysis is unchanged (docs/theory.md).
    executor
        Where the runs of a Monte Carlo go (:class:`SerialExecutor` by
        default; :func:`delayform.simulation.experiments.sweeps.executor` for Dask); a single
        simulation refuses one. Its ``workers`` attribute, if any, enters the
        Monte Carlo's memory and time guard.
    progress
        Optional callback ``progress(done, total)``: steps of a simulation,
        runs of a Monte Carlo.

    Examples
    --------
    >>> RunOptions(assignment="optimal").assignment
    'optimal'
    """

    save_every: int | None = None
    assignment: str = "given"
    executor: Executor | None = None
    progress: Progress | None = None

    def __post_init__(self) -> None:
        se = self.save_every
        if se is not None and (isinstance(se, bool) or not isinstance(se, int) or se < 1):
            raise SimulationInputError(f"save_every must be a positive integer, got {se!r}")
        check_assignment(self.assignment)
        if self.executor is not None and not isinstance(self.executor, Executor):
            raise SimulationInputError(f"executor must have a map(fn, tasks, progress) method, got {type(self.executor).__name__}")
        if self.progress is not None and not callable(self.progress):
            raise SimulationInputError(f"progress must be callable, got {type(self.progress).__name__}")
