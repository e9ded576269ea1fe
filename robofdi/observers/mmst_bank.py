"""The non-hybrid multiple-model effector bank with periodic resets — Bošković & Mehra, "Failure detection,
identification and reconfiguration in flight control", §5.3: the MMST switching logic on the index (44) with
its two refinements (a threshold favouring the nominal model, and every observer state reset to the measured
x every t_s), over the adaptive stuck-position observers (45)–(47) with projection (38).

Unlike :class:`~robofdi.observers.effector_bank.HybridEffectorFDI` (§5.4) nothing is ever frozen or committed:
every candidate keeps the pre-failure nominal for the other effectors, so — the limitation the chapter states —
a second failure is not modelled by any candidate.
"""
from __future__ import annotations

import numpy as np

from robofdi.observers.effector_bank import HybridEffectorFDI

__all__ = ["MultipleModelEffectorFDI"]


class MultipleModelEffectorFDI(HybridEffectorFDI):
    """Diagnoser: the observers of :class:`HybridEffectorFDI` with F = ∅ forever; every ``t_s`` (after
    ``holdoff``) the active model is i* = argminᵢ Iᵢ (44) when I₀ − I_{i*} > ``delta`` and the nominal
    otherwise (refinement 1: ties go to the nominal; it may switch back), then every observer state is reset to
    the measured x₂ (refinement 2; û and the integrals of (44), counted from the start, are kept).

    Residual: [I₀, I_{effector}…] then one status per effector (1 while it is the active model, else 0), as
    :class:`~robofdi.decision.multiple_model.SupervisorStatusDecision` reads it. Estimate: the adaptive û per
    effector [rad]. ``sequence`` lists (time, model) of every switch."""

    def _supervise(self, t: float, x: np.ndarray, u: np.ndarray) -> None:
        if t < self.holdoff - 1e-9:
            return
        I = self.index[1:]
        j = int(np.argmin(I))
        new = j if self.index[0] - I[j] > self.delta else None
        if new != self.active:
            self.active = new
            self.sequence.append((t, "nominal" if new is None else self.effectors[new]))
        x2 = x[self.x2]
        self._xh0 = x2.copy()
        self._z[:, :-1] = x2
