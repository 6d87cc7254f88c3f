"""Agent models: double integrators, differential-drive robots with limits, and the commands they execute.

Modules: :mod:`~delayform.simulation.models.robots` (agent models, robot limits,
ideal commands), :mod:`~delayform.simulation.models.commands` (speed, turn rate,
wheel speeds and where a limit was exceeded). Their public names are
re-exported by :mod:`delayform.simulation`.
"""
