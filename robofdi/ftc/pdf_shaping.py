"""Fault-tolerant PDF shaping for random-parameter systems — Wang, book ch. 2, Sec. 9.2, eq. (113).

    pdf_shaping_input   u_k = argmin_u ∫ K(s) (log Γ_y(s, θ̂, u)/Γ(s))² ds + R u², Γ the target PDF's transform (112)

The chapter gives no design procedure ("will therefore not be given"): the digest's reading [RECONSTRUCTED] is a
bounded scalar minimisation of (113) at every sample (scipy.optimize.minimize_scalar), with θ̂ from the diagnosis
(the scanning RLS (88)–(90) or the gradient (77)) — a fault moves θ̂, and the input that shapes the output PDF back
onto the target moves with it.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.optimize

from robofdi.errors import RobofdiError
from robofdi.observers.pdf import s_domain_criterion

__all__ = ["pdf_shaping_cost", "pdf_shaping_input"]


def pdf_shaping_cost(u: float, transform: Callable, theta, target: np.ndarray, s: np.ndarray, weight: np.ndarray,
                     R: float) -> float:
    """J(u) = ∫ K(s) (log Γ_y(s, θ̂, u)/Γ(s))² ds + R u² — eq. (113); transform(s, θ, u) → Γ_y on the grid s."""
    return s_domain_criterion(transform(s, theta, u), target, s, weight) + R * float(u) ** 2


def pdf_shaping_input(transform: Callable, theta, target, s, weight, R: float, bounds: tuple[float, float]) -> float:
    """u_k minimising (113) over ``bounds`` (|u| ≤ M_u of Sec. 5; the chapter's positive inputs: 0 < lower < upper).

    transform(s, θ̂, u) → the model's Γ_y(s, θ̂, u_k) (72) with the other multipliers of the sample fixed by the
    caller; target: Γ(s) of the desired PDF g (112) on the grid ``s``; weight: K(s) (76); R > 0."""
    if isinstance(R, bool) or not isinstance(R, (int, float, np.floating)) or not (np.isfinite(R) and R > 0):
        raise RobofdiError(f"pdf_shaping_input: field 'R' must be a finite number > 0, got {R!r}")
    lo, hi = (float(b) for b in bounds)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise RobofdiError(f"pdf_shaping_input: field 'bounds' must be (lower, upper) with lower < upper, got {bounds!r}")
    s, target, weight = (np.asarray(v, dtype=float) for v in (s, target, weight))
    res = scipy.optimize.minimize_scalar(pdf_shaping_cost, bounds=(lo, hi), method="bounded",
                                         args=(transform, theta, target, s, weight, float(R)),
                                         options={"xatol": 1e-10 * max(1.0, abs(hi - lo))})
    return float(res.x)
