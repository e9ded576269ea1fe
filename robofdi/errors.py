"""Input checks: the one error type, and the finiteness test of the hot paths."""
import math

import numpy as np

__all__ = ["RobofdiError", "all_finite"]


class RobofdiError(ValueError):
    """Invalid input: the message names the field (or joint, file) and what was expected."""


def all_finite(a: np.ndarray) -> bool:
    """True when every entry of the vector ``a`` is finite. One dot product on the hot path (NaN and inf propagate
    through it, and it is the cheapest reduction for short vectors); the exact element test only when that is not
    finite, so huge finite values never count as NaN."""
    return math.isfinite(a.dot(a)) or bool(np.isfinite(a).all())
