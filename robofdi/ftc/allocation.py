"""Thruster (control) allocation: τ = B diag(e) u solved for u, with the effectiveness e from the diagnosed health.

Antonelli's survey, Sec. 5: TCM column deletion (Romeo, ODIN), the minimum-norm pseudo-inverse (Sarkar/Podder, eq. (8)
with E_f = J M⁻¹ B S_f) and saturation-aware allocation ([41]). Pure functions:

* :func:`column_deletion_allocation` — delete the failed thrusters' columns, minimum-norm u over the rest;
* :func:`pseudo_inverse_allocation` — minimum-norm u of B diag(e) u = τ (e_i = 0 is column deletion, the digest's
  [DERIVED] equivalence; 0 < e_i < 1 shifts effort to healthy thrusters);
* :func:`constrained_allocation` — a QP honouring the thrust limits (qpsolvers with the clarabel backend):
  min ‖B diag(e) u − τ‖² + ε‖u‖² subject to lower ≤ u ≤ upper; it returns the unattained part of τ;
* :func:`null_space_allocation` — u = B⁺τ + (I − B⁺B)z with z chosen to bring u inside the thrust limits
  (alternating projections between {u : B diag(e) u = τ} and the box), the digest's null-space redistribution;
* :func:`direction_preserving_allocation` — when τ is not attainable, the largest α ∈ (0, 1] with α τ attainable
  (an LP), so the wrench keeps its direction and only its size is cut;
* :func:`capability` — the largest wrench attainable along each axis (LP), "how much capability remains".

:class:`ThrustReallocation` is the loop's :class:`~robofdi.protocols.Accommodation`: the controller's thrust demand
u_cmd is turned back into the wrench τ = B u_cmd it stands for and re-allocated with the health's failed thrusters.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import linprog

from robofdi.errors import RobofdiError, all_finite
from robofdi.protocols import Health

__all__ = ["AllocationResult", "check_allocation", "column_deletion_allocation", "pseudo_inverse_allocation",
           "constrained_allocation", "null_space_allocation", "direction_preserving_allocation", "capability",
           "ThrustReallocation", "ALLOCATORS"]

ALLOCATORS = ("column_deletion", "pseudo_inverse", "constrained", "null_space", "direction_preserving")


@dataclass(frozen=True)
class AllocationResult:
    """u [N]: thrust per thruster; attained: B diag(e) u; unattained: τ − attained (0 when the demand was met)."""

    u: np.ndarray
    attained: np.ndarray
    unattained: np.ndarray

    @property
    def feasible(self) -> bool:
        """True when the whole demand was attained (to 1e-6 of its size)."""
        return float(np.linalg.norm(self.unattained)) <= 1e-6 * max(1.0, float(np.linalg.norm(self.attained)))


def check_allocation(B, tau, effectiveness=None, lower=None, upper=None):
    """Validated (B (6, p), τ (6,), e (p,), lower (p,), upper (p,)) as float arrays; clear errors otherwise."""
    B = np.asarray(B, dtype=float)
    if B.ndim != 2 or B.shape[0] != 6 or B.shape[1] < 1:
        raise RobofdiError(f"allocation: field 'B' must be a 6 × p thruster control matrix, got shape {B.shape}")
    if not np.all(np.isfinite(B)):
        raise RobofdiError("allocation: field 'B' must be finite")
    p = B.shape[1]
    tau = np.asarray(tau, dtype=float)
    if tau.shape != (6,) or not all_finite(tau):
        raise RobofdiError(f"allocation: field 'tau' must be 6 finite wrench components [N, N·m], got {tau!r}")
    e = np.ones(p) if effectiveness is None else np.asarray(effectiveness, dtype=float)
    if e.shape != (p,) or not np.all(np.isfinite(e)) or np.any(e < 0) or np.any(e > 2):
        raise RobofdiError(f"allocation: field 'effectiveness' must hold {p} values in [0, 2], got {effectiveness!r}")
    lo = np.full(p, -np.inf) if lower is None else np.broadcast_to(np.asarray(lower, dtype=float), (p,)).copy()
    hi = np.full(p, np.inf) if upper is None else np.broadcast_to(np.asarray(upper, dtype=float), (p,)).copy()
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo > 0) or np.any(hi < 0) or np.any(lo >= hi):
        raise RobofdiError(f"allocation: saturation limits must satisfy lower <= 0 <= upper and lower < upper per "
                           f"thruster, got lower={lo.tolist()}, upper={hi.tolist()}")
    return B, tau, e, lo, hi


@lru_cache(maxsize=64)
def _pinv_cached(B_bytes: bytes, shape: tuple, e_bytes: bytes) -> np.ndarray:
    B = np.frombuffer(B_bytes).reshape(shape)
    return np.linalg.pinv(B * np.frombuffer(e_bytes))


def _weighted_pinv(B: np.ndarray, e: np.ndarray) -> np.ndarray:
    """(B diag(e))⁺, cached per (B, e): a loop re-allocates with the same health for long stretches."""
    return _pinv_cached(np.ascontiguousarray(B).tobytes(), B.shape, np.ascontiguousarray(e).tobytes())


def _result(B, e, u, tau) -> AllocationResult:
    attained = B @ (e * u)
    return AllocationResult(u, attained, tau - attained)


def pseudo_inverse_allocation(B, tau, effectiveness=None) -> AllocationResult:
    """Minimum-norm u with B diag(e) u = τ: u = (B diag(e))⁺ τ — the weighted pseudo-inverse of Sec. 5
    (least squares when B diag(e) has lost rank 6)."""
    B, tau, e, _, _ = check_allocation(B, tau, effectiveness)
    u = _weighted_pinv(B, e) @ tau
    return _result(B, e, u, tau)


def column_deletion_allocation(B, tau, failed: Sequence[int] = ()) -> AllocationResult:
    """TCM column deletion (Romeo, ODIN): minimum-norm u over the remaining columns, u_i = 0 for failed i."""
    B, tau, _, _, _ = check_allocation(B, tau)
    p = B.shape[1]
    failed = sorted(set(int(i) for i in failed))
    if any(i < 0 or i >= p for i in failed):
        raise RobofdiError(f"allocation: field 'failed' must hold thruster indices in [0, {p - 1}], got {failed}")
    keep = [i for i in range(p) if i not in failed]
    u = np.zeros(p)
    if keep:
        u[keep] = np.linalg.pinv(B[:, keep]) @ tau
    e = np.ones(p)
    e[failed] = 0.0
    return _result(B, e, u, tau)


def constrained_allocation(B, tau, lower, upper, effectiveness=None, regularisation: float = 1e-6) -> AllocationResult:
    """Saturation-aware allocation ([41] of the survey): the QP
    min_u ‖B diag(e) u − τ‖² + ε‖u‖²  s.t.  lower ≤ u ≤ upper  (qpsolvers, clarabel).

    When the minimum-norm solution already fits the limits it is the QP's solution (ε → 0), so the QP is only
    solved when a thruster would saturate. ``unattained`` reports what of τ the limits leave out."""
    B, tau, e, lo, hi = check_allocation(B, tau, effectiveness, lower, upper)
    if not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
        raise RobofdiError("allocation: constrained allocation needs finite saturation limits")
    Be = B * e
    u = _weighted_pinv(B, e) @ tau
    if np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12):
        return _result(B, e, np.clip(u, lo, hi), tau)
    from qpsolvers import solve_qp
    from scipy.sparse import csc_matrix

    p = B.shape[1]
    P = csc_matrix(Be.T @ Be + regularisation * np.eye(p))
    q = -Be.T @ tau
    sol = solve_qp(P, q, lb=lo, ub=hi, solver="clarabel")
    if sol is None or not np.all(np.isfinite(sol)):
        raise RobofdiError("allocation: the constrained allocation QP found no solution (clarabel)")
    return _result(B, e, np.clip(sol, lo, hi), tau)


def null_space_allocation(B, tau, lower, upper, effectiveness=None, iterations: int = 500,
                          tol: float = 1e-9) -> AllocationResult:
    """Null-space redistribution (Antonelli's survey, Sec. 5 / [41]): u = B⁺τ + (I − B⁺B) z, the null-space term
    moving effort from saturated thrusters to free ones without changing B diag(e) u. z is found by alternating
    projections (POCS) between the affine set {u : B diag(e) u = τ} and the box [lower, upper]: each step
    u ← u − N (u − clip(u)), N = I − (B diag(e))⁺ B diag(e). Converges to a point of both when τ is attainable;
    otherwise the clipped iterate is returned and ``unattained`` reports the rest."""
    B, tau, e, lo, hi = check_allocation(B, tau, effectiveness, lower, upper)
    if not isinstance(iterations, int) or iterations < 1:
        raise RobofdiError(f"allocation: field 'iterations' must be an integer >= 1, got {iterations!r}")
    Be = B * e
    pinv = _weighted_pinv(B, e)
    N = np.eye(B.shape[1]) - pinv @ Be
    u = pinv @ tau
    scale = max(1.0, float(np.max(np.abs(hi[np.isfinite(hi)]), initial=1.0)))
    for _ in range(iterations):
        excess = u - np.clip(u, lo, hi)
        if float(np.max(np.abs(excess))) <= tol * scale:
            break
        u = u - N @ excess
    u = np.clip(u, lo, hi)
    u[e == 0] = 0.0                                   # a failed thruster carries nothing (not round-off)
    return _result(B, e, u, tau)


def direction_preserving_allocation(B, tau, lower, upper, effectiveness=None) -> AllocationResult:
    """Direction-preserving scaling (the digest's saturation-aware step 3 for [41]): the minimum-norm u when it
    fits the limits; otherwise the LP max α s.t. B diag(e) u = α τ, lower ≤ u ≤ upper, 0 ≤ α ≤ 1 (scipy linprog),
    so the attained wrench is α τ — the demand's direction, cut in size. ``unattained`` = (1 − α) τ."""
    B, tau, e, lo, hi = check_allocation(B, tau, effectiveness, lower, upper)
    if not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
        raise RobofdiError("allocation: direction-preserving allocation needs finite saturation limits")
    Be = B * e
    u = _weighted_pinv(B, e) @ tau
    if np.all(u >= lo - 1e-12) and np.all(u <= hi + 1e-12) and np.allclose(Be @ u, tau, atol=1e-9 * max(1.0, np.abs(tau).max())):
        u = np.clip(u, lo, hi)
        u[e == 0] = 0.0
        return _result(B, e, u, tau)
    p = B.shape[1]
    c = np.zeros(p + 1)
    c[-1] = -1.0
    res = linprog(c, A_eq=np.hstack([Be, -tau[:, None]]), b_eq=np.zeros(6), bounds=[*zip(lo, hi), (0.0, 1.0)],
                  method="highs")
    if res.status != 0:
        raise RobofdiError("allocation: the direction-preserving LP found no solution (scipy linprog)")
    u = np.clip(res.x[:p], lo, hi)
    u[e == 0] = 0.0                                   # a failed thruster's column is zero: any value is optimal
    return _result(B, e, u, tau)


def capability(B, lower, upper, effectiveness=None) -> np.ndarray:
    """(6, 2) largest attainable [−, +] wrench along each axis alone (the other axes held at 0) — an LP per axis
    and direction (scipy linprog); 0 where the axis is lost."""
    B, _, e, lo, hi = check_allocation(B, np.zeros(6), effectiveness, lower, upper)
    Be = B * e
    out = np.zeros((6, 2))
    for axis in range(6):
        others = [k for k in range(6) if k != axis]
        for col, sign in ((0, -1.0), (1, 1.0)):
            res = linprog(-sign * Be[axis], A_eq=Be[others], b_eq=np.zeros(5), bounds=list(zip(lo, hi)), method="highs")
            out[axis, col] = sign * (-res.fun) if res.status == 0 else 0.0
    return out


class ThrustReallocation:
    """Accommodation: τ = B u_cmd re-allocated with effectiveness 0 for every thruster the health isolates.

    method: "column_deletion", "pseudo_inverse", "constrained" (QP within ±limit), "null_space" (null-space
    redistribution within ±limit) or "direction_preserving" (the demand scaled down, keeping its direction).
    ``effectiveness`` in the health's ``estimate`` is not used: a diagnosed thruster is treated as failed (the
    chapter's TCM modification). After each update, ``last`` holds the :class:`AllocationResult` and ``failed``
    the thrusters taken out.
    """

    def __init__(self, B, thrusters: Sequence[str], limit: float, method: str = "constrained"):
        self.B = np.asarray(B, dtype=float)
        self.thrusters = list(thrusters)
        if self.B.shape != (6, len(self.thrusters)):
            raise RobofdiError(f"ThrustReallocation: field 'B' must be (6, {len(self.thrusters)}) for thrusters "
                               f"{self.thrusters}, got {self.B.shape}")
        if method not in ALLOCATORS:
            raise RobofdiError(f"ThrustReallocation: field 'method' must be one of {ALLOCATORS}, got {method!r}")
        if not (np.isfinite(limit) and limit > 0):
            raise RobofdiError(f"ThrustReallocation: field 'limit' must be a thrust > 0 N, got {limit!r}")
        self.limit, self.method = float(limit), method
        self._index = {t: i for i, t in enumerate(self.thrusters)}
        self.reset()

    def reset(self) -> None:
        self.failed: tuple[str, ...] = ()
        self.last: AllocationResult | None = None

    def effectiveness(self, health: Health) -> np.ndarray:
        e = np.ones(len(self.thrusters))
        for target in health.isolated:
            i = self._index.get(target.split(":", 1)[0])
            if i is not None:
                e[i] = 0.0
        return e

    def update(self, u_cmd: np.ndarray, health: Health) -> np.ndarray:
        tau = self.B @ u_cmd
        e = self.effectiveness(health)
        self.failed = tuple(t for t, ei in zip(self.thrusters, e) if ei == 0)
        if self.method == "constrained":
            self.last = constrained_allocation(self.B, tau, -self.limit, self.limit, e)
        elif self.method == "pseudo_inverse":
            self.last = pseudo_inverse_allocation(self.B, tau, e)
        elif self.method == "null_space":
            self.last = null_space_allocation(self.B, tau, -self.limit, self.limit, e)
        elif self.method == "direction_preserving":
            self.last = direction_preserving_allocation(self.B, tau, -self.limit, self.limit, e)
        else:
            self.last = column_deletion_allocation(self.B, tau, np.flatnonzero(e == 0))
        return self.last.u

    def remaining_capability(self, health: Health | Mapping | None = None) -> np.ndarray:
        """:func:`capability` with the thrusters this health takes out (None: the last update's)."""
        e = np.ones(len(self.thrusters))
        failed = self.failed if health is None else (self.effectiveness(health) == 0).nonzero()[0]
        for f in failed:
            e[self._index[f] if isinstance(f, str) else int(f)] = 0.0
        return capability(self.B, -self.limit, self.limit, e)
