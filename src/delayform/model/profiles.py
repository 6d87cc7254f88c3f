"""Real robot profiles: the limits, geometry and arena of robots a formation is deployed on.

A profile is a named :class:`~delayform.model.RobotLimits` with
the source of every number, the arena where the platform has one and the
control period its makers use, and the physical numbers of its chassis
(:class:`~delayform.model.Chassis`: mass, inertia, tyres,
wheel servos) for ``model="physics"``. ``simulate(..., limits=profile.limits)``,
``--robot NAME`` and ``[robot] profile = "NAME"`` apply it to a run and to
the commands it exports; ``delayform check`` compares a design with it.

Conventions
-----------
Lengths in m, speeds in m/s, turn rates and wheel speeds in rad/s,
accelerations in m/s^2. A number the maker does not document is marked
"assumption" in :attr:`RobotProfile.sources`; a number derived from others
(e.g. the turn rate of both wheels at full speed in opposite directions,
``2 v_max / L``) says so. The softening of the paper's eq. 19
(``slow_speed``, ``turn_time_constant``) is a property of the controller,
not of the robot: every profile keeps the library's defaults.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass, field
from dataclasses import fields as dataclass_fields
from types import MappingProxyType

from delayform._validation import validated
from delayform.errors import RobotProfileError
from delayform.model.chassis import CREATE_CHASSIS, Chassis
from delayform.model.limits import IROBOT_CREATE, RobotLimits

__all__ = ["RobotProfile", "Arena", "PROFILES", "robot_profile", "profile_names"]


@dataclass(frozen=True)
class Arena:
    """A rectangular arena ``[x_min, x_min + width] x [y_min, y_min + height]`` (m)."""

    x_min: float
    y_min: float
    width: float
    height: float

    @property
    def x_max(self) -> float:
        """Right edge (m)."""
        return self.x_min + self.width

    @property
    def y_max(self) -> float:
        """Top edge (m)."""
        return self.y_min + self.height

    def describe(self) -> str:
        """``"3.2 m x 2 m, x in [-1.6, 1.6], y in [-1, 1]"``."""
        return (f"{self.width:g} m x {self.height:g} m, x in [{self.x_min:g}, {self.x_max:g}], "
                f"y in [{self.y_min:g}, {self.y_max:g}]")  # fmt: skip


@validated(RobotProfileError)
@dataclass(frozen=True)
class RobotProfile:
    """A real robot: its limits with their sources, its control period and its arena.

    Attributes
    ----------
    name
        Key for ``--robot`` and ``[robot] profile`` (lower case).
    title
        The robot's name as its maker writes it.
    limits
        Geometry and actuator limits (the simulation's saturated unicycle).
    sources
        Field of ``limits`` (and ``"control_period"``, ``"arena"``) -> where
        the number comes from, or why it is an assumption.
    control_period
        Period (s) at which the platform takes velocity commands, or None
        where the maker states none.
    arena
        The platform's arena, or None for robots that run anywhere.
    command_topic
        Where the robot takes ``geometry_msgs/msg/Twist`` (ROS 2), or None.
    chassis
        Mass, inertia, tyres and wheel servos for ``model="physics"``
        (sources under ``"chassis.<field>"``), or None for a robot whose
        physical numbers are not known (the physics model refuses it).
    """

    name: str
    title: str
    limits: RobotLimits
    sources: Mapping[str, str] = field(default_factory=dict)
    control_period: float | None = None
    arena: Arena | None = None
    command_topic: str | None = None
    chassis: Chassis | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "sources", MappingProxyType(dict(self.sources)))
        if self.chassis is not None and not isinstance(self.chassis, Chassis):
            raise RobotProfileError(f"chassis must be a Chassis or None, got {type(self.chassis).__name__}")

    def physics_chassis(self) -> Chassis:
        """The chassis for ``model="physics"``; refused, naming what is missing, when the profile has none.

        Raises
        ------
        RobotProfileError
            For a profile without physical numbers.
        """
        if self.chassis is None:
            missing = ", ".join(f.name for f in dataclass_fields(Chassis) if f.name != "yaw_inertia")
            raise RobotProfileError(f"robot profile {self.name!r} has no physical numbers for model='physics'; "
                                    f"missing: {missing}")  # fmt: skip
        return self.chassis

    def describe(self) -> str:
        """One line: title and limits."""
        return f"{self.title}: {self.limits.describe()}, body radius {self.limits.radius:g} m"


_CREATE_OI = "iRobot Create Open Interface Specification (iRobot, 2006)"
_CREATE2_OI = "iRobot Create 2 Open Interface Specification (iRobot, 2015)"
_LIBCREATE = "AutonomyLab libcreate (src/types.cpp, RobotModel::CREATE_2)"
_C3_SAFETY = "Create 3 docs, 'Safety Overrides' (iroboteducation.github.io/create3_docs/api/safety)"
_C3_SIM = "iRobotEducation/create3_sim, irobot_create_control/config/control.yaml"
_C3_URDF = "iRobotEducation/create3_sim, irobot_create_description/urdf/create3.urdf.xacro"
_ROBOTARIUM = "Robotarium simulator, rps/robotarium_abc.py (robotarium/robotarium_python_simulator)"
_TB3_SPEC = "ROBOTIS e-Manual, TurtleBot3 'Specifications' (Burger column)"
_TB3_CODE = "ROBOTIS turtlebot3 (ROS 2) burger parameters: wheel radius 0.033 m, separation 0.160 m"
_TB3_NAV = "ROBOTIS turtlebot3_navigation2 param/burger.yaml: robot_radius 0.105"
_ASSUMED_ACCEL = "assumption: the maker documents no acceleration limit"
_TB3_URDF = "ROBOTIS turtlebot3, turtlebot3_description/urdf/turtlebot3_burger.urdf"
_XL430 = "ROBOTIS e-Manual, DYNAMIXEL XL430-W250-T: stall torque 1.4 N m at 11.1 V"
_ASSUMED_SERVO = "assumption: not documented; a wheel speed loop of 25 ms time constant (Chassis.servo_time_constant)"
_ASSUMED_TORQUE = "assumption: not documented; three times the torque the acceleration limit needs"
_ASSUMED_TYRE = "assumption: rubber on a hard floor"
_ROBOTARIUM_MAG = "Wilson et al., 'The Robotarium', IEEE Control Systems Magazine 40(1), 2020"


def _physics_sources(**given: str) -> dict[str, str]:
    """``chassis.<field>`` -> source; fields not given are assumptions the maker does not document."""
    out = {f"chassis.{f.name}": "assumption: not documented by the maker" for f in dataclass_fields(Chassis)}
    out["chassis.servo_gain"] = _ASSUMED_SERVO
    out["chassis.max_torque"] = _ASSUMED_TORQUE
    out["chassis.tyre_friction"] = _ASSUMED_TYRE
    out["chassis.yaw_inertia"] = "derived: a uniform cylinder, mass radius^2 / 2"
    out.update({f"chassis.{k}": v for k, v in given.items()})
    return out

#: the paper's robot and today's defaults (:data:`IROBOT_CREATE`)
_CREATE = RobotProfile(
    name="create",
    title="iRobot Create (the paper's robot; delayform's defaults)",
    limits=IROBOT_CREATE,
    sources={
        "max_speed": f"{_CREATE_OI}: Drive takes -500..500 mm/s",
        "max_wheel_speed": "derived: 0.5 m/s / wheel radius",
        "axle_length": f"{_CREATE_OI}: 258 mm wheel base",
        "wheel_radius": f"{_CREATE2_OI}: 72 mm wheel diameter",
        "max_turn_rate": "derived: 2 * 0.5 / 0.258 (both wheels at full speed, opposite ways)",
        "max_acceleration": _ASSUMED_ACCEL,
        "radius": "0.34 m across (IROBOT_CREATE)",
        "control_period": "assumption: the OI streams sensor packets every 15 ms; no command period is fixed",
        **_physics_sources(control_period="assumption: 10 ms"),
    },
    chassis=CREATE_CHASSIS,
)

_CREATE2 = RobotProfile(
    name="create2",
    title="iRobot Create 2",
    limits=RobotLimits(wheel_radius=0.036, axle_length=0.235, max_wheel_speed=0.5 / 0.036, max_speed=0.5,
                       max_turn_rate=2 * 0.5 / 0.235, max_acceleration=0.5, radius=0.17),  # fmt: skip
    sources={
        "max_speed": f"{_CREATE2_OI}: Drive takes -500..500 mm/s; {_LIBCREATE}: max velocity 0.5",
        "max_wheel_speed": "derived: 0.5 m/s / wheel radius (Drive Direct: -500..500 mm/s per wheel)",
        "axle_length": f"{_LIBCREATE}: axle length 0.235 m",
        "wheel_radius": f"{_CREATE2_OI}: 72 mm wheel diameter; {_LIBCREATE}: 0.072",
        "max_turn_rate": "derived: 2 * 0.5 / 0.235",
        "max_acceleration": _ASSUMED_ACCEL,
        "radius": "assumption: 0.34 m across, as the Create",
        "control_period": "assumption: 15 ms, the OI's sensor streaming period",
        **_physics_sources(control_period="the profile's control period (an assumption, above)"),
    },
    control_period=0.015,
    chassis=CREATE_CHASSIS.with_changes(control_period=0.015),
)

_CREATE3 = RobotProfile(
    name="create3",
    title="iRobot Create 3",
    limits=RobotLimits(wheel_radius=0.03575, axle_length=0.233, max_wheel_speed=0.306 / 0.03575, max_speed=0.306,
                       max_turn_rate=2 * 0.306 / 0.233, max_acceleration=0.9, radius=0.164),  # fmt: skip
    sources={
        "max_speed": f"{_C3_SAFETY}: 0.306 m/s with safety_override none or backup_only (0.46 m/s with full)",
        "max_wheel_speed": "derived: 0.306 m/s / wheel radius (the speed limit applies to each wheel)",
        "axle_length": f"{_C3_SIM}: wheel_separation 0.233; {_C3_URDF}: 23.3 cm between wheels",
        "wheel_radius": f"{_C3_SIM}: wheel_radius 0.03575",
        "max_turn_rate": "derived: 2 * 0.306 / 0.233",
        "max_acceleration": f"{_C3_SAFETY}: wheel_accel_limit defaults to its maximum, 900 mm/s^2",
        "radius": f"{_C3_URDF}: body collision cylinder radius 16.4 cm",
        "control_period": f"{_C3_SIM}: controller update_rate 100 Hz (cmd_vel_timeout 0.25 s)",
        **_physics_sources(
            mass=f"{_C3_URDF}: body_mass 2.300 plus bumper_mass 0.1",
            height=f"{_C3_URDF}: body_length 6 cm",
            caster_offset=f"{_C3_URDF}: caster_position_x 12.5 cm",
            control_period=f"{_C3_SIM}: update_rate 100 Hz",
            wheel_mass="assumption: not documented (0.1 kg)",
        ),
    },
    control_period=0.01,
    command_topic="/cmd_vel",
    chassis=Chassis(mass=2.4, height=0.06, wheel_mass=0.1, wheel_width=0.02, caster_offset=0.125,
                    tyre_friction=0.8, servo_gain=0.07, max_torque=0.15, control_period=0.01),  # fmt: skip
)

_GRITSBOT = RobotProfile(
    name="robotarium",
    title="Robotarium GRITSbot",
    limits=RobotLimits(wheel_radius=0.016, axle_length=0.105, max_wheel_speed=0.2 / 0.016, max_speed=0.2,
                       max_turn_rate=2 * 0.2 / 0.11, max_acceleration=0.5, radius=0.055),  # fmt: skip
    sources={
        "max_speed": f"{_ROBOTARIUM}: max_linear_velocity 0.2",
        "max_wheel_speed": f"{_ROBOTARIUM}: max_wheel_velocity = 0.2 / 0.016 = 12.5",
        "axle_length": f"{_ROBOTARIUM}: base_length 0.105",
        "wheel_radius": f"{_ROBOTARIUM}: wheel_radius 0.016",
        "max_turn_rate": f"{_ROBOTARIUM}: max_angular_velocity = 2 (r / 0.11) (0.2 / r) = 3.64",
        "max_acceleration": _ASSUMED_ACCEL,
        "radius": f"{_ROBOTARIUM}: robot_diameter 0.11 (collisions are checked at 0.135 m between centres)",
        "control_period": f"{_ROBOTARIUM}: time_step 0.033",
        "arena": f"{_ROBOTARIUM}: boundaries [-1.6, -1, 3.2, 2] (lower left corner, width, height)",
        **_physics_sources(
            mass=f"assumption: 0.3 kg; {_ROBOTARIUM_MAG} describes the GRITSbot X without its mass",
            control_period=f"{_ROBOTARIUM}: time_step 0.033",
        ),
    },
    control_period=0.033,
    arena=Arena(-1.6, -1.0, 3.2, 2.0),
    chassis=Chassis(mass=0.3, height=0.07, wheel_mass=0.01, wheel_width=0.006, caster_offset=0.04,
                    tyre_friction=0.8, servo_gain=0.0017, max_torque=0.005, control_period=0.033),  # fmt: skip
)

_BURGER = RobotProfile(
    name="turtlebot3_burger",
    title="TurtleBot3 Burger",
    limits=RobotLimits(wheel_radius=0.033, axle_length=0.160, max_wheel_speed=0.22 / 0.033, max_speed=0.22,
                       max_turn_rate=2.84, max_acceleration=0.5, radius=0.105),  # fmt: skip
    sources={
        "max_speed": f"{_TB3_SPEC}: maximum translational velocity 0.22 m/s",
        "max_turn_rate": f"{_TB3_SPEC}: maximum rotational velocity 2.84 rad/s",
        "max_wheel_speed": "derived: 0.22 m/s / wheel radius",
        "axle_length": _TB3_CODE,
        "wheel_radius": _TB3_CODE,
        "max_acceleration": _ASSUMED_ACCEL,
        "radius": f"{_TB3_NAV} (the body is 138 x 178 mm)",
        "control_period": "assumption: none documented for cmd_vel",
        **_physics_sources(
            mass=f"{_TB3_SPEC}: 1 kg with SBC, battery and sensors; {_TB3_URDF}: base_link 0.826 kg plus the "
                 "lidar's 0.114 kg (the wheels apart)",
            yaw_inertia=f"{_TB3_URDF}: base_link izz 2.006e-3",
            height=f"{_TB3_URDF}: base collision box 0.143 m high",
            wheel_mass=f"{_TB3_URDF}: 2.85e-2 kg",
            wheel_width=f"{_TB3_URDF}: wheel cylinder 0.018 m long",
            caster_offset=f"{_TB3_URDF}: caster_back_joint at x = -0.081 (behind the axle)",
            max_torque=_XL430,
            control_period="assumption: 10 ms",
        ),
    },
    command_topic="/cmd_vel",
    chassis=Chassis(mass=0.94, height=0.143, wheel_mass=0.0285, wheel_width=0.018, caster_offset=-0.081,
                    tyre_friction=0.8, servo_gain=0.022, max_torque=1.4, control_period=0.01,
                    yaw_inertia=2.006e-3),  # fmt: skip
)

#: every profile by name
PROFILES: Mapping[str, RobotProfile] = MappingProxyType(
    {p.name: p for p in (_CREATE, _CREATE2, _CREATE3, _GRITSBOT, _BURGER)}
)

#: other spellings users type
_ALIASES = {"gritsbot": "robotarium", "burger": "turtlebot3_burger", "turtlebot3": "turtlebot3_burger",
            "irobot_create": "create", "create1": "create"}  # fmt: skip


def profile_names() -> tuple[str, ...]:
    """The profile names, in the order of :data:`PROFILES`."""
    return tuple(PROFILES)


@validated(RobotProfileError)
def robot_profile(name: str | RobotProfile) -> RobotProfile:
    """The profile called ``name`` (case and ``-`` / ``_`` do not matter).

    Parameters
    ----------
    name
        A key of :data:`PROFILES` (``"create"``, ``"create2"``, ``"create3"``,
        ``"robotarium"``, ``"turtlebot3_burger"``), an alias (``"gritsbot"``,
        ``"burger"``), or a profile, returned as it is.

    Raises
    ------
    RobotProfileError
        For an unknown name; the message lists the known ones.

    >>> robot_profile("robotarium").limits.max_speed
    0.2
    """
    if isinstance(name, RobotProfile):
        return name
    if not isinstance(name, str):
        raise RobotProfileError(f"a robot profile is named by a string, got {type(name).__name__}")
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    key = _ALIASES.get(key, key)
    if key not in PROFILES:
        close = difflib.get_close_matches(key, [*PROFILES, *_ALIASES], n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise RobotProfileError(f"unknown robot profile {name!r}{hint}; known: {', '.join(PROFILES)}")
    return PROFILES[key]
