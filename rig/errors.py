"""Exceptions of the rig. Each is still catchable as the built-in it specialises."""

import importlib


class RigError(Exception):
    """Base class of every error raised by :mod:`rig`."""


class ConfigError(RigError, ValueError):
    """An invalid parameter or scene value; the message names the key, the value and what is valid."""


class DivergenceError(RigError, FloatingPointError):
    """A simulation produced a non-finite state.

    Attributes
    ----------
    time_s : float
        Simulated time of the last finite state [s].
    state : numpy.ndarray
        That state, ``(theta_1..theta_n [rad], omega_1..omega_n [rad/s])``.
    """

    def __init__(self, message: str, time_s: float, state):
        super().__init__(message)
        self.time_s = time_s
        self.state = state


class MissingExtraError(RigError, ImportError):
    """An optional feature's package is not installed; the message names the extra that adds it."""


def import_extra(module: str, extra: str, feature: str):
    """``importlib.import_module(module)``, or :class:`MissingExtraError` saying that ``feature``
    needs it and which extra of pendulum-daq installs it (``pip install 'pendulum-daq[extra]'``).
    Only the absence of ``module`` itself is translated; any other import error propagates."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        top = module.split(".")[0]
        if exc.name is None or exc.name.split(".")[0] != top:
            raise
        raise MissingExtraError(f"{feature} needs {top}, which is not installed: "
                                f"pip install 'pendulum-daq[{extra}]'") from exc
