"""Many runs: seeded Monte Carlo runs over an imperfect network and sweeps over delays, gains and topologies.

Modules: :mod:`~delayform.simulation.experiments.montecarlo` (``monte_carlo``),
:mod:`~delayform.simulation.experiments.sweeps` (sweeps on a local or remote Dask
cluster). Their public names are re-exported by :mod:`delayform`.
"""
