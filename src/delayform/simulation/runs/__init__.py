"""A single run of the team: ``simulate``, the integrator table, run options, loose call forms, the result.

Modules: :mod:`~delayform.simulation.runs.runner` (``simulate``),
:mod:`~delayform.simulation.runs.integrators` (the integrator table, one entry per
agent model), :mod:`~delayform.simulation.runs.options` (how a run is carried
out), :mod:`~delayform.simulation.runs.compat` (the loose call forms),
:mod:`~delayform.simulation.runs.trajectory` (the result and its metrics).
Their public names are re-exported by :mod:`delayform.simulation`.
"""
