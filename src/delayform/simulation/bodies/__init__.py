"""Robots with bodies: the exact closest approach and contacts, the safety filter, slot assignment.

Modules: :mod:`~delayform.simulation.bodies.approach` (closest approach of a run,
contacts), :mod:`~delayform.simulation.bodies.safety` (control barrier functions
that keep the bodies apart), :mod:`~delayform.simulation.bodies.assignment`
(which robot takes which slot). Their public names are re-exported by
:mod:`delayform.simulation`.
"""
