"""Exceptions of bb2_control: each is a ValueError subclass with a message that says what is wrong."""
from __future__ import annotations

__all__ = ["ControlConfigError", "NonFiniteInputError", "UnknownStackError", "PathFollowingError"]


class ControlConfigError(ValueError):
    """A gain, tuning or configuration file is missing, malformed or out of range."""


class NonFiniteInputError(ValueError):
    """A controller input (reference or measurement) is NaN or infinite; no state was changed."""


class UnknownStackError(ValueError):
    """The requested control stack name is not one of the named configurations."""


class PathFollowingError(ValueError):
    """The path cannot be followed at this point (e.g. zero path speed or vertical tangent)."""
