"""The commands each robot executes: speed, turn rate, wheel speeds, and where a limit was exceeded.

Robots are numbered from 1 in every table, sentence and figure (index 0 is
robot 1). Times in s, speeds in m/s, turn rates and wheel speeds in rad/s,
accelerations in m/s^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._files import atomic_path, save_npz
from delayform._validation import validated
from delayform.errors import SimulationInputError
from delayform.simulation.models.robots import RobotLimits, wheel_speeds

__all__ = ["RobotCommands", "LimitExceedance"]

_Array = NDArray[np.float64]

#: columns of the CSV and keys of the NPZ, in order, with their units
COLUMNS = (
    ("v", "m/s"),
    ("omega", "rad/s"),
    ("dv_dt", "m/s^2"),
    ("wheel_left", "rad/s"),
    ("wheel_right", "rad/s"),
    ("ideal_omega", "rad/s"),
    ("ideal_dv_dt", "m/s^2"),
)


@dataclass(frozen=True)
class LimitExceedance:
    """The worst excess of one limit over the run.

    Attributes
    ----------
    limit_name
        ``"speed"``, ``"turn rate"``, ``"acceleration"`` or ``"wheel speed"``.
    robot
        Robot number, counted from 1.
    time
        When the worst excess happened (s).
    needed
        What the ideal command (paper, eq. 19) asked for there, in ``unit``.
    limit
        The limit, in ``unit``.
    unit
        Unit of ``needed`` and ``limit``.
    samples
        Number of (robot, sample) pairs beyond the limit.
    first_time
        First time any robot exceeded this limit (s).
    held
        True for a saturated robot held back by its speed limit (``needed``
        is then its speed there).
    """

    limit_name: str
    robot: int
    time: float
    needed: float
    limit: float
    unit: str
    samples: int
    first_time: float
    held: bool = False

    @property
    def sentence(self) -> str:
        """``"robot 3 needs 2.7 rad/s turn rate at t = 0.4 s; the limit is 1.5"``."""
        if self.held:
            return (
                f"robot {self.robot} is held back by the speed limit {self.limit:.3g} {self.unit} "
                f"from t = {self.time:.3g} s"
            )
        need = f"{self.needed:.3g} {self.unit}" if math.isfinite(self.needed) else "an unbounded"
        return (
            f"robot {self.robot} needs {need} {self.limit_name} at t = {self.time:.3g} s; "
            f"the limit is {self.limit:.3g}"
        )


@validated(SimulationInputError)
@dataclass(frozen=True, eq=False)
class RobotCommands:
    """Per-robot time series of the commands of the paper's eq. 19, actual and ideal.

    Attributes
    ----------
    times
        ``(T,)`` sample times (s).
    speed
        ``(T, n)`` signed linear speed v (m/s); negative when driving backwards.
    turn_rate
        ``(T, n)`` executed turn rate omega (rad/s).
    acceleration
        ``(T, n)`` executed dv/dt (m/s^2).
    wheel_left, wheel_right
        ``(T, n)`` wheel speeds (rad/s) for ``robot``'s geometry.
    ideal_turn_rate, ideal_acceleration
        ``(T, n)`` what the controller asks for at the robot's state before
        any limit: the paper's eq. 19 (softened below ``robot.slow_speed`` for
        robots with limits); equal to the executed commands for ideal robots.
    robot
        Geometry (and limits) the wheel speeds and checks use.
    limited
        True when the run integrated the saturated robot.
    speed_held
        ``(T, n)`` booleans of a saturated run: the speed limit held the
        robot back (cut its demanded acceleration); None for ideal robots.
    """

    times: _Array
    speed: _Array
    turn_rate: _Array
    acceleration: _Array
    wheel_left: _Array
    wheel_right: _Array
    ideal_turn_rate: _Array
    ideal_acceleration: _Array
    robot: RobotLimits
    limited: bool = False
    speed_held: _Array | None = None

    @classmethod
    def from_motion(
        cls,
        times: _Array,
        speed: _Array,
        turn_rate: _Array,
        acceleration: _Array,
        robot: RobotLimits,
        *,
        ideal_turn_rate: _Array | None = None,
        ideal_acceleration: _Array | None = None,
        limited: bool = False,
        speed_held: _Array | None = None,
    ) -> RobotCommands:
        """Commands with wheel speeds computed for ``robot``.

        Parameters
        ----------
        times, speed, turn_rate, acceleration
            Sample times and the executed v, omega, dv/dt.
        robot
            Geometry and limits.
        ideal_turn_rate, ideal_acceleration
            What the paper's eq. 19 asked for; default: the executed values.
        limited
            Whether the run was saturated.
        speed_held
            Where the speed limit held a saturated robot back.
        """
        left, right = wheel_speeds(speed, turn_rate, robot)
        return cls(
            times=times, speed=speed, turn_rate=turn_rate, acceleration=acceleration,
            wheel_left=left, wheel_right=right,
            ideal_turn_rate=turn_rate if ideal_turn_rate is None else ideal_turn_rate,
            ideal_acceleration=acceleration if ideal_acceleration is None else ideal_acceleration,
            robot=robot, limited=limited, speed_held=speed_held,
        )  # fmt: skip

    @property
    def n(self) -> int:
        """Number of robots."""
        return int(self.speed.shape[1])

    # ----------------------------------------------------------- limits
    def needed(self, limits: RobotLimits | None = None) -> dict[str, tuple[_Array, float, str]]:
        """What the ideal commands ask of each actuator: name -> (values (T, n), limit, unit).

        Parameters
        ----------
        limits
            Limits to compare with; default: :attr:`robot`.
        """
        lim = self.robot if limits is None else limits
        half = 0.5 * lim.axle_length * np.abs(self.ideal_turn_rate)
        with np.errstate(invalid="ignore"):
            wheels = (np.abs(self.speed) + half) / lim.wheel_radius
        return {
            "speed": (np.abs(self.speed), lim.max_speed, "m/s"),
            "turn rate": (np.abs(self.ideal_turn_rate), lim.max_turn_rate, "rad/s"),
            "acceleration": (np.abs(self.ideal_acceleration), lim.max_acceleration, "m/s^2"),
            "wheel speed": (wheels, lim.max_wheel_speed, "rad/s"),
        }

    def exceedances(self, limits: RobotLimits | None = None) -> tuple[LimitExceedance, ...]:
        """The worst excess of each limit the ideal commands exceeded (none: empty).

        Parameters
        ----------
        limits
            Limits to compare with; default: :attr:`robot`.
        """
        out = []
        for name, (values, limit, unit) in self.needed(limits).items():
            beyond = values > limit * (1 + 1e-9)
            if name == "speed" and self.speed_held is not None and limits is None:
                # a saturated robot never exceeds its speed: say where the limit held it back
                beyond = self.speed_held.astype(bool)
                values = np.where(beyond, values, -np.inf)
            if not beyond.any():
                continue
            ratio = np.where(beyond, values, -np.inf)
            k, i = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
            first = int(np.flatnonzero(beyond.any(axis=1))[0])
            held = name == "speed" and self.speed_held is not None and limits is None
            if held:  # the first time the limit held a robot back, not the worst
                k = first
                i = int(np.flatnonzero(beyond[k])[0])
            out.append(LimitExceedance(name, int(i) + 1, float(self.times[k]), float(values[k, i]),
                                       limit, unit, int(beyond.sum()), float(self.times[first]), held))  # fmt: skip
        return tuple(out)

    def summary(self, limits: RobotLimits | None = None) -> str:
        """One sentence per exceeded limit, or that no command exceeded a limit.

        Parameters
        ----------
        limits
            Limits to compare with; default: :attr:`robot`.
        """
        found = self.exceedances(limits)
        if not found:
            return "no ideal command exceeded a limit"
        return "; ".join(e.sentence for e in found)

    def executed_within_limits(self, *, rtol: float = 1e-6) -> bool:
        """Whether every executed command (speed, turn rate, acceleration, wheels) is within the limits.

        Parameters
        ----------
        rtol
            Relative tolerance for rounding.
        """
        lim = self.robot
        checks = (
            (self.speed, lim.max_speed), (self.turn_rate, lim.max_turn_rate),
            (self.acceleration, lim.max_acceleration),
            (self.wheel_left, lim.max_wheel_speed), (self.wheel_right, lim.max_wheel_speed),
        )  # fmt: skip
        return all(float(np.abs(a).max(initial=0.0)) <= b * (1 + rtol) for a, b in checks)

    # ----------------------------------------------------------- output
    def _table(self) -> dict[str, _Array]:
        return {
            "v": self.speed, "omega": self.turn_rate, "dv_dt": self.acceleration,
            "wheel_left": self.wheel_left, "wheel_right": self.wheel_right,
            "ideal_omega": self.ideal_turn_rate, "ideal_dv_dt": self.ideal_acceleration,
        }  # fmt: skip

    def to_csv(self, path: str | Path) -> Path:
        """Write one row per (time, robot): time, robot (from 1), then :data:`COLUMNS`.

        Parameters
        ----------
        path
            File to write.
        """
        path = Path(path)
        T, n = self.speed.shape
        table = self._table()
        cols = np.column_stack(
            [np.repeat(self.times, n), np.tile(np.arange(1, n + 1), T)] + [table[c].reshape(-1) for c, _ in COLUMNS]
        )
        header = "time,robot," + ",".join(c for c, _ in COLUMNS)
        with atomic_path(path) as tmp:
            np.savetxt(tmp, cols, delimiter=",", header=header, comments="", fmt="%.10g")
        return path

    def to_npz(self, path: str | Path) -> Path:
        """Write the series as a compressed NPZ: ``times`` and one ``(T, n)`` array per column.

        Parameters
        ----------
        path
            File to write (``.npz``).
        """
        path = Path(path)
        lim = self.robot
        save_npz(
            path, times=self.times, **self._table(),
            limits=np.array([lim.max_speed, lim.max_turn_rate, lim.max_acceleration, lim.max_wheel_speed]),
            geometry=np.array([lim.wheel_radius, lim.axle_length]),
        )  # fmt: skip
        return path

    def plot(self, ax: Any = None) -> Any:
        """Speed, turn rate and wheel speeds over time with the limits drawn; returns the three axes.

        Parameters
        ----------
        ax
            Three axes (speed, turn rate, wheels) or None for a new figure.
        """
        from delayform.plots import plot_commands

        return plot_commands(self, ax=ax)
