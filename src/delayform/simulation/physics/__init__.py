"""Robots with mass: differential-drive bodies, wheel servos and contacts in the MuJoCo engine.

``simulate(..., model="physics")`` runs the team here
(:func:`~delayform.simulation.physics.engine.integrate_physics`); the
robot's numbers are a :class:`Chassis` beside its
:class:`~delayform.simulation.robots.RobotLimits`.
"""

from delayform.simulation.physics.chassis import CREATE_CHASSIS, Chassis

__all__ = ["Chassis", "CREATE_CHASSIS"]
