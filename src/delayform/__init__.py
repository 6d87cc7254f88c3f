"""delayform: formation control of robot teams under two communication delays.

Exact CTCR stability maps in the (tau1, tau2) plane, dominant characteristic
roots and delay scheduling, formation design and simulation of
double-integrator agents and differential-drive robots, following
Cepeda-Gomez and Perico, "Formation Control of Non-holonomic Vehicles under
Time Delayed Communications".

The public names below are imported lazily, so ``import delayform`` stays
cheap and the command line starts fast.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: public name -> module that defines it
_EXPORTS: dict[str, str] = {
    # topology
    "Topology": "topology",
    "EigenvalueGroup": "topology",
    "paper_six": "topology",
    "ring": "topology",
    "complete": "topology",
    "star": "topology",
    "random_digraph": "topology",
    "grid": "topology",
    # characteristic equation
    "TwoDelayQuasiPolynomial": "characteristic",
    "CharacteristicFactor": "characteristic",
    "factors": "characteristic",
    "full_characteristic": "characteristic",
    # any number of delays (issue 19)
    "QuasiPolynomial": "quasipolynomial",
    # CTCR
    "stability_map": "analysis.ctcr",
    "crossing_map": "analysis.ctcr",
    "StabilityMap": "analysis.ctcr",
    "PAPER_POINTS": "analysis.ctcr",
    # characteristic roots
    "roots_in": "analysis.roots",
    "factor_roots_in": "analysis.roots",
    "rightmost_root": "analysis.roots",
    "count_roots_right_of": "analysis.roots",
    "dominant_root": "analysis.roots",
    "dominant_root_map": "analysis.roots",
    "DominantRoot": "analysis.roots",
    "DominantRootMap": "analysis.roots",
    # the eigenvalue plane (issue 11)
    "lambda_region": "analysis.plane",
    "LambdaRegion": "analysis.plane",
    "safe_delays": "analysis.plane",
    "SafeDelayMap": "analysis.plane",
    "SpectrumSet": "analysis.plane",
    "spectrum_bound": "analysis.plane",
    "SpectrumBound": "analysis.plane",
    # design
    "schedule_delays": "design.scheduling",
    "DelaySchedule": "design.scheduling",
    "design_gains": "design.gains",
    "GainDesign": "design.gains",
    "GainPlaneMap": "design.gains",
    # formation and simulation
    "formation_forcing": "formation",
    "named_formation": "formation",
    "predicted_final_positions": "formation",
    "simulate": "simulation",
    "Trajectory": "simulation",
    "paper_simulations": "simulation",
    "RobotLimits": "simulation",
    "IROBOT_CREATE": "simulation",
    "RobotCommands": "simulation",
    # imperfect networks and Monte Carlo
    "Network": "simulation.network",
    "LinkDelays": "simulation.network",
    "SmoothVariation": "simulation.network",
    "Jitter": "simulation.network",
    "BernoulliLoss": "simulation.network",
    "GilbertElliott": "simulation.network",
    "Sampling": "simulation.network",
    "MeasurementNoise": "simulation.network",
    "monte_carlo": "simulation.montecarlo",
    "MonteCarloResult": "simulation.montecarlo",
    "make_setup": "simulation.montecarlo",
    # sweeps, here or on Dask
    "executor_for": "sweeps",
    "sweep": "sweeps",
    "delay_sweep": "sweeps",
    "gain_sweep": "sweeps",
    "topology_sweep": "sweeps",
    "network_sweep": "sweeps",
    "SweepResult": "sweeps",
    # scenario files
    "load_scenario": "scenario",
    "Scenario": "scenario",
    # the browser explorer
    "Explorer": "app",
    "ExplorerLimits": "app",
    "scenario_toml": "app",
    # robots with bodies (issue 21)
    "Robot": "simulation",
    "Contact": "simulation",
    "Approach": "simulation",
    "closest_approach": "simulation",
    "assign_slots": "simulation.assignment",
    "SlotAssignment": "simulation.assignment",
    "BarrierFilter": "simulation.safety",
    "SafetyReport": "simulation.safety",
    # actuation delay (issue 21, item 4)
    "actuated_factor": "analysis.roots.actuated",
    "ActuatedStabilityMap": "analysis.ctcr.actuated",
}

__all__ = sorted(_EXPORTS) + ["errors", "__version__"]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        if name == "errors":
            return importlib.import_module("delayform.errors")
        raise AttributeError(f"module 'delayform' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"delayform.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
