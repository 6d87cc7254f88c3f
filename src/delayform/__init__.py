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

#: The public names grouped by what they are, in the order a user meets them (docs/api.md and the
#: site's reference use the same groups and titles): group title -> {public name -> its module}.
_GROUPS: dict[str, dict[str, str]] = {
    "Topologies and the problem's nouns": {
        "Topology": "topology",
        "EigenvalueGroup": "topology",
        "paper_six": "topology",
        "ring": "topology",
        "complete": "topology",
        "star": "topology",
        "random_digraph": "topology",
        "grid": "topology",
        "Team": "model",
        "Delays": "model",
        "Start": "model",
        "formation_forcing": "formation",
        "named_formation": "formation",
        "predicted_final_positions": "formation",
    },
    "Characteristic equations": {
        "TwoDelayQuasiPolynomial": "characteristic",
        "CharacteristicFactor": "characteristic",
        "factors": "characteristic",
        "full_characteristic": "characteristic",
        "QuasiPolynomial": "quasipolynomial",
        "actuated_factor": "analysis.roots.actuated",
    },
    "Analysis: stability maps": {
        "stability_map": "analysis.ctcr",
        "crossing_map": "analysis.ctcr",
        "StabilityMap": "analysis.ctcr",
        "ActuatedStabilityMap": "analysis.ctcr.actuated",
        "PAPER_POINTS": "analysis.ctcr",
    },
    "Analysis: roots": {
        "roots_in": "analysis.roots",
        "factor_roots_in": "analysis.roots",
        "rightmost_root": "analysis.roots",
        "count_roots_right_of": "analysis.roots",
        "dominant_root": "analysis.roots",
        "dominant_root_map": "analysis.roots",
        "DominantRoot": "analysis.roots",
        "DominantRootMap": "analysis.roots",
        "delay_reach": "analysis.roots.single",
        "difference_operator": "analysis.neutral",
        "DifferenceOperator": "analysis.neutral",
        "neutral_spectrum": "analysis.neutral",
        "NeutralSpectrum": "analysis.neutral",
        "neutral_roots_in": "analysis.neutral",
        "neutral_rightmost_root": "analysis.neutral",
        "neutral_count_right_of": "analysis.neutral",
    },
    "Analysis: regions and spectrum sets": {
        "lambda_region": "analysis.plane",
        "LambdaRegion": "analysis.plane",
        "safe_delays": "analysis.plane",
        "SafeDelayMap": "analysis.plane",
        "SpectrumSet": "analysis.plane",
        "spectrum_bound": "analysis.plane",
        "SpectrumBound": "analysis.plane",
    },
    "Analysis: certificates": {
        "time_varying_delay_margin": "analysis.certificates",
        "certify_time_varying": "analysis.certificates",
        "TimeVaryingMargin": "analysis.certificates",
        "DelayCertificate": "analysis.certificates",
    },
    "Analysis: networks": {
        "link_dominant_root": "analysis.network",
        "LinkDominantRoot": "analysis.network",
        "robust_stability": "analysis.network",
        "RobustStability": "analysis.network",
        "jitter_margin": "analysis.network",
        "jitter_margin_map": "analysis.network",
        "JitterMargin": "analysis.network",
        "JitterMarginMap": "analysis.network",
        "mean_square_stability": "analysis.network",
        "bursty_mean_square_stability": "analysis.network",
        "MeanSquareStability": "analysis.network",
    },
    "Analysis: python-control loops": {
        "delay_margin": "loops",
        "DelayMargin": "loops",
        "Crossover": "loops",
        "loop_quasi_polynomial": "loops",
        "loop_polynomials": "loops",
        "loop_characteristic": "loops",
    },
    "Design": {
        "schedule_delays": "design.scheduling",
        "DelaySchedule": "design.scheduling",
        "design_gains": "design.gains",
        "GainDesign": "design.gains",
        "GainPlaneMap": "design.gains",
        "box_is_stable": "design.gains",
        "gain_crossing_curves": "design.gains",
        "design_loop_gains": "design.loop_gains",
        "LoopGainDesign": "design.loop_gains",
        "pd_loop_quasi_polynomial": "design.loop_gains",
    },
    "Simulation": {
        "simulate": "simulation",
        "RunOptions": "simulation.runs.options",
        "Trajectory": "simulation",
        "paper_simulations": "simulation",
        "Robot": "model",
        "RobotLimits": "model",
        "IROBOT_CREATE": "model",
        "RobotCommands": "simulation",
        "Contact": "simulation",
        "Approach": "simulation",
        "closest_approach": "simulation",
        "assign_slots": "simulation.bodies.assignment",
        "SlotAssignment": "simulation.bodies.assignment",
        "BarrierFilter": "model",
        "SafetyReport": "simulation.bodies.safety",
        # robots with mass in a physics engine (Robot(model="physics"))
        "Chassis": "model",
        "compare_with_kinematic": "simulation.physics",
        "KinematicComparison": "simulation.physics",
        "identify_actuation": "simulation.physics",
        "ServoIdentification": "simulation.physics",
        "actuation_verdict": "simulation.physics",
        "ActuationVerdict": "simulation.physics",
    },
    "Simulation: imperfect networks": {
        "Network": "model",
        "LinkDelays": "model",
        "SmoothVariation": "model",
        "Jitter": "model",
        "BernoulliLoss": "model",
        "GilbertElliott": "model",
        "Sampling": "model",
        "MeasurementNoise": "model",
    },
    "Simulation: Monte Carlo and sweeps": {
        "monte_carlo": "simulation.experiments.montecarlo",
        "MonteCarloResult": "simulation.experiments.montecarlo",
        "make_setup": "simulation.experiments.montecarlo",
        "run_quantile": "simulation.experiments.montecarlo",
        "SerialExecutor": "simulation.experiments.montecarlo",
        "executor_for": "simulation.experiments.sweeps",
        "sweep": "simulation.experiments.sweeps",
        "delay_sweep": "simulation.experiments.sweeps",
        "gain_sweep": "simulation.experiments.sweeps",
        "topology_sweep": "simulation.experiments.sweeps",
        "network_sweep": "simulation.experiments.sweeps",
        "SweepResult": "simulation.experiments.sweeps",
        "check_workers": "simulation.experiments.sweeps",
        "check_scheduler": "simulation.experiments.sweeps",
        "parse_scheduler": "simulation.experiments.sweeps",
        "usable_cores": "simulation.experiments.sweeps",
    },
    "Deployment": {
        "RobotProfile": "model",
        "PROFILES": "model",
        "robot_profile": "deploy",
        "FormationController": "deploy",
        "NeighbourMessage": "deploy",
        "write_mcap": "deploy.recording",
        "run_fleet": "fleet",
        "robot_check": "report.check",
        "RobotCheck": "report.check",
    },
    "Outputs: scenarios, reports and the explorer": {
        "load_scenario": "scenario",
        "Scenario": "scenario",
        "write_report": "report",
        "Explorer": "app",
        "ExplorerLimits": "app",
        "scenario_toml": "scenario",
        "example_path": "packaged",
        "example_names": "packaged",
    },
    "Errors": {
        **{name: "errors" for name in (
            "DelayformError", "InputError", "TopologyError", "NoSpanningTreeError", "GainError", "DelayError",
            "NoStableDelaysError", "NoStableGainsError", "QuasiPolynomialError", "NeutralQuasiPolynomialError",
            "FormationError", "SimulationInputError", "NetworkError", "ClusterError", "ScenarioError",
            "ResourceLimitError", "RobotProfileError", "ControllerInputError", "RecordingError", "LoopError",
            "UnstableLoopError", "NotConvergedError", "EssentialSpectrumError", "MissingExtraError", "FleetError", "FleetRunError",
            "FragileNeutralWarning",
        )},  # fmt: skip
        "MissingGlyphWarning": "plots",
    },
}

#: public name -> module that defines it
_EXPORTS: dict[str, str] = {name: module for names in _GROUPS.values() for name, module in names.items()}

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
