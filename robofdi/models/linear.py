"""Linear state-space models (the belief for linear plants), their exact discretisation and seeded mismatch.

    continuous (dt None):  ẋ = A x + B u + E d,        y = C x + D u
    discrete (dt [s]):     x(k+1) = A x(k) + B u(k) + E d(k),   y(k) = C x(k) + D u

``d`` is an unknown input (disturbance) of the plant: diagnosers that decouple it (unknown-input observers) read E;
the others ignore it. Every entry of x, u, y has a name and a unit.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg

from robofdi.errors import RobofdiError
from robofdi.seeding import rng

__all__ = ["LinearModel", "LinearMismatch", "discretize", "require_discrete", "vector_field", "perturbed", "unobservable_modes",
           "uncontrollable_modes", "format_mode", "covariance_factor"]

#: Relative tolerance on dt when a discrete model meets a requested sampling period.
DT_RTOL = 1e-9


def _matrix(value, shape: tuple[int | None, int | None], name: str) -> np.ndarray:
    """A finite float matrix of ``shape`` (None = any size), read-only; errors name the field."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise RobofdiError(f"LinearModel: field {name!r} must be a numeric matrix, got {value!r}") from None
    if a.ndim != 2 or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        want = "x".join("any" if s is None else str(s) for s in shape)
        raise RobofdiError(f"LinearModel: field {name!r} must be a {want} matrix, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        i, j = np.argwhere(~np.isfinite(a))[0]
        raise RobofdiError(f"LinearModel: field {name!r} must be finite, got {a[i, j]} at [{i}, {j}]")
    a.setflags(write=False)
    return a


def _names(value, size: int, prefix: str, name: str) -> tuple[str, ...]:
    if value is None:
        return tuple(f"{prefix}{i + 1}" for i in range(size))
    if isinstance(value, str):
        raise RobofdiError(f"LinearModel: field {name!r} must be a sequence of {size} names, got the string {value!r}")
    names = tuple(value)
    if len(names) != size:
        raise RobofdiError(f"LinearModel: field {name!r} must hold {size} names (one per entry), got {len(names)}")
    bad = [v for v in names if not isinstance(v, str) or not v or "+" in v]
    if bad:
        raise RobofdiError(f"LinearModel: field {name!r} must hold non-empty names without '+', got {bad[0]!r}")
    dup = sorted({v for v in names if names.count(v) > 1})
    if dup:
        raise RobofdiError(f"LinearModel: field {name!r} must hold unique names, got {dup[0]!r} more than once")
    return names


@dataclass(frozen=True, eq=False)
class LinearModel:
    """A continuous (``dt`` None) or discrete (``dt`` = sampling period [s]) linear state-space model.

    A (n×n), B (n×m), C (p×n); D (p×m, default 0); E (n×q, unknown inputs, default none: n×0).
    ``state_names`` / ``input_names`` / ``output_names`` default to x1…, u1…, y1…; inputs and outputs are fault
    targets, so their names must differ from each other. ``units`` maps "state", "u", "y" to one unit per entry
    (default "1", dimensionless). Arrays are stored read-only; models compare by identity.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray | None = None
    E: np.ndarray | None = None
    dt: float | None = None
    state_names: Sequence[str] | None = None
    input_names: Sequence[str] | None = None
    output_names: Sequence[str] | None = None
    units: Mapping[str, Sequence[str]] = field(default_factory=dict)

    def __post_init__(self):
        A = _matrix(self.A, (None, None), "A")
        n = A.shape[0]
        if A.shape != (n, n):
            raise RobofdiError(f"LinearModel: field 'A' must be square (n x n), got shape {A.shape}")
        if n == 0:
            raise RobofdiError("LinearModel: field 'A' must have at least one state, got a 0 x 0 matrix")
        B = _matrix(self.B, (n, None), "B")
        C = _matrix(self.C, (None, n), "C")
        m, p = B.shape[1], C.shape[0]
        if m == 0 or p == 0:
            raise RobofdiError(f"LinearModel: fields 'B' and 'C' need at least one input and one output, got m={m}, p={p}")
        D = _matrix(np.zeros((p, m)) if self.D is None else self.D, (p, m), "D")
        E = _matrix(np.zeros((n, 0)) if self.E is None else self.E, (n, None), "E")
        dt = self.dt
        if dt is not None:
            if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating, np.integer)) or not (
                    np.isfinite(dt) and dt > 0):
                raise RobofdiError(f"LinearModel: field 'dt' must be None (continuous) or a sampling period > 0 s, got {dt!r}")
            dt = float(dt)
        states = _names(self.state_names, n, "x", "state_names")
        inputs = _names(self.input_names, m, "u", "input_names")
        outputs = _names(self.output_names, p, "y", "output_names")
        shared = sorted(set(inputs) & set(outputs))
        if shared:
            raise RobofdiError(
                f"LinearModel: fields 'input_names' and 'output_names' must differ (both are fault targets), "
                f"got {shared[0]!r} in both"
            )
        if not isinstance(self.units, Mapping):
            raise RobofdiError(f"LinearModel: field 'units' must map 'state', 'u', 'y' to unit lists, got {self.units!r}")
        unknown = sorted(set(self.units) - {"state", "u", "y"})
        if unknown:
            raise RobofdiError(f"LinearModel: field 'units' has unknown key {unknown[0]!r}; expected 'state', 'u', 'y'")
        units = {}
        for key, size in (("state", n), ("u", m), ("y", p)):
            given = self.units.get(key)
            if given is None:
                units[key] = ("1",) * size
                continue
            if isinstance(given, str) or len(given) != size or not all(isinstance(s, str) for s in given):
                raise RobofdiError(f"LinearModel: field 'units[{key!r}]' must hold {size} unit strings, got {given!r}")
            units[key] = tuple(given)
        for name, value in (("A", A), ("B", B), ("C", C), ("D", D), ("E", E), ("dt", dt), ("state_names", states),
                            ("input_names", inputs), ("output_names", outputs), ("units", units)):
            object.__setattr__(self, name, value)

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def m(self) -> int:
        return self.B.shape[1]

    @property
    def p(self) -> int:
        return self.C.shape[0]

    @property
    def q(self) -> int:
        return self.E.shape[1]

    @property
    def discrete(self) -> bool:
        return self.dt is not None


@dataclass(frozen=True)
class LinearMismatch:
    """Deliberate relative errors of the nominal parameters (see :func:`perturbed`), drawn with ``seed``."""

    relative: float = 0.0
    seed: int = 0

    def __post_init__(self):
        v = self.relative
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not (np.isfinite(v) and 0 <= v < 0.5):
            raise RobofdiError(f"LinearMismatch: field 'relative' must be a relative error in [0, 0.5), got {v!r}")
        s = self.seed
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
            raise RobofdiError(f"LinearMismatch: field 'seed' must be an integer >= 0, got {s!r}")


def _check_dt(dt, name: str = "dt") -> float:
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating, np.integer)) or not (np.isfinite(dt) and dt > 0):
        raise RobofdiError(f"discretize: field {name!r} must be a sampling period > 0 s, got {dt!r}")
    return float(dt)


def vector_field(value, size: int, name: str, where: str, default: float, *, allow_inf: bool = False,
                 positive: bool = False) -> np.ndarray:
    """A configuration vector of ``size`` floats: None → ``default`` everywhere, a scalar → broadcast; errors name
    ``where``, the field and the first bad entry."""
    if value is None:
        return np.full(size, float(default))
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise RobofdiError(f"{where}: field {name!r} must be {size} numbers, got {value!r}") from None
    if a.ndim == 0:
        a = np.full(size, float(a))
    if a.shape != (size,):
        raise RobofdiError(f"{where}: field {name!r} must be a vector of {size} values, got shape {a.shape}")
    bad = (np.isnan(a) if allow_inf else ~np.isfinite(a)) | ((a <= 0) if positive else False)
    if bad.any():
        expected = "values > 0" if positive else ("non-NaN" if allow_inf else "finite")
        raise RobofdiError(f"{where}: field {name!r} must be {expected}, "
                           f"got {a[bad][0]} at index {int(np.flatnonzero(bad)[0])}")
    return a


def require_discrete(model, where: str, period: str = "control") -> LinearModel:
    """``model`` if it is a discrete LinearModel; else an error naming ``where`` and what to do."""
    if not isinstance(model, LinearModel):
        raise RobofdiError(f"{where}: field 'model' must be a LinearModel, got {type(model).__name__}")
    if not model.discrete:
        raise RobofdiError(f"{where}: field 'model' must be discrete; discretize(model, dt) at the {period} period first")
    return model


def discretize(model: LinearModel, dt: float) -> LinearModel:
    """Exact zero-order-hold discretisation: exp([[A, B, E], [0, 0, 0]] dt) = [[A_d, B_d, E_d], [0, I, 0]] —
    Van Loan, "Computing integrals involving the matrix exponential", IEEE TAC 23(3), 1978, Theorem 1; C, D kept.

    u and d are held constant over each period. A discrete model is returned unchanged when its dt equals ``dt``
    (relative tolerance 1e-9); a discrete model with another dt is an error (resampling is not a ZOH question).
    """
    if not isinstance(model, LinearModel):
        raise RobofdiError(f"discretize: field 'model' must be a LinearModel, got {type(model).__name__}")
    dt = _check_dt(dt)
    if model.dt is not None:
        if abs(model.dt - dt) > DT_RTOL * dt:
            raise RobofdiError(f"discretize: field 'dt' must equal the discrete model's dt={model.dt} s, got {dt}")
        return model
    n, m, q = model.n, model.m, model.q
    M = np.zeros((n + m + q, n + m + q))
    M[:n, :n], M[:n, n:n + m], M[:n, n + m:] = model.A, model.B, model.E
    Phi = scipy.linalg.expm(M * dt)
    return replace(model, A=Phi[:n, :n], B=Phi[:n, n:n + m], E=Phi[:n, n + m:], dt=dt)


def perturbed(model: LinearModel, relative_error: float | LinearMismatch, seed: int = 0) -> LinearModel:
    """The nominal belief with deliberate seeded parameter errors, so that diagnosers face real mismatch.

    Every non-zero entry of the physical parameters is scaled by (1 + ε), ε ~ N(0, relative_error²) truncated at
    ±2σ (so with σ < 0.5 no entry changes sign), independently per entry; structural zeros stay zero.
    Continuous models: entries of A and B. Discrete models: entries of A − I (≈ dt · A_continuous, so a 1 on the
    diagonal is not mistaken for a physical parameter) and of B. C, D (sensor placement) and E are kept.
    ``relative_error`` may be a :class:`LinearMismatch` (then ``seed`` is taken from it).
    The draws come from ``robofdi.seeding.rng(seed, "nominal", "A" | "B")``.
    """
    if not isinstance(model, LinearModel):
        raise RobofdiError(f"perturbed: field 'model' must be a LinearModel, got {type(model).__name__}")
    mm = relative_error if isinstance(relative_error, LinearMismatch) else LinearMismatch(relative_error, seed)
    if mm.relative == 0:
        return model

    def scale(M: np.ndarray, name: str) -> np.ndarray:
        eps = np.clip(rng(mm.seed, "nominal", name).standard_normal(M.shape), -2.0, 2.0) * mm.relative
        return M * (1.0 + eps)

    eye = np.eye(model.n) if model.discrete else np.zeros((model.n, model.n))
    return replace(model, A=eye + scale(model.A - eye, "A"), B=scale(model.B, "B"))


def _pbh(A: np.ndarray, M: np.ndarray) -> list[complex]:
    """Eigenvalues λ of A with rank [λI − A; M] < n — the Popov–Belevitch–Hautus test (Hautus 1969; Kailath, *Linear
    Systems*, 1980, Sec. 2.4); rank by SVD, relative tolerance 1e-7."""
    n = A.shape[0]
    tol = 1e-7 * max(1.0, float(np.linalg.norm(np.vstack([A, M]), 2)))
    modes: list[complex] = []
    for lam in np.linalg.eigvals(A):
        if any(abs(lam - mu) <= 1e-9 * max(1.0, abs(mu)) for mu in modes):
            continue
        s = np.linalg.svd(np.vstack([lam * np.eye(n) - A, M.astype(complex)]), compute_uv=False)
        if s[-1] <= tol:
            modes.append(complex(lam))
    return modes


def unobservable_modes(A: np.ndarray, C: np.ndarray) -> list[complex]:
    """Eigenvalues of A that C does not see (PBH test on [λI − A; C])."""
    return _pbh(np.asarray(A, dtype=float), np.asarray(C, dtype=float))


def uncontrollable_modes(A: np.ndarray, B: np.ndarray) -> list[complex]:
    """Eigenvalues of A that B cannot move (PBH test on [λI − Aᵀ; Bᵀ])."""
    return _pbh(np.asarray(A, dtype=float).T, np.asarray(B, dtype=float).T)


def format_mode(lam: complex) -> str:
    """λ as a short string for messages: real modes as 1.0453, complex ones as 0.9+0.1j, with |λ|."""
    lam = complex(lam)
    text = f"{lam.real:.6g}" if abs(lam.imag) < 1e-12 else f"{lam.real:.6g}{lam.imag:+.6g}j"
    return f"{text} (|λ|={abs(lam):.6g})"


def covariance_factor(value, size: int, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(covariance, F with F Fᵀ = covariance) of a ``size``×``size`` PSD matrix or a vector of ``size`` variances.

    A diagonal covariance gets a diagonal F (so entry j of the noise draws only on its own stream); otherwise F
    is the Cholesky factor, or V √Λ of the eigendecomposition when the matrix is singular.
    """
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise RobofdiError(f"field {name!r} must be a covariance matrix or a vector of variances, got {value!r}") from None
    if a.ndim == 1 and a.shape == (size,):
        a = np.diag(a)
    if a.shape != (size, size):
        raise RobofdiError(f"field {name!r} must be a {size}x{size} covariance or {size} variances, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise RobofdiError(f"field {name!r} must be finite, got {a[~np.isfinite(a)][0]}")
    scale = max(1.0, float(np.abs(a).max()))
    if not np.allclose(a, a.T, rtol=0.0, atol=1e-12 * scale):
        raise RobofdiError(f"field {name!r} must be symmetric")
    a = 0.5 * (a + a.T)
    smallest = float(np.linalg.eigvalsh(a).min()) if size else 0.0
    if smallest < -1e-12 * scale:
        raise RobofdiError(f"field {name!r} must be positive semi-definite, got smallest eigenvalue {smallest:.3g}")
    if np.count_nonzero(a - np.diag(np.diag(a))) == 0:
        return a, np.diag(np.sqrt(np.maximum(np.diag(a), 0.0)))
    try:
        return a, np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        lam, V = np.linalg.eigh(a)
        return a, V * np.sqrt(np.maximum(lam, 0.0))
