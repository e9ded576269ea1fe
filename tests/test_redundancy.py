"""NLAR engine: the hydraulic model's tests against the chapter's printed R1–R5 (spec digest §4), the corrected
count rule, errata, bad input, and the derivative filter."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from robofdi import RobofdiError
from robofdi.models.hydraulic import hydraulic_domain, hydraulic_model
from robofdi.redundancy import ControlAffineModel, derive_nlar
from robofdi.redundancy.derivatives import DerivativeEstimator, SavitzkyGolay, estimate_derivatives


@pytest.fixture(scope="module")
def design():
    m = hydraulic_model(load_model="none")
    return derive_nlar(m, hydraulic_domain(m))


def _book(design):
    """The chapter's tests (15)–(19) written out by hand from the printed equations, in the measured symbols."""
    S = {str(s): s for s in design.model.params}
    B, J, d, C, b, v, K, rho, ps = (S[k] for k in ("B_m", "J_t", "d_m", "C_tm", "beta_e", "v_t", "K_f", "rho", "p_s"))
    y1, y1d, y1dd, y2, y2d, y2dd, u, ud = sp.symbols(
        "shaft_speed shaft_speed_d1 shaft_speed_d2 load_pressure load_pressure_d1 load_pressure_d2 servovalve servovalve_d1")
    phi = sp.sqrt(2 * (ps - y2) / rho)
    R1 = -y1d - B / J * y1 + d / J * y2
    R2_printed = -y1dd + (B**2 / J**2 - 4 * b * d**2 / (J * v)) * y1 + (-B * d / J**2 - 4 * b * d * C / (J * v)) * y2
    R2 = R2_printed + 4 * b * d * K / (J * v) * phi * u
    R4 = -y2d - 4 * b * d * y1 / v - 4 * b * C * y2 / v + 4 * b * K / v * phi * u

    def R5(factor):
        return (-y2dd + (4 * B * b * d / (J * v) + 16 * b**2 * d * C / v**2 + 8 * b**2 * d * K / v**2 * factor * u) * y1
                + (-4 * b * d**2 / (J * v) + 16 * b**2 * C**2 / v**2 + 8 * b**2 * K * C / v**2 * factor * u) * y2
                - 16 * b**2 * K * C / v**2 * phi * u - 16 * b**2 * K**2 * u**2 / (rho * v**2) + 4 * b * K / v * phi * ud)

    return {"R1": R1, "R2": R2, "R2_printed": R2_printed, "R4": R4, "R5": R5(sp.sqrt(2 / (rho * (ps - y2)))),
            "R5_printed": R5(phi), "phi": phi, "u": u, "consts": (b, d, K, J, v)}


def _same(design, a, b) -> bool:
    """a ≡ b on the model's domain p_l < p_s: substitute p_l = p_s − q with q > 0, then simplify."""
    ps = next(s for s in design.model.params if str(s) == "p_s")
    q = sp.Symbol("q", positive=True)
    return sp.simplify((a - b).subs(sp.Symbol("load_pressure"), ps - q)) == 0


def test_four_independent_tests_equivalent_to_R1_R2_R4_R5_and_R3_trivial(design):
    book = _book(design)
    assert design.orders == [2, 2] and design.rank == 2
    assert design.count == 4                                   # Σ(r_j + 1) − rank = 6 − 2 (corrected rule)
    assert design.trivial == ["R3"] and design.tests["R3"] == 0
    assert design.independent == ["R1", "R2", "R4", "R5"] and design.redundant == []
    for name in ("R1", "R2", "R4", "R5"):                       # the corrected printed tests, identically
        assert _same(design, design.tests[name], book[name]), name


def test_errata_printed_R2_misses_the_valve_term_and_printed_R5_is_wrong(design):
    book = _book(design)
    b, d, K, J, v = book["consts"]
    assert _same(design, book["R2_printed"], design.tests["R2"] - 4 * b * d * K / (J * v) * book["phi"] * book["u"])
    assert not _same(design, book["R5_printed"], design.tests["R5"])
    # the printed count rule Σ r_j + (m − n) gives 3, not 4 (digest §1 [ERRATUM])
    assert sum(design.orders) + (design.model.p - design.model.n) == 3


def test_omega_annihilates_the_observability_and_the_literal_products_are_minus_y1_R(design):
    assert sp.simplify(design.omega * design.observability) == sp.zeros(5, 1)
    y1 = sp.Symbol("shaft_speed")
    rename = {u: sp.Symbol(n) for n, u in zip(design.model.input_names, design.model.inputs)}
    for r, name in enumerate(design.tests):
        assert sp.simplify(design.products[r].subs(rename) + y1 * design.tests[name]) == 0


def test_load_compensation_adds_the_pump_pressure_terms():
    m = hydraulic_model(load_model="measured_pump_pressure")
    d = derive_nlar(m, hydraulic_domain(m))
    S = {str(s): s for s in m.params}
    pL, pLd = sp.symbols("pump_pressure pump_pressure_d1")
    base = derive_nlar(hydraulic_model(load_model="none"), hydraulic_domain(hydraulic_model(load_model="none")))
    dm, J, B = S["d_m"], S["J_t"], S["B_m"]
    assert sp.simplify(d.tests["R1"] - (base.tests["R1"] - dm / J * pL)) == 0
    assert sp.simplify(d.tests["R2"] - (base.tests["R2"] + B * dm / J**2 * pL - dm / J * pLd)) == 0
    assert sp.simplify(d.tests["R4"] - base.tests["R4"]) == 0


def test_generated_residuals_vanish_on_exact_model_trajectories(design):
    """Tests evaluated on the model's own derivatives (computed by hand from eq. (9)) are zero to round-off."""
    P = {str(k): v for k, v in design.model.params.items()}
    fn = design.residual_function()
    w, p, u, ud = 0.5, 1.2e6, 0.06, 0.3
    phi = np.sqrt(2 * (P["p_s"] - p) / P["rho"])
    wd = -P["B_m"] / P["J_t"] * w + P["d_m"] / P["J_t"] * p
    pd = -4 * P["beta_e"] * (P["d_m"] * w + P["C_tm"] * p) / P["v_t"] + 4 * P["beta_e"] * P["K_f"] / P["v_t"] * phi * u
    wdd = -P["B_m"] / P["J_t"] * wd + P["d_m"] / P["J_t"] * pd
    dphi = -pd / (P["rho"] * phi)
    pdd = (-4 * P["beta_e"] * (P["d_m"] * wd + P["C_tm"] * pd) / P["v_t"]
           + 4 * P["beta_e"] * P["K_f"] / P["v_t"] * (dphi * u + phi * ud))
    r = np.array(fn(w, wd, wdd, p, pd, pdd, u, ud))
    scale = np.array([abs(wd), abs(wdd), abs(pd), abs(pdd)]) + 1.0
    assert np.all(np.abs(r) / scale < 1e-9)
    r_bad = np.array(fn(w, wd, wdd, p, pd + 1e6, pdd, u, ud))
    assert abs(r_bad[2]) == pytest.approx(1e6)


def test_any_model_pendulum_with_nonlinear_friction():
    th, om, tau = sp.symbols("theta omega tau")
    g, l, c, mu = sp.symbols("g l c mu", positive=True)
    m = ControlAffineModel.from_equations([th, om], [tau], [om, -g / l * sp.sin(th) - c * sp.tanh(50 * om) * mu + tau],
                                          [th], {g: 9.81, l: 0.5, c: 1.0, mu: 0.3}, output_names=("angle",),
                                          input_names=("torque",))
    d = derive_nlar(m)
    assert d.orders == [2] and d.rank == 2 and d.count == 1 and d.independent == ["R2"]
    a, a1, a2, u = sp.symbols("angle angle_d1 angle_d2 torque")
    expected = -a2 - 9.81 / 0.5 * sp.sin(a) - 0.3 * sp.tanh(50 * a1) + u
    assert sp.simplify(d.tests["R2"].subs(m.params) - expected) == 0


def test_not_control_affine_is_refused():
    x, u = sp.symbols("x u")
    with pytest.raises(RobofdiError, match="not control-affine"):
        ControlAffineModel.from_equations([x], [u], [-x + u**2], [x])
    with pytest.raises(RobofdiError, match="not control-affine"):
        ControlAffineModel.from_equations([x], [u], [-x + sp.sin(x * u)], [x])


def test_mismatched_symbol_lists_are_refused():
    x1, x2, u, k = sp.symbols("x1 x2 u k")
    with pytest.raises(RobofdiError, match="2 equations"):
        ControlAffineModel.from_equations([x1, x2], [u], [x2], [x1])
    with pytest.raises(RobofdiError, match="neither states, inputs nor params"):
        ControlAffineModel.from_equations([x1, x2], [u], [x2, -k * x1 + u], [x1])
    with pytest.raises(RobofdiError, match="states only"):
        ControlAffineModel.from_equations([x1, x2], [u], [x2, -x1 + u], [x1 + u])


def test_unobservable_model_is_refused():
    x1, x2, x3, u = sp.symbols("x1 x2 x3 u")
    with pytest.raises(RobofdiError, match="unobservable"):
        derive_nlar(ControlAffineModel.from_equations([x1], [u], [-x1 + u], [sp.Integer(1)]))
    # x2 − x3 never reaches y: both enter the rows, only their sum can be reconstructed
    m = ControlAffineModel.from_equations([x1, x2, x3], [u], [x2 + x3, -x2 + u, -x3], [x1])
    with pytest.raises(RobofdiError, match="unobservable"):
        derive_nlar(m)


def test_savitzky_golay_derivatives_and_delay():
    sg = SavitzkyGolay(dt=0.001, window=41, order=3)
    assert sg.delay == pytest.approx(0.020)
    t = np.arange(200) * 0.001
    x = np.sin(3 * t)
    est = DerivativeEstimator(sg, 1)
    out = [est.update(np.array([v])) for v in x]
    assert all(o is None for o in out[:40])
    k = 150
    tc = t[k] - sg.delay                                      # the estimates refer to the window centre
    assert out[k][0, 0] == pytest.approx(np.sin(3 * tc), abs=1e-6)
    assert out[k][1, 0] == pytest.approx(3 * np.cos(3 * tc), abs=1e-4)
    assert out[k][2, 0] == pytest.approx(-9 * np.sin(3 * tc), abs=1e-2)
    offline = estimate_derivatives(x, sg)
    assert offline[k - 40] == pytest.approx(out[k])
    assert SavitzkyGolay(dt=0.001, window=21, position="end").delay == 0.0


def test_too_few_samples_and_bad_filter_settings_are_refused():
    sg = SavitzkyGolay(dt=0.001, window=41)
    with pytest.raises(RobofdiError, match="too few samples for the derivative filter: 30 samples"):
        estimate_derivatives(np.zeros(30), sg)
    with pytest.raises(RobofdiError, match="'window' must be an odd integer"):
        SavitzkyGolay(dt=0.001, window=40)
    with pytest.raises(RobofdiError, match="'max_derivative'"):
        SavitzkyGolay(dt=0.001, window=41, order=1, max_derivative=2)


def test_linear_ar_is_the_engine_on_the_linearised_model():
    """Linear AR (parity space): the engine on eqs. (8)–(10) with Q ≈ Q0 + k_q(u − u0) − k_c(p − p0) gives the pressure
    test −ṗ − 4β_e d_m θ̇/v_t − 4β_e (C_tm + k_c) p/v_t + 4β_e/v_t (Q0 + k_q (u − u0) + k_c p0) (digest §5.1)."""
    from robofdi.models.hydraulic import CATALOGUE as P
    from robofdi.models.hydraulic import flow_gains, linearised_model

    u0, p0 = 0.06, 1.2e6
    d = derive_nlar(linearised_model(P, u0, p0), {sp.Symbol("omega"): (0.1, 2.0), sp.Symbol("p_l"): (1e5, 5e6)})
    assert d.count == 4 and d.independent == ["R1", "R2", "R4", "R5"]
    Q0, kq, kc = flow_gains(P, u0, p0)
    w, p, pd, u = sp.symbols("shaft_speed load_pressure load_pressure_d1 servovalve")
    k = 4 * P.beta_e / P.v_t
    expected = -pd - k * P.d_m * w - k * (P.C_tm + kc) * p + k * (Q0 + kq * (u - u0) + kc * p0)
    diff = sp.expand(d.tests["R4"] - expected)
    assert all(abs(float(c)) < 1e-6 * k * 1e-6 for c in sp.Poly(diff, w, p, pd, u).coeffs())


def test_printed_variants_are_the_chapters_forms(design):
    """r2_variant / r5_variant = "as_printed" swap in the printed (16) and (19); the corrected ones stay the default."""
    from robofdi.models.hydraulic import with_variants

    book = _book(design)
    printed = with_variants(design, "as_printed", "as_printed")
    assert _same(design, printed.tests["R2"], book["R2_printed"])
    assert _same(design, printed.tests["R5"], book["R5_printed"])
    assert with_variants(design).tests == design.tests
    with pytest.raises(RobofdiError, match="r2_variant"):
        with_variants(design, "typo")
