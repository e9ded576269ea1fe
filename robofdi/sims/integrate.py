"""Fixed-step integration of a plant's ODE between control samples."""
from __future__ import annotations

from collections.abc import Callable

__all__ = ["rk4"]


def rk4(f: Callable, x, h: float, steps: int, t: float = 0.0):
    """``steps`` classical Runge–Kutta (RK4) steps of ẋ = f(t, x) from (t, x) with step ``h`` [s] → (x, t)."""
    for _ in range(steps):
        k1 = f(t, x)
        k2 = f(t + 0.5 * h, x + 0.5 * h * k1)
        k3 = f(t + 0.5 * h, x + 0.5 * h * k2)
        k4 = f(t + h, x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += h
    return x, t
