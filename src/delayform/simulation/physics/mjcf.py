"""The team as one MuJoCo model, written as MJCF by code from the robot's numbers.

Every robot is the same differential drive (:class:`~delayform.model.chassis.Chassis`
and :class:`~delayform.model.RobotLimits`): a body on a free
joint whose collision shape is a vertical cylinder of the robot's radius,
two drive wheels on hinges about the axle, and a frictionless sphere for
the caster. A wheel touches the floor as a sphere of the wheel radius: on
a flat floor it rolls on the same point below the axle as a disc does, with
one contact instead of the several of a cylinder on a plane (about half
the engine's time; the wheels touch nothing else). The wheel's mass and
inertia are a disc's of the tyre's width. Each
wheel is driven by a velocity servo, torque ``servo_gain (target - speed)``
clipped to ``max_torque``.

Which geoms touch which: the wheels and the caster touch the floor only;
the bodies touch each other only (MuJoCo's ``contype`` / ``conaffinity``
bits). So robots push each other with their bodies, as bumpers do, and the
floor carries them on three points.

Numbers in the model
--------------------
Body origin at the middle of the axle, at the wheel radius above the floor.
The body's mass sits a third of the way to the caster (inside the triangle
of the contacts, so the robot does not tip), with the yaw inertia of the
chassis; the caster's radius is half the wheel's. The engine step and
solver are set in :func:`team_mjcf`; the step is :data:`~delayform.model.chassis.TIMESTEP`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from delayform.model.chassis import Chassis
from delayform.model import RobotLimits

__all__ = ["team_mjcf", "QPOS_PER_ROBOT", "QVEL_PER_ROBOT"]

#: free joint (3 position + 4 quaternion) and two wheel hinges
QPOS_PER_ROBOT = 9
#: free joint (3 linear + 3 angular) and two wheel hinges
QVEL_PER_ROBOT = 8

#: geom bits: floor 1, wheels and casters touch the floor (type 2, affinity 1 of the floor's type 1)
_FLOOR = 'contype="1" conaffinity="2"'
_WHEEL = 'contype="2" conaffinity="0"'
#: bodies touch bodies only
_BODY = 'contype="4" conaffinity="4"'

_Array = NDArray[np.float64]


def _g(x: float) -> str:
    """A number for MJCF, to full precision."""
    return repr(float(x))


def _robot(i: int, chassis: Chassis, limits: RobotLimits, pose: tuple[float, float, float]) -> str:
    """One robot's bodies, joints and geoms."""
    r, half_track, radius = limits.wheel_radius, 0.5 * limits.axle_length, limits.radius
    x, y, theta = pose
    caster_r = 0.5 * r
    # the caster stays under the body: at most the body's radius less its own from the axle
    caster_x = float(np.sign(chassis.caster_offset)) * min(abs(chassis.caster_offset), radius - caster_r)
    com_x = caster_x / 3.0
    izz = chassis.yaw_inertia if chassis.yaw_inertia is not None else 0.5 * chassis.mass * radius * radius
    ixx = chassis.mass * (3 * radius * radius + chassis.height**2) / 12.0
    ixx = max(ixx, 0.5 * izz * (1 + 1e-9))  # a valid inertia: the sum of any two exceeds the third
    # the body's cylinder starts a quarter wheel radius above the floor (origin: axle, at height r)
    body_z = -0.75 * r + 0.5 * chassis.height
    wm, ww = chassis.wheel_mass, chassis.wheel_width
    wheel_i = chassis.wheel_inertia(r)
    rotor = chassis.rotor_inertia(r)
    wheel_t = wm * (3 * r * r + ww * ww) / 12.0
    quat = f"{_g(np.cos(theta / 2))} 0 0 {_g(np.sin(theta / 2))}"
    wheels = "".join(
        f'<body name="w{side}{i}" pos="0 {_g(sign * half_track)} 0">'
        f'<joint name="j{side}{i}" type="hinge" axis="0 1 0" damping="0" armature="{_g(rotor)}"/>'
        f'<inertial pos="0 0 0" mass="{_g(wm)}" diaginertia="{_g(wheel_t)} {_g(wheel_i)} {_g(wheel_t)}"/>'
        f'<geom type="sphere" size="{_g(r)}" {_WHEEL} '
        f'friction="{_g(chassis.tyre_friction)} 0.005 0.0001" condim="3" solref="0.004 1"/></body>'
        for side, sign in (("l", 1.0), ("r", -1.0))
    )
    return (
        f'<body name="b{i}" pos="{_g(x)} {_g(y)} {_g(r)}" quat="{quat}"><freejoint name="f{i}"/>'
        f'<inertial pos="{_g(com_x)} 0 {_g(body_z)}" mass="{_g(chassis.mass)}" '
        f'diaginertia="{_g(ixx)} {_g(ixx)} {_g(izz)}"/>'
        f'<geom type="cylinder" size="{_g(radius)} {_g(0.5 * chassis.height)}" pos="0 0 {_g(body_z)}" '
        f'{_BODY} friction="0.3 0.005 0.0001" solref="0.004 1" mass="0"/>'
        f'<geom type="sphere" size="{_g(caster_r)}" pos="{_g(caster_x)} 0 {_g(caster_r - r)}" {_WHEEL} '
        f'friction="0 0 0" condim="1" mass="0"/>'
        f"{wheels}</body>"
    )


def team_mjcf(chassis: Chassis, limits: RobotLimits, poses: _Array) -> str:
    """The MJCF of ``n`` identical robots at ``poses`` on a flat floor.

    Parameters
    ----------
    chassis
        Mass, inertia, tyres and servos.
    limits
        Wheel radius, track and body radius (the speed limits act in the controller).
    poses
        ``(n, 3)`` rows ``(x, y, theta)``: each robot's axle midpoint (m) and heading (rad).

    Returns
    -------
    str
        The model, to be compiled by ``mujoco.MjModel.from_xml_string``.
        Robot i's joints are ``f{i}`` (free), ``jl{i}`` and ``jr{i}``
        (left and right wheels, positive forward); its actuators are
        ``2 i`` (left) and ``2 i + 1`` (right).

    Examples
    --------
    >>> from delayform.model import IROBOT_CREATE
    >>> from delayform.model.chassis import CREATE_CHASSIS
    >>> xml = team_mjcf(CREATE_CHASSIS, IROBOT_CREATE, np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]])
    >>> xml.count("<freejoint")
    2
    """
    poses = np.asarray(poses, dtype=np.float64)
    kv, tmax = _g(chassis.servo_gain), _g(chassis.max_torque)
    robots = "".join(_robot(i, chassis, limits, (p[0], p[1], p[2])) for i, p in enumerate(poses))
    actuators = "".join(
        f'<velocity joint="j{side}{i}" kv="{kv}" forcelimited="true" forcerange="-{tmax} {tmax}"/>'
        for i in range(poses.shape[0])
        for side in ("l", "r")
    )
    # semi-implicit Euler: the servo's torque and the contacts are solved together, so a stiff servo
    # drives the chassis as it should (an implicit servo term is applied after the contacts are solved
    # and lags the chassis by about dt servo_gain / inertia); stable thanks to the rotor inertia
    # (Chassis.rotor_inertia). Elliptic cones: the tyres' friction circle (slip in any direction)
    return (
        '<mujoco model="team"><compiler angle="radian" autolimits="true"/>'
        f'<option timestep="{_g(chassis.engine_grid()[0])}" integrator="Euler" cone="elliptic" impratio="10" gravity="0 0 -9.81">'
        '<flag energy="disable"/></option>'
        '<size memory="64M"/>'
        f'<worldbody><geom name="floor" type="plane" size="0 0 1" {_FLOOR} friction="0 0 0"/>{robots}</worldbody>'
        f"<actuator>{actuators}</actuator></mujoco>"
    )
