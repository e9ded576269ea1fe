"""The stepped cascade of sliding-mode observers — Edwards, Alwi & Tan §4, eqs. (26)–(38) (Tan & Edwards 2010),
on the design of :func:`robofdi.observers.smo_reconstruction.cascade_design`.

Stage i (not the last) runs the observer (26)–(28) on its augmented system (x^i with the disturbance-filter states
ξ^i) in the coordinates of Proposition 1 (C̄ = [0 C̄2], C̄2 orthogonal): ż = Ā z + B̄ u − Ḡ_l e_y + Ḡ_n ν,
ν = −ρ e_y/(‖e_y‖ + δ) (the sigmoid of Remark 4), e_y = C̄ z − y^i, Ḡ_n = [−L̄; I] C̄2ᵀ with L̄ = [L̄_o 0]
(erratum 2's sign, so the sliding motion is Ā_1 + L̄_o Ā_31 of (31)), Ḡ_l placing the output-error poles at
A_s = −a_s I. Once sliding, z^i := C̄2ᵀ ν_eq = Ā_3 w + M̄_2 f (32); its first m^{i+1} rows z_1^i = Ā_31 w (33,
algebraic: erratum 4) are the output y^{i+1} of the next, fictitious system (36)–(38). ν_eq is ν low-pass
filtered with time constant τ (Remark 3: the filter bandwidth, not its type, matters). The last stage
(rank C^k M^k = rank M^k) is the §3 reconstruction observer (Tan & Edwards 2003) with f̂ = W ν_eq (10).

Everything is integrated together at the sub-step h (explicit Euler); ``update(y, u)`` advances one sample T
with y and u held. Measured on §4.1: give it y at the sub-step (sample_time = substep); with y held over ten
sub-steps the first stage's injection also carries the hold error and the last stage loses sliding.

Supported: cascades whose intermediate stages have r̄^i = 0 (the fault reaches none of their outputs: no fault
scaling T_2 and no filters z_f of (35)), which is the §4.1 civil-aircraft case; others are refused.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from robofdi.checks import is_number
from robofdi.errors import RobofdiError
from robofdi.observers.smo_reconstruction import cascade_design, reconstruction_design
from robofdi.observers.sliding_mode import _mat

__all__ = ["CascadeReconstructor", "cascade_reconstruction_run"]


def _stage_gains(Ab, Cb, L_o, a_s: float):
    """Ḡ_l, Ḡ_n of (27) in the stage's coordinates (C̄ = [0 C̄2])."""
    nb, p = Ab.shape[0], Cb.shape[0]
    r = nb - p
    C2 = Cb[:, r:]
    L = np.zeros((r, p))
    L[:, : L_o.shape[1]] = L_o
    TL = np.eye(nb)
    TL[:r, r:] = L
    TLi = np.linalg.inv(TL)
    At = TL @ Ab @ TLi
    G_l = TLi @ np.vstack([At[:r, r:], At[r:, r:] + a_s * np.eye(p)]) @ C2.T
    G_n = np.vstack([-L, np.eye(p)]) @ C2.T
    return G_l, G_n, C2


class CascadeReconstructor:
    """``update(y, u)`` → f̂ (q,), the cascade's reconstruction of the actuator fault of ẋ = A x + B u + M f + Q ξ,
    y = C x (module docstring). filters: the (A_Ω, B_Ω) of each fictitious stage (23)–(25); rho: the switching gain
    of each stage (len = number of stages, the last the §3 observer's), in the units of that stage's output rate;
    sample_time / substep [s]; tau [s]: the ν_eq low-pass; a_s [1/s]: the output-error poles −a_s; poles: the last
    stage's sliding poles (eig(A11 + L_o A211); None: the Riccati gain, which keeps the invariant zeros); delta: the
    boundary layer of ν = −ρ e_y/(‖e_y‖ + δ) (Remark 4's sigmoid: unit-vector chattering, low-pass filtered, would
    be the next stage's measurement noise and is amplified down the cascade)."""

    def __init__(self, A, B, M, C, Q, filters: Sequence[tuple], rho: Sequence[float], sample_time: float = 1e-3,
                 substep: float = 1e-4, tau: float = 0.002, a_s: float = 20.0, poles=None, delta: float = 1e-3):
        where = "CascadeReconstructor"
        A = _mat(A, "A", where)
        n = A.shape[0]
        B = _mat(B, "B", where, rows=n) if np.size(B) else np.zeros((n, 0))
        self.stages = cascade_design(A, M, C, Q, filters)
        k = len(self.stages)
        inner = self.stages[:-1]
        bad = [i + 1 for i, s in enumerate(inner) if s.rbar > 0]
        if bad:
            raise RobofdiError(f"{where}: stage {bad[0]} has r̄ > 0 (the fault reaches some of its outputs): the fault "
                               "scaling T_2 and the filters z_f of (35) are not implemented in the stepped cascade")
        rho = list(rho)
        if len(rho) != k or not all(is_number(x) and x > 0 for x in rho):
            raise RobofdiError(f"{where}: field 'rho' must hold {k} gains > 0 (one per stage), got {rho!r}")
        for name, v in (("sample_time", sample_time), ("substep", substep), ("tau", tau), ("a_s", a_s),
                        ("delta", delta)):
            if not (is_number(v) and v > 0):
                raise RobofdiError(f"{where}: field {name!r} must be > 0, got {v!r}")
        if substep > sample_time or substep >= tau:
            raise RobofdiError(f"{where}: field 'substep' must be <= sample_time and < tau, got {substep!r}")
        self.n_sub = max(1, int(round(sample_time / substep)))
        self.h = sample_time / self.n_sub
        self.tau, self.rho, self.delta = float(tau), [float(x) for x in rho], float(delta)
        self._A, self._Gl, self._Gn, self._C, self._C2, self._B, self._m = [], [], [], [], [], [], []
        for i, s in enumerate(inner):
            G_l, G_n, C2 = _stage_gains(s.A, s.C, s.L_o, a_s)
            Bb = s.T @ np.vstack([B, np.zeros((s.h, B.shape[1]))]) if i == 0 else np.zeros((s.n, B.shape[1]))
            self._A.append(s.A), self._Gl.append(G_l), self._Gn.append(G_n), self._C.append(s.C)
            self._C2.append(C2), self._B.append(Bb), self._m.append(s.m_next)
        last = self.stages[-1]
        Bk = last.T @ B if k == 1 else np.zeros((last.n, B.shape[1]))
        self.design = reconstruction_design(last.A, last.C, last.M, Q=last.Q, poles=poles, A_s=-a_s * np.eye(last.p),
                                            method="riccati" if poles is None else "place")
        self._A.append(last.A), self._Gl.append(self.design.G_l), self._Gn.append(self.design.G_n)
        self._C.append(last.C), self._B.append(Bk)
        self.W = self.design.W
        self.q = self.W.shape[0]
        self.reset()

    def reset(self) -> None:
        self.z = [np.zeros(a.shape[0]) for a in self._A]
        self.nu_f = [np.zeros(c.shape[0]) for c in self._C]
        self.estimate = np.zeros(self.q)

    @property
    def injections(self) -> list[np.ndarray]:
        """z^i = C̄2ᵀ ν_eq of each fictitious stage (32), then the last stage's ν_eq."""
        return [c2.T @ nf for c2, nf in zip(self._C2, self.nu_f)] + [self.nu_f[-1]]

    def update(self, y, u) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        u = np.asarray(u, dtype=float)
        if y.shape != (self._C[0].shape[0],) or not np.all(np.isfinite(y)):
            raise RobofdiError(f"CascadeReconstructor: input 'y' must be {self._C[0].shape[0]} finite outputs, got {y!r}")
        h, a = self.h, self.h / self.tau
        k = len(self._A)
        for _ in range(self.n_sub):
            yi = y
            for i in range(k):
                ey = self._C[i] @ self.z[i] - yi
                nu = -self.rho[i] * ey / (float(np.linalg.norm(ey)) + self.delta)
                dz = self._A[i] @ self.z[i] + self._B[i] @ u - self._Gl[i] @ ey + self._Gn[i] @ nu
                self.z[i] = self.z[i] + h * dz
                self.nu_f[i] = self.nu_f[i] + a * (nu - self.nu_f[i])
                if i < k - 1:
                    yi = (self._C2[i].T @ self.nu_f[i])[: self._m[i]]          # y^{i+1} = z_1^i (33)
        self.estimate = self.W @ self.nu_f[-1]
        return self.estimate.copy()


def cascade_reconstruction_run(A, M, C, Q, filters, duration: float = 10.0, step: float = 1e-4, fault=None,
                               rho=None, since: float = 3.0) -> dict:
    """The §4.1 check (digest check 5, ΔA = 0): a smooth actuator fault f(t) (default 0.2 sin(0.4 t) [input units],
    harness) on ẋ = A x + M (u + f), u = 0, discretised exactly (zero-order hold of f at mid-step) at ``step``,
    the cascade updated at every step (sample time = sub-step: with y held over longer samples the first stage's
    injection also carries the hold error Δy, and the cascade amplifies it). Returns t, f, f_hat (decimated to
    1 ms) and the relative error max|f̂ − f| / max|f| for t ≥ ``since`` s (after the transients)."""
    import scipy.linalg

    fault = fault or (lambda t: 0.2 * np.sin(0.4 * t))
    A = np.asarray(A, dtype=float)
    M = np.asarray(M, dtype=float)
    C = np.asarray(C, dtype=float)
    n = A.shape[0]
    obs = CascadeReconstructor(A, np.zeros((n, 0)), M, C, Q, filters, rho or [50.0] * (len(filters) + 1),
                               sample_time=step, substep=step, delta=1e-2)
    E = scipy.linalg.expm(np.block([[A, M[:, :1]], [np.zeros((1, n + 1))]]) * step)
    Phi, Gam = E[:n, :n], E[:n, n]
    N = int(round(duration / step))
    x = np.zeros(n)
    t = np.arange(N + 1) * step
    f_hat = np.zeros(N + 1)
    for j in range(N + 1):
        if j:
            x = Phi @ x + Gam * fault(t[j] - step / 2)
        f_hat[j] = obs.update(C @ x, np.zeros(0))[0]
    f = np.array([fault(s) for s in t])
    late = t >= since
    rel = float(np.abs(f_hat - f)[late].max() / np.abs(f[late]).max())
    keep = slice(None, None, max(1, int(round(1e-3 / step))))
    return {"t": t[keep], "f": f[keep], "f_hat": f_hat[keep], "relative_error": rel, "since": since,
            "fault": "0.2 sin(0.4 t) (harness)", "rho": obs.rho, "tau": obs.tau, "delta": obs.delta, "step": step,
            "last_stage_sliding_poles": [str(complex(np.round(p, 4))) for p in np.sort_complex(obs.design.sliding_poles)],
            "last_stage_gamma": obs.design.gamma}
