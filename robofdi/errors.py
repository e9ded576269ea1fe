"""The one error type of robofdi's input checks."""

__all__ = ["RobofdiError"]


class RobofdiError(ValueError):
    """Invalid input: the message names the field (or joint, file) and what was expected."""
