"""The scenario writer, kept importable here: it lives beside the reader in :mod:`delayform.scenario.write`."""

from delayform.scenario.write import scenario_toml

__all__ = ["scenario_toml"]
