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
    # the problem's nouns
    "Team": "model",
    "Delays": "model",
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
    # run-time hardening (issue 24, items 2-5)
    "check_workers": "sweeps",
    "check_scheduler": "sweeps",
    "parse_scheduler": "sweeps",
    "usable_cores": "sweeps",
    "run_quantile": "simulation.montecarlo",
    "delay_reach": "analysis.roots.single",
    # from design to robots (issue 22): profiles, the on-robot controller, MCAP, the check
    "RobotProfile": "deploy",
    "PROFILES": "deploy",
    "robot_profile": "deploy",
    "FormationController": "deploy",
    "NeighbourMessage": "deploy",
    "write_mcap": "deploy.recording",
    "robot_check": "report.check",
    "RobotCheck": "report.check",
    # guarantees for real networks (issue 20)
    "link_dominant_root": "analysis.network",
    "LinkDominantRoot": "analysis.network",
    "robust_stability": "analysis.network",
    "RobustStability": "analysis.network",
    "jitter_margin": "analysis.network",
    "jitter_margin_map": "analysis.network",
    "JitterMargin": "analysis.network",
    "JitterMarginMap": "analysis.network",
    "mean_square_stability": "analysis.network",
    "MeanSquareStability": "analysis.network",
    # bursty (Gilbert-Elliott) loss in the mean square (issue 20, branch jitter-view)
    "bursty_mean_square_stability": "analysis.network",
    # neutral quasi-polynomials (issue 19, item 5)
    "difference_operator": "analysis.neutral",
    "DifferenceOperator": "analysis.neutral",
    "neutral_spectrum": "analysis.neutral",
    "NeutralSpectrum": "analysis.neutral",
    "neutral_roots_in": "analysis.neutral",
    "neutral_rightmost_root": "analysis.neutral",
    "neutral_count_right_of": "analysis.neutral",
    # python-control loops: exact delay margins, loop quasi-polynomials (issue 23)
    "delay_margin": "loops",
    "DelayMargin": "loops",
    "Crossover": "loops",
    "loop_quasi_polynomial": "loops",
    "loop_polynomials": "loops",
    "loop_characteristic": "loops",
    "design_loop_gains": "design.loop_gains",
    "LoopGainDesign": "design.loop_gains",
    "pd_loop_quasi_polynomial": "design.loop_gains",
    # example scenarios shipped in the wheel (issue 23)
    "example_path": "packaged",
    "example_names": "packaged",
    # issue 24: every name docs/api.md shows in bold is importable from here
    "box_is_stable": "design.gains",
    "gain_crossing_curves": "design.gains",
    "SerialExecutor": "simulation.montecarlo",
    "write_report": "report",
    **{name: "errors" for name in (
        "DelayformError", "InputError", "TopologyError", "NoSpanningTreeError", "GainError", "DelayError",
        "NoStableDelaysError", "NoStableGainsError", "QuasiPolynomialError", "NeutralQuasiPolynomialError",
        "FormationError", "SimulationInputError", "NetworkError", "ClusterError", "ScenarioError",
        "ResourceLimitError", "NotConvergedError", "MissingExtraError",
    )},  # fmt: skip
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
    # robots with mass in a physics engine (model="physics")
    "Chassis": "simulation.physics",
    "compare_with_kinematic": "simulation.physics",
    "KinematicComparison": "simulation.physics",
    "identify_actuation": "simulation.physics",
    "ServoIdentification": "simulation.physics",
    "actuation_verdict": "simulation.physics",
    "ActuationVerdict": "simulation.physics",
    # Lyapunov-Krasovskii certificates for time-varying delays of linear DDEs
    "time_varying_delay_margin": "analysis.certificates",
    "certify_time_varying": "analysis.certificates",
    "TimeVaryingMargin": "analysis.certificates",
    "DelayCertificate": "analysis.certificates",
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
