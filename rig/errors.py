"""Exceptions of the rig. Each is still catchable as the built-in it specialises."""


class RigError(Exception):
    """Base class of every error raised by :mod:`rig`."""


class ConfigError(RigError, ValueError):
    """An invalid parameter or scene value; the message names the key, the value and what is valid."""


class ForceRequired(ConfigError):
    """A refusal to replace or change something that exists (an output file, a sweep directory
    of another plan) unless asked to (``force=True``). The message says what exists and names no
    command-line flag; ``action`` says what forcing would do (e.g. "overwrite it"), for a caller
    to offer its own way of forcing."""

    def __init__(self, message: str, action: str = "overwrite it"):
        super().__init__(message)
        self.action = action


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
