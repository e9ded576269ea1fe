"""Input checks: the one error type, and the finiteness test of the hot paths."""
import math

import numpy as np

__all__ = ["RobofdiError", "all_finite"]


class RobofdiError(ValueError):
    """Invalid input: the message names the field (or joint, file) and what was expected."""


def all_finite(a: np.ndarray) -> bool:
    """True when every entry of ``a`` is finite. One reduction on the hot path (NaN and inf propagate through the
    sum); the exact element test only when the sum is not finite, so huge finite values never count as NaN."""
    return math.isfinite(a.sum()) or bool(np.isfinite(a).all())
