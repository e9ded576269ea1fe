"""Fault detection and diagnosis from output PDFs of random-parameter systems — Wang, book ch. 2, Secs. 6–8.

    laplace_transform      Γ(s) = ∫₀^∞ γ(x) e^{−sx} dx of a PDF on a grid, and its derivatives — eqs. (61)–(63)
    criterion_weight       the largest admissible weight K(s) of the s-domain criterion — eq. (76)
    s_domain_criterion     π(θ̂) = ∫ K(s) (log Γ_y(s, θ̂)/Γ_y(s))² ds on a grid of s — eq. (74)
    SDomainDiagnosis       θ̂(k) = θ̂(k−1) − λ ∂π/∂θ̂ — eq. (77)
    rbf_basis              Gaussian radial basis B_p(s) for the log-transform expansion (81)–(82) [RECONSTRUCTED]
    ScanningRLS            RLS over the scan points s_q within one sample, detection |ε_q| > λ — eqs. (84)–(92)
    EntropyDiagnosis       F̂(k) = F̂(k−1) − λ ∂J/∂F, J = entropy + mean of the residual PDF — eqs. (95)–(100)

The chapter has no numerical example for these methods: the tests use the digest's synthetic checks (spec_wang_
nongaussian.md C). The digest's readings of the garbled equations are used: the measured Γ_y in (79), the standard
RLS (P(q−1) in (88); ``variant="as_printed"`` keeps the literal formula), and a selectable mean term in (99).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence

import numpy as np
import scipy.integrate
import scipy.stats

from robofdi.errors import RobofdiError

__all__ = ["laplace_transform", "criterion_weight", "s_domain_criterion", "SDomainDiagnosis", "rbf_basis",
           "ScanningRLS", "EntropyDiagnosis", "MEAN_TERMS"]

MEAN_TERMS = ("signed", "abs", "squared")


def laplace_transform(pdf: np.ndarray, x: np.ndarray, s, derivative: int = 0) -> np.ndarray:
    """dˡΓ/dsˡ(s) = ∫ (−x)ˡ γ(x) e^{−sx} dx of a PDF sampled on the grid ``x`` (x ≥ 0), by Simpson's rule
    (scipy.integrate.simpson) — eq. (61); with l = 1, 2 at s = 0: mean = −Γ'(0), var = Γ''(0) − Γ'(0)² (62)–(63)."""
    x = np.asarray(x, dtype=float)
    pdf = np.asarray(pdf, dtype=float)
    if x.ndim != 1 or pdf.shape != x.shape or x.size < 3 or np.any(np.diff(x) <= 0):
        raise RobofdiError("laplace_transform: 'x' must be an increasing grid of >= 3 points and 'pdf' its values")
    if x[0] < 0 or np.any(pdf < 0):
        raise RobofdiError("laplace_transform: the PDF must live on x >= 0 with non-negative values (Sec. 6)")
    s = np.atleast_1d(np.asarray(s, dtype=float))
    kernel = (-x[None, :]) ** derivative * np.exp(-s[:, None] * x[None, :])
    return scipy.integrate.simpson(pdf[None, :] * kernel, x=x, axis=1)


def criterion_weight(s, M0: float, M1: float = 1.0, M2: float = 1.0) -> np.ndarray:
    """K(s) = M₁ s² e^{−M₂ s} / (8 M₀² [(log M₀)² + (log s)²]), the upper bound of (76) that keeps π finite (75).
    M0: a uniform upper bound of the output PDFs (≠ 1, else K(1) is unbounded); M1, M2 > 0: user constants."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    for name, v in (("M0", M0), ("M1", M1), ("M2", M2)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not (np.isfinite(v) and v > 0):
            raise RobofdiError(f"criterion_weight: field {name!r} must be a finite number > 0, got {v!r}")
    if M0 == 1.0:
        raise RobofdiError("criterion_weight: field 'M0' must not be 1 (the bound (76) is infinite at s = 1)")
    if np.any(s < 0):
        raise RobofdiError("criterion_weight: 's' must be >= 0")
    with np.errstate(divide="ignore"):
        log_s = np.where(s > 0, np.log(np.where(s > 0, s, 1.0)), np.inf)
    return np.where(s > 0, M1 * s**2 * np.exp(-M2 * s) / (8 * M0**2 * (np.log(M0) ** 2 + log_s**2)), 0.0)


def s_domain_criterion(model: np.ndarray, measured: np.ndarray, s: np.ndarray, weight: np.ndarray) -> float:
    """π = ∫ K(s) (log Γ_model(s)/Γ_measured(s))² ds by Simpson's rule on the grid ``s`` — eq. (74); the PDF-shaping
    cost (113) is the same integral with the target PDF's transform in place of the measured one."""
    s = np.asarray(s, dtype=float)
    model, measured, weight = (np.asarray(v, dtype=float) for v in (model, measured, weight))
    if s.ndim != 1 or s.size < 3 or np.any(np.diff(s) <= 0):
        raise RobofdiError("s_domain_criterion: 's' must be an increasing grid of >= 3 points")
    if not (model.shape == measured.shape == weight.shape == s.shape):
        raise RobofdiError("s_domain_criterion: 'model', 'measured' and 'weight' must have one value per s")
    if np.any(model <= 0) or np.any(measured <= 0):
        raise RobofdiError("s_domain_criterion: Laplace transforms of PDFs must be > 0 on the grid (Sec. 6)")
    return float(scipy.integrate.simpson(weight * np.log(model / measured) ** 2, x=s))


class SDomainDiagnosis:
    """θ̂(k) = θ̂(k−1) − λ ∂π/∂θ̂ at θ̂(k−1) — Wang eq. (77), π the s-domain criterion (74) weighted by ``weight``
    (e.g. :func:`criterion_weight`, (76)).

    transform(s, θ, multipliers) → Γ_y(s, θ, u_k) of the model (72) (the user's product of the parameters'
    transforms); ``update`` takes the measured Γ_y(s, u_k) on the grid ``s`` (e.g. :func:`laplace_transform` of the
    measured output PDF, assumption A1) with the sample's multipliers and takes ``steps`` gradient steps (the
    gradient by central differences of ``h`` per parameter [RECONSTRUCTED]; the chapter gives one step per sample).
    """

    def __init__(self, transform: Callable, s: Sequence[float], weight: Sequence[float], theta0, rate: float,
                 h: float = 1e-4, steps: int = 1):
        self.transform, self.s, self.weight = transform, np.asarray(s, dtype=float), np.asarray(weight, dtype=float)
        if self.s.ndim != 1 or self.weight.shape != self.s.shape:
            raise RobofdiError("SDomainDiagnosis: 'weight' must hold one value per point of 's'")
        if not (np.isfinite(rate) and rate > 0) or not (np.isfinite(h) and h > 0):
            raise RobofdiError("SDomainDiagnosis: fields 'rate' (λ) and 'h' must be > 0")
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise RobofdiError(f"SDomainDiagnosis: field 'steps' must be an integer >= 1, got {steps!r}")
        self.theta = np.atleast_1d(np.array(theta0, dtype=float))
        self.rate, self.h, self.steps = float(rate), float(h), steps

    def criterion(self, theta, measured, multipliers) -> float:
        """π(θ) of (74) against the measured transform."""
        return s_domain_criterion(self.transform(self.s, np.asarray(theta, dtype=float), multipliers), measured,
                                  self.s, self.weight)

    def gradient(self, measured, multipliers) -> np.ndarray:
        """∂π/∂θ at θ̂ by central differences."""
        g = np.empty_like(self.theta)
        for i in range(self.theta.size):
            d = np.zeros_like(self.theta)
            d[i] = self.h
            g[i] = (self.criterion(self.theta + d, measured, multipliers)
                    - self.criterion(self.theta - d, measured, multipliers)) / (2 * self.h)
        return g

    def update(self, measured, multipliers) -> np.ndarray:
        for _ in range(self.steps):
            self.theta = self.theta - self.rate * self.gradient(measured, multipliers)   # (77)
        return self.theta


def rbf_basis(centres: Sequence[float], width: float) -> Callable[[np.ndarray], np.ndarray]:
    """B(s) → (…, N): Gaussian radial basis functions exp(−(s − c_p)²/(2 width²)) [RECONSTRUCTED: the chapter names
    no basis]."""
    c = np.asarray(centres, dtype=float)
    if c.ndim != 1 or c.size == 0 or not (np.isfinite(width) and width > 0):
        raise RobofdiError("rbf_basis: 'centres' must be a non-empty vector and 'width' > 0")

    def basis(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        return np.exp(-((s[..., None] - c) ** 2) / (2.0 * width**2))

    return basis


class ScanningRLS:
    """s-domain scanning parameter estimation and detection — Wang eqs. (84)–(92).

    r(s_q, k) = Θ Φ(k, s_q), Φ(k, s_q) = (B(m₁ s_q), …, B(m_J s_q)) for the multipliers m = (u_k, …, u_{k−m},
    y_{k−1}, …, y_{k−n}) of the sample (the (87) form). At each sample the RLS runs over q = 1…M (88)–(91), P
    carried over from sample to sample (optionally with ``forgetting`` < 1), and the sample's prediction errors
    ε_q = r(s_q, k) − Θ^{q−1}Φ (89) are returned; |ε_q| > λ flags a fault (92).
    variant: "standard" (P(q−1) in the gain) or "as_printed" (the updated P(q) in numerator and denominator).
    """

    def __init__(self, basis: Callable[[np.ndarray], np.ndarray], scan_points: Sequence[float], blocks: int,
                 p0: float = 1e3, forgetting: float = 1.0, variant: str = "standard", theta0=None):
        s = np.asarray(scan_points, dtype=float)
        if s.ndim != 1 or s.size == 0 or np.any(s < 0):
            raise RobofdiError("ScanningRLS: 'scan_points' must be a vector of s_q >= 0")
        if variant not in ("standard", "as_printed"):
            raise RobofdiError(f"ScanningRLS: field 'variant' must be 'standard' or 'as_printed', got {variant!r}")
        if not (0 < forgetting <= 1):
            raise RobofdiError(f"ScanningRLS: field 'forgetting' must be in (0, 1], got {forgetting!r}")
        self.basis, self.s, self.blocks = basis, s, int(blocks)
        self.N = basis(np.zeros(1)).shape[-1]
        self.dim = self.N * self.blocks
        self.theta = np.zeros(self.dim) if theta0 is None else np.array(theta0, dtype=float)
        if self.theta.shape != (self.dim,):
            raise RobofdiError(f"ScanningRLS: field 'theta0' must hold {self.dim} values")
        self.P = p0 * np.eye(self.dim)
        self.forgetting, self.variant = float(forgetting), variant

    def regressor(self, multipliers: np.ndarray) -> np.ndarray:
        """Φ(k, s_q) for every q: (M, dim) — eq. (87)."""
        m = np.asarray(multipliers, dtype=float)
        if m.shape != (self.blocks,):
            raise RobofdiError(f"ScanningRLS: expected {self.blocks} multipliers (u_k … u_(k−m), y_(k−1) … y_(k−n))")
        return self.basis(m[None, :] * self.s[:, None]).reshape(self.s.size, self.dim)

    def update(self, r: np.ndarray, multipliers: np.ndarray) -> np.ndarray:
        """r(s_q, k) for q = 1…M (79, measured) and the sample's multipliers → ε_q (89)."""
        r = np.asarray(r, dtype=float)
        if r.shape != self.s.shape or not np.all(np.isfinite(r)):
            raise RobofdiError(f"ScanningRLS: 'r' must be {self.s.size} finite values, one per scan point")
        Phi = self.regressor(multipliers)
        eps = np.empty_like(r)
        self.P = self.P / self.forgetting
        for q, phi in enumerate(Phi):
            eps[q] = r[q] - self.theta @ phi                                     # (89)
            Pphi = self.P @ phi
            P_new = self.P - np.outer(Pphi, Pphi) / (1.0 + phi @ Pphi)          # (90), matrix inversion lemma
            if self.variant == "standard":
                self.theta = self.theta + Pphi * eps[q] / (1.0 + phi @ Pphi)    # (88) with P(q−1)
            else:
                Pn = P_new @ phi
                self.theta = self.theta + Pn * eps[q] / (1.0 + phi @ Pn)        # (88) as printed
            self.P = P_new
        return eps


class EntropyDiagnosis:
    """F̂(k) = F̂(k−1) − λ ∂J/∂F̂ — Wang eq. (100), with J(F̂) = H(ε) + mean term of ε over a window (99).

    residual(F̂, window) → the residual samples ε = ŷ − y of the window for a candidate F̂ (the user's model h,
    eq. (95)); H is scipy.stats.differential_entropy of those samples (the integral (99) by a spacing estimator).
    mean_term: "signed" (as printed: rewards a negative mean, spec W8), "abs" or "squared". The gradient is a
    central difference of step ``h``.
    """

    def __init__(self, residual: Callable[[float, list], np.ndarray], F0: float, rate: float, window: int = 100,
                 mean_term: str = "abs", h: float = 1e-3):
        if mean_term not in MEAN_TERMS:
            raise RobofdiError(f"EntropyDiagnosis: field 'mean_term' must be one of {MEAN_TERMS}, got {mean_term!r}")
        if not (np.isfinite(rate) and rate > 0) or not (np.isfinite(h) and h > 0):
            raise RobofdiError("EntropyDiagnosis: fields 'rate' (λ) and 'h' must be > 0")
        if isinstance(window, bool) or not isinstance(window, int) or window < 5:
            raise RobofdiError(f"EntropyDiagnosis: field 'window' must be an integer >= 5, got {window!r}")
        self.residual, self.F, self.rate, self.mean_term, self.h = residual, float(F0), float(rate), mean_term, float(h)
        self._window: deque = deque(maxlen=window)

    def criterion(self, F: float) -> float:
        """J(F) over the current window — eq. (99)."""
        eps = np.asarray(self.residual(F, list(self._window)), dtype=float)
        mean = float(eps.mean())
        term = {"signed": mean, "abs": abs(mean), "squared": mean**2}[self.mean_term]
        return float(scipy.stats.differential_entropy(eps)) + term

    def update(self, sample) -> float:
        """Add one sample (anything ``residual`` understands, e.g. (u_k, y_k)) and take one gradient step."""
        self._window.append(sample)
        if len(self._window) < 5:
            return self.F
        grad = (self.criterion(self.F + self.h) - self.criterion(self.F - self.h)) / (2 * self.h)
        self.F -= self.rate * grad                                               # (100)
        return self.F
