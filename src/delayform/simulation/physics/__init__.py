"""Robots with mass: differential-drive bodies, wheel servos and contacts in the MuJoCo engine.

``simulate(..., model="physics")`` runs the team here
(:func:`~delayform.simulation.physics.engine.integrate_physics`); the
robot's numbers are a :class:`~delayform.model.Chassis` (a noun, carried by
:class:`~delayform.model.Robot` and by each robot profile) beside its
:class:`~delayform.model.RobotLimits`; it is re-exported here.
:func:`compare_with_kinematic` says what the dynamics cost against the
kinematic model; :func:`identify_actuation` measures the robot's own lag and
:func:`actuation_verdict` asks the exact chart again with it.
"""

from delayform.model.chassis import CREATE_CHASSIS, Chassis
from delayform.simulation.physics.compare import (
    ActuationVerdict,
    KinematicComparison,
    actuation_verdict,
    compare_with_kinematic,
    kinematic_twin,
)
from delayform.simulation.physics.identify import ServoIdentification, identify_actuation

__all__ = [
    "Chassis",
    "CREATE_CHASSIS",
    "compare_with_kinematic",
    "KinematicComparison",
    "kinematic_twin",
    "identify_actuation",
    "ServoIdentification",
    "actuation_verdict",
    "ActuationVerdict",
]
