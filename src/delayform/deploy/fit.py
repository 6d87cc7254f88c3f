"""Whether a formation can be held by real robots at all: bodies that do not overlap, a shape that fits the arena.

These are the checks a scenario must pass before it is simulated with a
robot profile (``delayform simulate --robot NAME``): a desired shape whose
closest two places are nearer than two body radii asks the robots to stand
inside each other, and a shape wider than the arena (less a body radius on
each side) cannot be placed in it however the team is translated (paper,
eq. 13 fixes the shape and its orientation, not its position).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from delayform.deploy.profiles import Arena, RobotProfile
from delayform.errors import RobotProfileError
from delayform.simulation.models.robots import RobotLimits

__all__ = ["FormationFit", "formation_fit", "require_formation_fit"]


@dataclass(frozen=True)
class FormationFit:
    """The numbers of the fit of a desired shape to a robot (m).

    Attributes
    ----------
    closest_places
        Smallest distance between two desired positions.
    body_diameter
        Twice the robot's radius: the closest two centres can be.
    extent
        ``(width, height)`` of the shape's bounding box of centres.
    arena
        The arena, or None.
    """

    closest_places: float
    body_diameter: float
    extent: tuple[float, float]
    arena: Arena | None

    @property
    def bodies_fit(self) -> bool:
        """Whether the desired places are more than a body diameter apart."""
        return self.closest_places > self.body_diameter

    @property
    def arena_fits(self) -> bool | None:
        """Whether the shape with its bodies fits the arena (None: no arena)."""
        if self.arena is None:
            return None
        r = 0.5 * self.body_diameter
        return self.extent[0] + 2 * r <= self.arena.width and self.extent[1] + 2 * r <= self.arena.height

    def problems(self) -> tuple[str, ...]:
        """One sentence per failed check (none: empty)."""
        out = []
        if not self.bodies_fit:
            out.append(f"two desired positions are {self.closest_places:.3g} m apart, but the robots' bodies "
                       f"need {self.body_diameter:.3g} m (twice the radius)")  # fmt: skip
        if self.arena_fits is False:
            assert self.arena is not None
            out.append(f"the formation with its bodies spans {self.extent[0] + self.body_diameter:.3g} m x "
                       f"{self.extent[1] + self.body_diameter:.3g} m, more than the arena's "
                       f"{self.arena.width:g} m x {self.arena.height:g} m")  # fmt: skip
        return tuple(out)


def formation_fit(desired: ArrayLike, robot: RobotProfile | RobotLimits, *, arena: Arena | None = None) -> FormationFit:
    """The fit of a desired shape to a robot's body (and the profile's arena).

    Parameters
    ----------
    desired
        ``(n, 2)`` desired positions (m).
    robot
        A profile (its arena is used unless ``arena`` is given) or limits.
    arena
        An arena to fit into; default: the profile's.

    >>> from delayform.deploy.profiles import robot_profile
    >>> fit = formation_fit([[0, 0], [0.1, 0]], robot_profile("robotarium"))
    >>> fit.bodies_fit, round(fit.body_diameter, 3)
    (False, 0.11)
    """
    z = np.asarray(desired, dtype=np.float64)
    if z.ndim != 2 or z.shape[1] != 2 or z.shape[0] < 2 or not np.all(np.isfinite(z)):
        raise RobotProfileError(f"desired positions must be finite numbers of shape (n, 2), n >= 2, got {z.shape}")
    limits = robot.limits if isinstance(robot, RobotProfile) else robot
    if arena is None and isinstance(robot, RobotProfile):
        arena = robot.arena
    from scipy.spatial import cKDTree

    # nearest other place of every place: O(n log n), for teams of any size
    closest = float(cKDTree(z).query(z, k=2)[0][:, 1].min())
    span = z.max(axis=0) - z.min(axis=0)
    return FormationFit(closest, 2.0 * limits.radius, (float(span[0]), float(span[1])), arena)


def require_formation_fit(desired: ArrayLike, robot: RobotProfile | RobotLimits, *, arena: Arena | None = None) -> FormationFit:
    """:func:`formation_fit`, raising :class:`RobotProfileError` when the formation cannot be held.

    Parameters
    ----------
    desired, robot, arena
        As for :func:`formation_fit`.
    """
    fit = formation_fit(desired, robot, arena=arena)
    found = fit.problems()
    if found:
        name = robot.title if isinstance(robot, RobotProfile) else "these robots"
        raise RobotProfileError(f"the formation does not fit {name}: " + "; ".join(found))
    return fit
