"""The robot: its agent model, limits, body, safety filter and profile, checked once when made.

A :class:`Robot` gathers what belongs to the robot in a simulation, as
:class:`~delayform.model.Network` gathers the network: the agent model
(:data:`MODELS`; each name is one entry of the integrator table of
:mod:`delayform.simulation.runs.integrators`), the actuator limits
(:class:`~delayform.model.RobotLimits`) or the real robot they come from
(:class:`~delayform.model.RobotProfile`), the body's radius, the safety
filter (:class:`BarrierFilter`), the actuation delay and, for robots with
mass, the :class:`~delayform.model.Chassis`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
import numpy as np
from numpy.typing import NDArray

from delayform._extras import require_extra
from delayform._validation import check_delay, check_positive, validated
from delayform.errors import SimulationInputError
from delayform.model.chassis import CREATE_CHASSIS, Chassis
from delayform.model.limits import IROBOT_CREATE, RobotLimits
from delayform.model.profiles import RobotProfile, robot_profile

__all__ = ["Robot", "MODELS", "REST_SPEED", "SAFETY_FILTERS", "BarrierFilter", "check_safety"]

_Array = NDArray[np.float64]

#: agent models a :class:`Robot` names; each is one entry of the integrator table
#: :data:`delayform.simulation.runs.integrators.INTEGRATORS` (a test checks that the two agree);
#: ``"physics"``: robots with mass in a physics engine (:mod:`delayform.simulation.physics`)
MODELS = ("double_integrator", "unicycle", "physics")

#: below this speed (m/s) and acceleration (m/s^2) a robot is at rest and holds
#: its heading: the iRobot Create's drive command has a resolution of 1 mm/s
REST_SPEED = 1e-3

#: what ``Robot(safety=...)`` accepts by name
SAFETY_FILTERS = ("barrier",)


@validated(SimulationInputError)
@dataclass(frozen=True)
class BarrierFilter:
    """The control-barrier-function safety filter (module doc).

    Attributes
    ----------
    rate
        k (1/s): the barrier's double pole; larger lets robots approach faster
        and brake harder. Default 2.
    margin
        Added to the sum of the radii (m): the safe distance ``Ds``. Default 0.02.

    Raises
    ------
    MissingExtraError
        Without Clarabel (the ``safety`` extra), which solves its joint QP.
    """

    rate: float = 2.0
    margin: float = 0.02

    def __post_init__(self) -> None:
        # its joint QP (Clarabel) is reached only mid-run, when constraints conflict: refuse up front
        require_extra("safety")
        for name in ("rate", "margin"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise SimulationInputError(f"safety.{name} must be a number, got {value!r}")
            if not math.isfinite(value) or value < 0 or (name == "rate" and value == 0):
                raise SimulationInputError(f"safety.{name} must be finite and {'positive' if name == 'rate' else 'non-negative'}, got {value!r}")
            object.__setattr__(self, name, float(value))


def check_safety(safety: object) -> BarrierFilter | None:
    """``None``, a :class:`BarrierFilter`, or a name of :data:`SAFETY_FILTERS` -> the filter (or None).

    Parameters
    ----------
    safety
        What ``simulate(..., safety=...)`` or ``Robot(safety=...)`` was given.

    Raises
    ------
    SimulationInputError
        For anything else.
    """
    if safety is None or isinstance(safety, BarrierFilter):
        return safety
    if isinstance(safety, str) and safety in SAFETY_FILTERS:
        return BarrierFilter()
    raise SimulationInputError(f"unknown safety filter {safety!r}; choose one of {', '.join(SAFETY_FILTERS)} or None")


def _nonnegative(name: str, value: object, unit: str) -> float:
    """A finite non-negative number of a Robot, or SimulationInputError naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SimulationInputError(f"{name} must be a number ({unit}), got {value!r}")
    if not (math.isfinite(value) and value >= 0):
        raise SimulationInputError(f"{name} must be finite and non-negative ({unit}), got {value!r}")
    return float(value)


@validated(SimulationInputError)
@dataclass(frozen=True)
class Robot:
    """What belongs to the robot in a simulation, gathered as :class:`~delayform.model.Network` gathers the network.

    Attributes
    ----------
    model
        ``"unicycle"`` (differential-drive robot, the paper's eq. 19),
        ``"double_integrator"`` (point agents, ``x'' = u``) or ``"physics"``
        (differential-drive bodies with mass, wheel servos and contacts in
        a physics engine: :mod:`delayform.simulation.physics`, the
        ``physics`` extra).
    limits
        Actuator limits (:class:`RobotLimits`); None for ideal robots (for
        ``"physics"``: the profile's, else :data:`IROBOT_CREATE`).
    radius
        Radius (m) of the disc containing the body, for contacts. None
        (default): ``limits.radius``, else the Create's 0.17 m for robots
        and 0 (points, no contacts) for double integrators.
    safety
        A safety filter (:class:`BarrierFilter`, or its name ``"barrier"``),
        or None (default).
    actuation_delay
        tau_a >= 0 (s): each robot applies its command tau_a late,
        ``x'' = u(t - tau_a)`` for double integrators; for robots the demands
        (dv/dt, omega) of the paper's eq. 19, computed on the state when the
        command is made, are executed tau_a later under the limits of that
        time (docs/theory.md, "Actuation delay"); for ``"physics"`` the wheel
        targets reach the servos tau_a late, on top of the servos' own lag.
        0 (default): the paper's model.
    profile
        The real robot (a :class:`~delayform.model.RobotProfile` or its name,
        e.g. ``"create"``), or None. Its limits are the robot's ``limits``
        (give one or the other, or the same twice).
    rest_speed
        Ideal robots whose speed (m/s) and commanded acceleration (m/s^2)
        are both below this hold their heading (:data:`REST_SPEED`).
    chassis
        For ``model="physics"`` only: mass, inertia, tyres and wheel servos
        (:class:`~delayform.model.Chassis`). None: the profile's (refused,
        naming what is missing, for a profile without one), else the
        Create's (:data:`~delayform.model.CREATE_CHASSIS`).

    Raises
    ------
    SimulationInputError
        For an unknown model, limits on point agents, a chassis on a
        kinematic model, or a bad number.
    RobotProfileError
        For an unknown profile name, or a profile without a chassis for
        ``model="physics"``.

    Examples
    --------
    >>> Robot().body_radius, Robot(model="double_integrator").body_radius
    (0.17, 0.0)
    """

    model: str = "unicycle"
    limits: RobotLimits | None = None
    radius: float | None = None
    safety: str | BarrierFilter | None = None
    actuation_delay: float = 0.0
    profile: RobotProfile | str | None = None
    rest_speed: float = REST_SPEED
    chassis: Chassis | None = None

    def __post_init__(self) -> None:
        if self.profile is not None:
            profile = robot_profile(self.profile)
            if self.limits is not None and self.limits != profile.limits:
                raise SimulationInputError(
                    f"give the limits or the profile {profile.name!r}, not both: they differ"
                )
            object.__setattr__(self, "profile", profile)
            object.__setattr__(self, "limits", profile.limits)
        object.__setattr__(self, "safety", check_safety(self.safety))
        object.__setattr__(self, "actuation_delay", check_delay("actuation_delay", self.actuation_delay))  # a DelayError, as everywhere
        if self.model not in MODELS:
            raise SimulationInputError(f"unknown model {self.model!r}; choose one of {', '.join(MODELS)}")
        if self.limits is not None and not isinstance(self.limits, RobotLimits):
            raise SimulationInputError(f"limits must be a RobotLimits or None, got {type(self.limits).__name__}")
        if self.limits is not None and self.model == "double_integrator":
            raise SimulationInputError("limits apply to robots: use model='unicycle'")
        if self.model == "physics":
            self._physics_defaults()
        elif self.chassis is not None:
            raise SimulationInputError("a chassis (mass, servos, tyres) applies to model='physics' only")
        if self.radius is not None:
            object.__setattr__(self, "radius", _nonnegative("radius", self.radius, "m"))
        object.__setattr__(self, "rest_speed", check_positive("rest_speed", self.rest_speed, SimulationInputError))

    def _physics_defaults(self) -> None:
        """The profile's (else the Create's) limits and chassis where none are given."""
        if self.chassis is None:
            profile = self.profile
            chassis = profile.physics_chassis() if isinstance(profile, RobotProfile) else CREATE_CHASSIS
            object.__setattr__(self, "chassis", chassis)
        elif not isinstance(self.chassis, Chassis):
            raise SimulationInputError(f"chassis must be a Chassis, got {type(self.chassis).__name__}")
        if self.limits is None:
            object.__setattr__(self, "limits", IROBOT_CREATE)

    @property
    def body_radius(self) -> float:
        """The radius (m) used for contacts (see :attr:`radius`)."""
        if self.radius is not None:
            return self.radius
        if self.limits is not None:
            return self.limits.radius
        return IROBOT_CREATE.radius if self.model == "unicycle" else 0.0

    def check_slots(self, desired: _Array) -> None:
        """Refuse a formation whose slots are closer than two body radii, or than the safety filter's distance.

        With a safety filter (:attr:`safety`) the robots are kept at least
        two radii plus its margin apart, so slots closer than that could
        never be reached: the run would end far from the formation and look
        unstable although the delays are stable.

        Parameters
        ----------
        desired
            ``(n, 2)`` desired positions.

        Raises
        ------
        SimulationInputError
            Naming the closest two slots.
        """
        r = self.body_radius
        margin = 0.0 if self.safety is None else self.safety.margin
        n = desired.shape[0]
        if r + margin == 0.0 or n < 2:
            return
        from scipy.spatial import cKDTree

        dist, idx = cKDTree(desired).query(desired, k=2)
        i = int(np.argmin(dist[:, 1]))
        d = float(dist[i, 1])
        if d >= (2.0 * r + margin) * (1.0 - 1e-9):  # touching slots (and slots at the safe distance) are allowed
            return
        # for two slots at the same place the tree may list i itself second: name the other one
        other = int(idx[i, 1]) if int(idx[i, 1]) != i else int(idx[i, 0])
        a, b = sorted((i, other))
        if d < 2.0 * r * (1.0 - 1e-9):
            raise SimulationInputError(
                f"formation slots {a + 1} and {b + 1} are {d:.3g} m apart, closer than two robot "
                f"radii ({2.0 * r:.3g} m): the bodies would overlap in formation; spread the formation "
                f"or give a smaller radius"
            )
        raise SimulationInputError(
            f"formation slots {a + 1} and {b + 1} are {d:.3g} m apart, closer than the safety filter keeps "
            f"the robots (two radii plus its margin: {2.0 * r + margin:.3g} m): the formation could never be "
            f"reached; spread the formation or give a smaller safety margin"
        )


