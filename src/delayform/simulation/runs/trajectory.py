"""The result of a simulation: motion, metrics, status and the robots' commands."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._files import atomic_path, save_npz
from delayform._display import FigureRepr  # Jupyter shows the figure
from delayform._validation import validated
from delayform.errors import SimulationInputError
from delayform.simulation.bodies.approach import Contact
from delayform.simulation.models.commands import RobotCommands
from delayform.simulation.models.robots import RobotLimits
from delayform.simulation.bodies.safety import SafetyReport

__all__ = ["Trajectory", "SETTLING_FRACTION", "STATUSES"]

_Array = NDArray[np.float64]

#: settling: the formation error stays below this fraction of its initial value
SETTLING_FRACTION = 0.02

#: what :attr:`Trajectory.status` can be
STATUSES = ("settled", "not settled", "diverging", "stopped", "deadlock")

#: a run whose formation error ends this many times above its initial value is diverging
DIVERGING_GROWTH = 10.0


@validated(SimulationInputError)
@dataclass(frozen=True, eq=False)
class Trajectory(FigureRepr):
    """A simulated run of eq. formation: the motion, its metrics and its status.

    Attributes
    ----------
    times
        Saved time points ``(T,)`` (s).
    positions
        ``(T, n, 2)`` positions x, y (m).
    velocities
        ``(T, n, 2)`` Cartesian velocities (m/s).
    headings
        ``(T, n)`` headings theta in (-pi, pi]; for the double integrator the
        direction of the velocity.
    speeds
        ``(T, n)`` speeds: the signed v of the robot, ``|xdot|`` for the
        double integrator.
    inputs
        ``(T, n, 2)``: the executed ``(dv/dt, omega)`` of the paper's eq. 19 for
        robots, ``u`` of the paper's eq. 1 for the double integrator.
    desired
        ``(n, 2)`` desired formation.
    model, P, D, tau1, tau2, dt
        What was simulated.
    stated_order
        Order of accuracy of the integrator for this run (4 or 2; 2 with limits).
    formation_error
        ``(T,)`` root-mean-square distance of the agents from the desired
        shape after removing the common offset (the mean of positions minus
        desired positions).
    settling_time
        First saved time after which the formation error stays below
        :data:`SETTLING_FRACTION` of its initial value; ``inf`` when it never
        does (see :attr:`status` and :attr:`warnings` for why).
    final_centroid
        Weighted centroid ``w^T x`` (paper, eq. 4) at the last time.
    min_distance
        Smallest centre-to-centre distance of two robots over the run, exact
        for the interpolated motion between saved samples too
        (:func:`~delayform.simulation.bodies.approach.closest_approach`).
    closest_at
        When it happened (s).
    radius
        The robots' body radius (m) used for contacts; 0 for point agents.
    contacts
        Each time two bodies overlapped (:class:`~delayform.simulation.bodies.approach.Contact`:
        which pair, when, how long, how close); a run with contacts says so
        in :attr:`warnings`.
    slots
        ``(n,)``: the slot of ``formation`` robot i took (``simulate(...,
        assignment=...)``); ``desired`` is already in this order.
    safety
        When the safety filter acted (:class:`~delayform.simulation.bodies.safety.SafetyReport`),
        or None for a run without it.
    commands
        The robots' commands (:class:`RobotCommands`); None for double integrators.
    limits
        The actuator limits of a saturated run, or None for ideal robots.
    status
        One of :data:`STATUSES`: ``"settled"``; ``"not settled"`` within the
        run; ``"diverging"`` (the error ended more than 10 times its start);
        ``"stopped"`` (the state overflowed and integration stopped early);
        ``"deadlock"`` (the safety filter holds the robots still short of
        the formation).
    warnings
        Sentences for a reader about a run that did not settle.
    labels
        Agent labels of the topology (figures number agents from 1).
    stopped_at
        Time (s) at which integration stopped because the state passed 1e8
        times its initial size (status ``"stopped"``), else None.
    actuation_delay
        The robots' actuation delay tau_a (s), 0 for the paper's model.
    """

    _figure_method = "plot_traces"  # the robots' paths in the plane: what a notebook wants to see

    times: _Array
    positions: _Array
    velocities: _Array
    headings: _Array
    speeds: _Array
    inputs: _Array
    desired: _Array
    model: str
    P: float
    D: float
    tau1: float
    tau2: float
    dt: float
    stated_order: int
    formation_error: _Array
    settling_time: float
    final_centroid: _Array
    min_distance: float
    closest_at: float = math.nan
    radius: float = 0.0
    contacts: tuple[Contact, ...] = ()
    slots: NDArray[np.intp] | None = None
    safety: SafetyReport | None = None
    commands: RobotCommands | None = None
    limits: RobotLimits | None = None
    status: str = "settled"
    warnings: tuple[str, ...] = ()
    labels: tuple[Any, ...] = field(default=())
    stopped_at: float | None = None
    #: tau_a (s), the actuation delay of the run (:attr:`~delayform.simulation.models.robots.Robot.actuation_delay`)
    actuation_delay: float = 0.0

    @property
    def n(self) -> int:
        """Number of agents."""
        return int(self.positions.shape[1])

    @property
    def collided(self) -> bool:
        """Whether two robots' bodies overlapped during the run (see :attr:`contacts`)."""
        return bool(self.contacts)

    @property
    def final_positions(self) -> _Array:
        """``(n, 2)`` positions at the last saved time."""
        return self.positions[-1]

    def plot_xy(self, ax: Any = None) -> Any:
        """x and y of every agent versus time (paper, Figs. 5 and 7); returns the axes (pair).

        Parameters
        ----------
        ax
            A pair of axes or None for a new figure.
        """
        from delayform.plots import plot_trajectory_xy

        return plot_trajectory_xy(self, ax=ax)

    def plot_traces(self, ax: Any = None, *, snapshots: int = 6) -> Any:
        """Paths in the plane with heading marks at snapshots (paper, Fig. 6).

        Parameters
        ----------
        ax
            Axes or None for a new figure.
        snapshots
            Number of instants at which positions and headings are marked.
        """
        from delayform.plots import plot_trajectory_traces

        return plot_trajectory_traces(self, ax=ax, snapshots=snapshots)

    def save_gif(self, path: str | Path, *, frames: int = 80, fps: int = 15) -> Path:
        """Write an animated GIF of the robots moving into formation.

        Parameters
        ----------
        path
            File to write.
        frames, fps
            Number of frames and frames per second.
        """
        from delayform.plots import save_trajectory_gif

        return save_trajectory_gif(self, path, frames=frames, fps=fps)

    def to_csv(self, path: str | Path) -> Path:
        """Write one row per (time, agent): time, agent (from 1), x, y, heading, speed, input1, input2.

        Parameters
        ----------
        path
            File to write.
        """
        path = Path(path)
        T, n = self.headings.shape
        cols = np.column_stack(
            [
                np.repeat(self.times, n),
                np.tile(np.arange(1, n + 1), T),
                self.positions.reshape(-1, 2),
                self.headings.reshape(-1),
                self.speeds.reshape(-1),
                self.inputs.reshape(-1, 2),
            ]
        )
        input_names = "u_x,u_y" if self.model == "double_integrator" else "dv_dt,omega"
        header = f"time,agent,x,y,heading,speed,{input_names}"
        with atomic_path(path) as tmp:
            np.savetxt(tmp, cols, delimiter=",", header=header, comments="", fmt="%.10g")
        return path

    def to_npz(self, path: str | Path) -> Path:
        """Write times, positions, velocities, headings, speeds, inputs and the error as compressed NPZ.

        Parameters
        ----------
        path
            File to write (``.npz``).
        """
        path = Path(path)
        save_npz(
            path, times=self.times, positions=self.positions, velocities=self.velocities,
            headings=self.headings, speeds=self.speeds, inputs=self.inputs,
            formation_error=self.formation_error, desired=self.desired,
        )  # fmt: skip
        return path

    def csv_bytes(self) -> int:
        """Approximate size (bytes) of :meth:`to_csv`'s file, to decide whether to write it."""
        return int(self.headings.size * 8 * 13)


# ---------------------------------------------------------------- metrics
def formation_error(positions: _Array, desired: _Array) -> _Array:
    """RMS distance from the desired shape after removing the common (mean) offset."""
    dev = positions - desired[None]
    dev -= dev.mean(axis=1, keepdims=True)
    return np.sqrt(np.mean(np.sum(dev**2, axis=2), axis=1))


def settling_time(times: _Array, error: _Array, scale: float) -> float:
    """First time after which ``error`` stays below SETTLING_FRACTION of ``error[0]``.

    Errors below ``1e-12 scale`` (rounding, for a team that starts in
    formation) count as settled. A run whose error does not end below the
    threshold has not settled: ``inf``.
    """
    above = np.flatnonzero(~(error <= max(SETTLING_FRACTION * error[0], 1e-12 * scale)))
    if above.size == 0:
        return float(times[0])
    last = above[-1]
    return float(times[last + 1]) if last + 1 < times.size else math.inf


def contact_warning(contacts: tuple[Contact, ...], labels: tuple[Any, ...] = ()) -> str:
    """The sentence of a run whose robots touched: how many contacts, the deepest one."""
    deepest = max(contacts, key=lambda c: c.depth)
    pairs = len({c.agents for c in contacts})
    return (
        f"the robots collided: {len(contacts)} contact(s) between {pairs} pair(s) of robots; the deepest: "
        + deepest.sentence(labels)
    )


def run_status(
    times: _Array, error: _Array, settled_at: float, stopped: float | None, duration: float
) -> tuple[str, tuple[str, ...]]:
    """The status of a run and sentences explaining a run that did not settle."""
    if stopped is not None:
        return "stopped", (
            f"the run diverged: the state passed 1e8 times its initial size at t = {stopped:.4g} s "
            f"and integration stopped there (the delays are probably unstable)",
        )
    if math.isfinite(settled_at):
        return "settled", ()
    growth = float(error[-1] / error[0]) if error[0] > 0 else math.inf
    if growth > DIVERGING_GROWTH:
        return "diverging", (
            f"the formation error grew {growth:.3g}-fold over {times[-1]:.4g} s: the run is diverging "
            f"(the delays are probably unstable)",
        )
    return "not settled", (
        f"the formation error did not stay below {SETTLING_FRACTION:.0%} of its initial value within "
        f"{duration:.4g} s (it ended at {error[-1] / error[0]:.2%}); simulate longer",
    )
