"""An over-actuated flight-control surrogate for Bošković & Mehra's chapter 5 ("Failure detection, identification
and reconfiguration in flight control"): longitudinal + lateral linear dynamics, eight control effectors and a
polynomial wing-damage parameterisation A(ρ), B(ρ) (the chapter's eqs. (50)–(56)).

**Not from the chapter.** The chapter's F/A-18C/D power-approach model and the TAFA/X-36 damage model are
only cited (its refs. [11], [13]); no matrix is printed. This surrogate is robofdi's own, chosen so that every
scenario of the chapter can be run and *isolated*:

* states x = [V, α, θ, β, φ | q, p, r] (m/s, rad, rad/s) about a power-approach trim (V₀ ≈ 70 m/s). The first
  five are the chapter's x₁ (not directly actuated: ẋ₁ = Ā x, eq. (27)), the body rates are x₂ (relative degree
  one: ẋ₂ = A x + B u, eq. (28)). Control forces are neglected (the usual dynamic-inversion simplification), so
  B₁ = 0 exactly. V is kept so that a pitch-attitude sensor bias is observable (θ enters V̇ through −g θ: the
  full-state A is nonsingular, which Theorem 1's φ_d → 0 needs).
* eight effectors: left/right leading-edge flaps, left/right stabilators, left/right ailerons (trailing-edge
  flaps), left/right canted rudders — the six surfaces of Sim 5 plus a pair of ailerons, so that after any two
  failures five healthy surfaces still span the three moment axes with margin. Left/right pairs act equally in
  pitch and oppositely in roll (and the canted twin tails oppositely in roll, equally in yaw), so all 28 column
  pairs are non-collinear: a lock-in-place of any one surface is isolable from any other.
* position and rate limits per effector (F/A-18-like values), enforced by the simulator
  (:class:`robofdi.sims.flight.FlightPlant`).
* outer-left-wing damage ρ ∈ [0, 1]: A(ρ) = A₀ + A₁ρ + A₂ρ², B(ρ) = B₀ + B₁ρ + B₂ρ² (order 2 of the chapter's
  order-5 polynomials (51)–(52)): the left LEF and aileron lose effectiveness, the asymmetric lift adds a
  rolling and yawing moment per unit α, roll damping drops. Only the moment rows (x₂) change, as §6's
  Assumption 2 requires (Ā does not depend on ρ).

Why not Guo et al.'s lateral model (robofdi.models.linear_examples.aircraft_lateral): its B has rank 5 with a
non-zero x₁ block on the (q, p, r) partition, so it has no relative-degree-one subsystem of the chapter's form
and no redundancy left after a failure; and it has no longitudinal axis for Sim 2's α/q/θ sensors.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["FlightSurrogate", "flight_surrogate", "STATE_NAMES", "EFFECTORS", "STATE_UNITS", "G"]

G = 9.81
STATE_NAMES = ("V", "alpha", "theta", "beta", "phi", "q", "p", "r")
STATE_UNITS = ("m/s", "rad", "rad", "rad", "rad", "rad/s", "rad/s", "rad/s")
EFFECTORS = ("lef_left", "lef_right", "stab_left", "stab_right", "ail_left", "ail_right", "rud_left", "rud_right")
#: n − p = 5 states of x₁, p = 3 body rates of x₂.
N_X1 = 5


@dataclass(frozen=True, eq=False)
class FlightSurrogate:
    """The nominal and damaged matrices of the surrogate (see the module docstring).

    A_coeffs / B_coeffs: (A₀, A₁, A₂) full-state n×n and (B₀, B₁, B₂) full-state n×m; u_min / u_max [rad];
    rate_limit [rad/s]. ``A(ρ)`` / ``B(ρ)`` evaluate the polynomials (51)–(52); ``partition`` gives Ā and the x₂
    rows (eqs. (53)–(56))."""

    A_coeffs: tuple
    B_coeffs: tuple
    u_min: np.ndarray
    u_max: np.ndarray
    rate_limit: np.ndarray
    state_names: tuple = STATE_NAMES
    effectors: tuple = EFFECTORS
    units: tuple = STATE_UNITS
    n1: int = N_X1

    @property
    def n(self) -> int:
        return len(self.state_names)

    @property
    def m(self) -> int:
        return len(self.effectors)

    @property
    def p(self) -> int:
        return self.n - self.n1

    def _rho(self, rho: float) -> float:
        if not (np.isfinite(rho) and 0.0 <= rho <= 1.0):
            raise RobofdiError(f"FlightSurrogate: damage 'rho' must be in [0, 1], got {rho!r}")
        return float(rho)

    def A(self, rho: float = 0.0) -> np.ndarray:
        """Full-state A(ρ) = Σ Aᵢ ρⁱ — eq. (51)."""
        rho = self._rho(rho)
        return sum(Ai * rho**i for i, Ai in enumerate(self.A_coeffs))

    def B(self, rho: float = 0.0) -> np.ndarray:
        """Full-state B(ρ) = Σ Bᵢ ρⁱ — eq. (52)."""
        rho = self._rho(rho)
        return sum(Bi * rho**i for i, Bi in enumerate(self.B_coeffs))

    @property
    def Abar(self) -> np.ndarray:
        """Ā ((n − p) × n): ẋ₁ = Ā x — eq. (53) (acting on the full x, the digest's dimension fix)."""
        return self.A_coeffs[0][: self.n1].copy()

    def A2(self, rho: float = 0.0) -> np.ndarray:
        """The x₂ rows of A(ρ) (p × n) — eq. (55)."""
        return self.A(rho)[self.n1:]

    def B2(self, rho: float = 0.0) -> np.ndarray:
        """The x₂ rows of B(ρ) (p × m) — eq. (56)."""
        return self.B(rho)[self.n1:]

    @property
    def A2_coeffs(self) -> tuple:
        return tuple(Ai[self.n1:] for Ai in self.A_coeffs)

    @property
    def B2_coeffs(self) -> tuple:
        return tuple(Bi[self.n1:] for Bi in self.B_coeffs)

    def weights(self) -> np.ndarray:
        """The default diagonal W of the minimum-effort allocation: 1/(half range)² per effector (effort relative
        to its travel), the leading-edge flaps made 10× cheaper (they are weak in moment, and a surface the
        allocation never moves has an unobservable lock, the chapter's Sim 5 needs them to work)."""
        half = 0.5 * (self.u_max - self.u_min)
        w = 1.0 / half**2
        w[:2] *= 0.1
        return w


@lru_cache(maxsize=1)
def _matrices():
    n, m = len(STATE_NAMES), len(EFFECTORS)
    ix = {s: i for i, s in enumerate(STATE_NAMES)}
    A0 = np.zeros((n, n))

    def put(A, row, **entries):
        for col, v in entries.items():
            A[ix[row], ix[col]] = v

    put(A0, "V", V=-0.04, alpha=4.0, theta=-G)
    put(A0, "alpha", V=-0.003, alpha=-0.6, q=1.0)
    put(A0, "theta", q=1.0)
    put(A0, "beta", beta=-0.15, phi=G / 70.0, p=0.1, r=-1.0)
    put(A0, "phi", p=1.0)
    put(A0, "q", alpha=-1.5, q=-0.6)
    put(A0, "p", beta=-4.0, p=-1.2, r=0.5)
    put(A0, "r", beta=1.0, p=-0.05, r=-0.25)
    # moment rows (q, p, r) per rad of each surface [rad/s² per rad]
    B2 = np.array([
        #  lefL   lefR  stabL  stabR   ailL   ailR   rudL   rudR
        [0.25, 0.25, -4.00, -4.00, -1.20, -1.20, 0.25, 0.25],     # pitch
        [0.75, -0.75, 2.50, -2.50, 4.00, -4.00, 0.80, -0.80],     # roll
        [0.40, -0.40, 0.35, -0.35, -0.45, 0.45, -1.60, -1.60],    # yaw
    ])
    B0 = np.zeros((n, m))
    B0[N_X1:] = B2
    # outer-left-wing damage: asymmetric lift (rolling / yawing moment per unit α), roll damping loss
    A1, A2 = np.zeros((n, n)), np.zeros((n, n))
    put(A1, "p", alpha=-3.0, p=0.5, beta=0.8)
    put(A1, "r", alpha=0.4)
    put(A2, "p", alpha=-1.0, p=0.2)
    B1, B2d = np.zeros((n, m)), np.zeros((n, m))
    for k, (lin, quad) in {0: (0.4, 0.2), 4: (0.5, 0.3)}.items():     # left LEF, left aileron
        B1[N_X1:, k] = -lin * B2[:, k]
        B2d[N_X1:, k] = -quad * B2[:, k]
    deg = np.pi / 180.0
    u_min = np.array([-15, -15, -24, -24, -25, -25, -30, -30]) * deg
    u_max = np.array([21, 21, 10.5, 10.5, 25, 25, 30, 30]) * deg
    rate = np.array([15, 15, 40, 40, 100, 100, 82, 82]) * deg
    return (A0, A1, A2), (B0, B1, B2d), u_min, u_max, rate


def flight_surrogate() -> FlightSurrogate:
    """The shipped surrogate (fresh copies of its arrays)."""
    Ac, Bc, lo, hi, rate = _matrices()
    return FlightSurrogate(tuple(a.copy() for a in Ac), tuple(b.copy() for b in Bc), lo.copy(), hi.copy(),
                           rate.copy())
