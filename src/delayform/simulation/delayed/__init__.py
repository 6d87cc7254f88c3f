"""Integrators of delayed reception: RK4 with a bounded history, the actuation buffer, what each agent hears.

Modules: :mod:`~delayform.simulation.delayed.integrator` (fixed-step RK4 with
Hermite look-ups into a bounded history), :mod:`~delayform.simulation.delayed.actuation`
(the buffer of commands applied late), :mod:`~delayform.simulation.delayed.reception`
(what each agent hears over an imperfect network, the per-link integrator),
:mod:`~delayform.simulation.delayed.filtered` (small teams under the safety filter).
"""
