"""The errors :mod:`processing` raises: all derive from :class:`ProcessingError`, and the bad
input ones are also ``ValueError`` (catchable as the built-in)."""


class ProcessingError(Exception):
    """Base class of every error raised by :mod:`processing`."""


class SettingsError(ProcessingError, ValueError):
    """Invalid analyzer settings, or settings that do not fit the data (e.g. ``nperseg`` longer
    than a record); the message names the field, the value and what is valid."""


class ChannelDataError(ProcessingError, ValueError):
    """Channel data of the wrong shape, non-finite, or a channel name that is not present."""


__all__ = ["ProcessingError", "SettingsError", "ChannelDataError"]
