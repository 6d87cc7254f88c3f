"""The optional parts of delayform and the one check that names the extra to install.

``pip install delayform`` brings what the analysis and the plain simulation
need; the rest comes with extras named for what they bring. Every place
that uses an optional package calls :func:`require_extra` first, so a
missing one is one line saying which extra to install
(:class:`~delayform.errors.MissingExtraError`), never a raw ImportError
from deep inside a run.
"""

from __future__ import annotations

import importlib.util

from delayform.errors import MissingExtraError

__all__ = ["EXTRAS", "require_extra"]

#: extra -> (what it brings, in a user's words; the top-level modules it installs)
EXTRAS: dict[str, tuple[str, tuple[str, ...]]] = {
    # the explorer's page switches the safety filter on and off: its extra brings Clarabel too
    "explore": ("the explorer (delayform explore)", ("starlette", "uvicorn", "plotly", "clarabel")),
    "cluster": ("runs on a Dask cluster (workers or a scheduler)", ("dask", "distributed")),
    "ros": ("ROS 2 recordings (MCAP)", ("mcap", "rosbags")),
    "fleet": ("the team as processes over Zenoh (delayform fleet)", ("zenoh", "mcap", "rosbags")),
    "control": ("python-control loops", ("control",)),
    "safety": ("the safety filter (safety = \"barrier\")", ("clarabel",)),
    # the same solver, for the semidefinite programs of the time-varying delay certificates
    "certificates": ("the time-varying delay certificates (Lyapunov-Krasovskii LMIs)", ("clarabel",)),
    "physics": ("robots with mass in a physics engine (model = \"physics\")", ("mujoco",)),
}


def _installed(module: str) -> bool:
    """Whether a top-level module can be found, without importing it (plotly is only a file here)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a finder that refuses it, or a half-removed module
        return False


def require_extra(extra: str) -> None:
    """Refuse, in one line naming the extra to install, when a module of ``extra`` is missing.

    Parameters
    ----------
    extra
        A key of :data:`EXTRAS`: ``"explore"``, ``"cluster"``, ``"ros"``, ``"control"``, ``"safety"``, ``"certificates"`` or ``"physics"``.

    Raises
    ------
    MissingExtraError
        When any of the extra's modules is not installed; the message ends
        with ``pip install 'delayform[<extra>]'``.

    >>> require_extra("numpy")
    Traceback (most recent call last):
    ...
    KeyError: "no extra 'numpy'"
    """
    if extra not in EXTRAS:  # a programming error of delayform itself, not the user's
        raise KeyError(f"no extra {extra!r}")
    purpose, modules = EXTRAS[extra]
    missing = [m for m in modules if not _installed(m)]
    if missing:
        raise MissingExtraError(
            f"{purpose}: {', '.join(missing)} not installed; pip install 'delayform[{extra}]'", extra=extra
        )
