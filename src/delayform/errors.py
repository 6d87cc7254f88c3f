"""The exceptions of delayform.

Every error the library raises on purpose is a subclass of
:class:`DelayformError` and of the built-in exception a user would expect
(``ValueError`` for bad input, ``RuntimeError`` for a computation that did
not succeed), so ``except ValueError`` keeps working for users who do not
know this module.

The tree::

    DelayformError
    +-- InputError (ValueError)            bad argument of any kind
    |   +-- TopologyError                  adjacency, informers, sizes
    |   |   +-- NoSpanningTreeError        Lemma 3: consensus impossible
    |   +-- GainError                      P, D not finite and positive
    |   +-- DelayError                     tau1, tau2 negative or not finite
    |   |   +-- NoStableDelaysError        delay scheduling: no stable pair in the box
    |   +-- QuasiPolynomialError           malformed coefficients
    |   |   +-- NeutralQuasiPolynomialError  not retarded: CTCR and roots refuse
    |   +-- FormationError                 desired shape of the wrong size
    |   +-- SimulationInputError           dt, duration, initial states
    |   +-- NetworkError                   an imperfect-network model (delays, loss, sampling, noise)
    |   +-- ClusterError                   Dask workers / scheduler address of a sweep
    |   +-- ScenarioError                  a TOML scenario file
    |   +-- ResourceLimitError             a job larger than the machine's memory or time budget
    |   +-- RobotProfileError              an unknown robot profile, or one the formation cannot meet
    |   +-- ControllerInputError           the on-robot controller: a bad state or message
    |   +-- RecordingError                 an MCAP recording that cannot be written there
    |   +-- FleetError                     a fleet run that cannot start (endpoint, port, network part)
    |   +-- LoopError                      a feedback loop (python-control object) outside what is analysed
    |       +-- UnstableLoopError          a loop unstable at tau = 0 asked for a delay margin
    +-- NotConvergedError (RuntimeError)   carries the partial result
    +-- FleetRunError (RuntimeError)       a fleet run whose robot or world process failed
    +-- EssentialSpectrumError (RuntimeError)  neutral: no root right of the essential spectrum
    +-- MissingExtraError (ImportError)    an optional package not installed: names the extra

    FragileNeutralWarning (UserWarning)    neutral: an answer at the delays given that is not
                                           strongly stable (small delay changes destabilize it)
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "DelayformError",
    "InputError",
    "TopologyError",
    "NoSpanningTreeError",
    "GainError",
    "DelayError",
    "NoStableDelaysError",
    "NoStableGainsError",
    "QuasiPolynomialError",
    "NeutralQuasiPolynomialError",
    "FormationError",
    "SimulationInputError",
    "NetworkError",
    "ClusterError",
    "ScenarioError",
    "ResourceLimitError",
    "NotConvergedError",
    "RobotProfileError",
    "ControllerInputError",
    "RecordingError",
    "FleetError",
    "FleetRunError",
    "EssentialSpectrumError",
    "FragileNeutralWarning",
    "LoopError",
    "UnstableLoopError",
    "MissingExtraError",
]


class DelayformError(Exception):
    """Base class of every error raised on purpose by delayform."""


class InputError(DelayformError, ValueError):
    """An argument that delayform cannot work with."""


class TopologyError(InputError):
    """A communication topology that is malformed for protocol (paper, eq. 1).

    Raised for a non-square or non-binary adjacency matrix, self-loops, and
    agents without informers (the protocol divides by the in-degree).
    """


class NoSpanningTreeError(TopologyError):
    """The topology has no spanning tree, so consensus is impossible (Lemma 3)."""


class GainError(InputError):
    """A control gain P or D that is not a finite positive number."""


class DelayError(InputError):
    """A delay tau1 or tau2 that is negative or not finite."""


class NoStableDelaysError(DelayError):
    """No delay pair in the box given to delay scheduling is stable."""


class QuasiPolynomialError(InputError):
    """Coefficients of a quasi-polynomial (paper, eq. 5) that are malformed."""


class NeutralQuasiPolynomialError(QuasiPolynomialError):
    """A quasi-polynomial of neutral type, outside what CTCR here treats."""


class FormationError(InputError):
    """A desired formation that does not fit the team."""


class SimulationInputError(InputError):
    """A time step, duration or initial state that cannot be simulated."""


class NetworkError(InputError):
    """An imperfect-network model that cannot be simulated (:mod:`delayform.model.network`).

    Raised for a probability outside [0, 1], a delay matrix of the wrong size,
    jitter or variation that would make a delay negative or shorter than the
    step, a negative noise level, or a sampling rate that is not positive.
    """


class ClusterError(InputError):
    """Where to run a sweep: a bad number of workers, or a Dask scheduler that cannot be reached."""


class ScenarioError(InputError):
    """A scenario file that is missing a field, has an unknown key or a wrong value."""


class ResourceLimitError(InputError):
    """A job that would need more memory or time than the machine has or the budget allows.

    Raised before the job starts (see :mod:`delayform.resources`); the
    message says how much would be needed and which setting to change.
    """


class RobotProfileError(InputError):
    """An unknown robot profile, or a profile whose limits the scenario's formation cannot meet."""


class ControllerInputError(InputError):
    """A state, message or time the on-robot controller cannot use (:mod:`delayform.deploy.controller`)."""


class RecordingError(InputError):
    """An MCAP recording that cannot be written: a folder that is missing or not writable, a bad name."""


class FleetError(InputError):
    """A fleet run that cannot start: a bad endpoint or port, a network part not applied to real messages."""


class FleetRunError(DelayformError, RuntimeError):
    """A fleet run that started and failed: a robot or world process that died or never became ready."""


class NotConvergedError(DelayformError, RuntimeError):
    """An iterative computation that did not reach its tolerance.

    Parameters
    ----------
    message
        What did not converge and how far it got.
    partial
        The partial result, for callers that can use it.
    """

    def __init__(self, message: str, partial: Any = None) -> None:
        super().__init__(message)
        self.partial = partial


class NoStableGainsError(GainError):
    """No gains within the bounds given to gain design make the team converge."""


class EssentialSpectrumError(DelayformError, RuntimeError):
    """A neutral system whose rightmost root does not lie right of its essential spectrum.

    The supremum of the real parts of the roots is then the abscissa of the
    essential spectrum at the delays given (or a root lies within the search
    margin of it), so there is no rightmost root to return.

    Parameters
    ----------
    message
        What was asked and the abscissae.
    abscissa
        The essential abscissa at the delays given (nominal): for commensurate
        delays that of the difference equation at exactly these delays, for
        rationally independent ones the robust C_D.
    line
        The abscissa right of which no root was certified to lie (the nominal
        abscissa plus the search margin); None when the question was about a
        line left of it.
    robust_abscissa
        C_D, the robust (strong) essential abscissa, reached under arbitrarily
        small changes of the delays (equal to ``abscissa`` when not given).
    """

    def __init__(
        self, message: str, abscissa: float, line: float | None = None, robust_abscissa: float | None = None
    ) -> None:
        super().__init__(message)
        self.abscissa = abscissa
        self.line = line
        self.robust_abscissa = abscissa if robust_abscissa is None else robust_abscissa


class FragileNeutralWarning(UserWarning):
    """An answer for a neutral system at its delays as given that is not strongly stable.

    The robust essential abscissa C_D is >= 0: an arbitrarily small change of
    the delays moves the essential spectrum to Re s = C_D, so a system stable
    at the delays given is destabilized by it (Hale and Verduyn Lunel 2002).
    """


class LoopError(InputError):
    """A feedback loop that :mod:`delayform.loops` cannot turn into a quasi-polynomial.

    Raised for an object that is not a linear continuous-time system, a
    discrete-time loop or one carrying a delay of its own, an improper loop,
    a biproper loop with |L(j inf)| >= 1 (neutral type, no delay margin), and
    a MIMO loop where a SISO one is needed; the message says which.
    """


class UnstableLoopError(LoopError):
    """A loop whose closed loop 1 + L(s) is not stable without delay, asked for a delay margin."""


class MissingExtraError(DelayformError, ImportError):
    """A feature whose optional packages are not installed; the message names the extra to install.

    ``pip install delayform`` brings the analysis and the plain simulation;
    the explorer, Dask clusters, ROS 2 recordings and python-control loops
    come with extras (``pip install 'delayform[explore]'``). An ``ImportError``
    too, so code that already guards an import keeps working.

    Parameters
    ----------
    message
        One line: what needs which packages, and the ``pip install`` that brings them.
    extra
        The extra's name (``"explore"``, ``"cluster"``, ``"ros"``, ``"control"``).
    """

    def __init__(self, message: str, extra: str = "") -> None:
        super().__init__(message)
        self.extra = extra
