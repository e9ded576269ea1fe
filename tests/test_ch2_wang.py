"""Wang, book ch. 2: the TMP chip-refiner checks of spec_wang_nongaussian.md B.7 and the synthetic checks of C."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.signal
import scipy.stats

from robofdi import RobofdiError
from robofdi.decision import WindowedTTest
from robofdi.experiments.ch2_wang import ftc_check, noise_free_checks, stochastic_checks
from robofdi.ftc import GainCompensation
from robofdi.models.linear_examples import CHIP_REFINER, chip_refiner
from robofdi.models.linear import LinearModel
from robofdi.observers.gain import GainFaultObserver
from robofdi.ftc import reduced_actuator_set
from robofdi.ftc.pdf_shaping import pdf_shaping_input
from robofdi.observers.pdf import (
    EntropyDiagnosis, ScanningRLS, criterion_weight, laplace_transform, rbf_basis, s_domain_criterion,
)
from robofdi.protocols import Health


def test_static_and_noise_free_checks():
    checks, rec = noise_free_checks()
    failed = [c["quantity"] for c in checks if not c["pass"]]
    assert not failed, failed
    # the values themselves, independently of the check list: digest B.6
    f_hat = rec.signals["gain_estimate"][:, 0]
    assert f_hat[51] == pytest.approx(8.4375, abs=1e-4) and abs(f_hat[60] - 8.0) < 1e-6
    assert rec.diagnosers["gain"].residual[60:100, 0].mean() == pytest.approx(-1.9644, abs=1e-3)


@pytest.mark.parametrize("sigma", [0.05, 0.1])
def test_stochastic_detection_over_20_seeds(sigma):
    checks, stats = stochastic_checks(sigma, range(20))
    assert all(c["pass"] for c in checks), [c for c in checks if not c["pass"]]
    assert stats["seeds"] == 20


def test_literal_denominator_raises_false_alarms():
    # the literal (variance) denominator raises false alarms: the documented divergence
    _, lit = stochastic_checks(0.1, range(3))
    assert max(lit["var_literal_false_alarm_rate"]) > 0.0


def test_same_seed_gives_a_byte_identical_record(tmp_path):
    from robofdi.systems.refiner import run_refiner

    a, _ = run_refiner(seed=5, sigma=0.1)
    b, _ = run_refiner(seed=5, sigma=0.1)
    assert a.save(tmp_path / "a.h5").read_bytes() == b.save(tmp_path / "b.h5").read_bytes()


def test_gain_compensation_restores_the_healthy_loop():
    check, _, _ = ftc_check()
    assert check["pass"]
    m = chip_refiner()
    K = CHIP_REFINER["K"]
    for f in (8.0, 12.5):             # (104) with f̂ = f: eig(A − B f (f_H/f̂) K) = {0.1, 0.2}
        u_scale = GainCompensation(["chip_feed"], 10.0).update(np.ones(1), Health(0.0, ("chip_feed",), {"chip_feed": f}))
        eig = np.sort(np.linalg.eigvals(m.A - f * u_scale[0] * m.B @ K).real)
        assert np.allclose(eig, [0.1, 0.2], atol=1e-9)


def test_windowed_t_test_and_gain_observer_validate():
    m = chip_refiner()
    with pytest.raises(RobofdiError, match="full row rank"):
        GainFaultObserver(LinearModel(m.A, m.B, m.C, dt=1.0), CHIP_REFINER["L"], 10.0)
    with pytest.raises(RobofdiError, match="not stable"):
        GainFaultObserver(m, [[3.0], [3.0]], 10.0)
    obs = GainFaultObserver(m, CHIP_REFINER["L"], 10.0)
    with pytest.raises(RobofdiError, match="denominator"):
        WindowedTTest(obs.components, [8.0], obs.signatures(), denominator="variance")
    t = WindowedTTest(obs.components, [0.9], obs.signatures(), window=3)
    for v in (0.0, 0.0, 0.0):
        assert not t.update(np.array([v])).alarm.any()                        # window (N + 1 = 4) not full yet
    assert not t.update(np.array([0.0])).alarm.any() and t.statistic[0] == 0.0   # s = 0 and mean 0: statistic 0
    # window [0, 0, 0, 1]: mean 0.25, s = 0.75 / 3 = 0.25, statistic 0.25 / (√0.25 / √4) = 1.0 > 0.9
    assert t.update(np.array([1.0])).alarm.all() and t.statistic[0] == pytest.approx(1.0)
    lit = WindowedTTest(obs.components, [0.9], obs.signatures(), window=3, denominator="var_literal")
    for v in (0.0, 0.0, 0.0, 1.0):
        lit.update(np.array([v]))
    assert lit.statistic[0] == pytest.approx(0.25 / (0.25 / 2))               # divides by the variance as printed


def test_laplace_transform_of_pdfs():
    x = np.linspace(0.0, 60.0, 60001)
    lo, hi = 1.0, 3.0
    support = np.linspace(lo, hi, 2001)                                       # the uniform's support as the grid
    uni = np.full(support.size, 1.0 / (hi - lo))
    s = np.array([0.1, 0.5, 2.0])
    closed = (np.exp(-s * lo) - np.exp(-s * hi)) / (s * (hi - lo))
    assert np.allclose(laplace_transform(uni, support, s), closed, atol=1e-6)
    k, th = 3.0, 0.7
    gam = scipy.stats.gamma.pdf(x, k, scale=th)
    assert np.allclose(laplace_transform(gam, x, s), (1 + th * s) ** -k, atol=1e-6)
    mean = -laplace_transform(gam, x, 0.0, 1)[0]
    var = laplace_transform(gam, x, 0.0, 2)[0] - mean**2
    assert mean == pytest.approx(k * th, rel=1e-6) and var == pytest.approx(k * th**2, rel=1e-6)
    # transform of a convolution = product of transforms (64)
    dx = x[1] - x[0]
    g2 = scipy.stats.gamma.pdf(x, 2.0, scale=0.5)
    conv = np.maximum(scipy.signal.fftconvolve(gam, g2)[: x.size] * dx, 0.0)   # FFT round-off below 0
    assert np.allclose(laplace_transform(conv, x, s), laplace_transform(gam, x, s) * laplace_transform(g2, x, s),
                       atol=1e-4)
    # scaling (70): Γ_a(s, y) = Γ_a(y s), against Monte Carlo samples of a·y
    a = np.random.default_rng(0).gamma(k, th, 200000)
    y = 1.7
    assert np.mean(np.exp(-0.3 * a * y)) == pytest.approx((1 + th * 0.3 * y) ** -k, abs=5e-3)
    with pytest.raises(RobofdiError, match="x >= 0"):
        laplace_transform(uni, support - 2.0, s)


def test_scanning_rls_recovers_theta_and_detects_a_change():
    basis = rbf_basis(np.linspace(0.0, 4.0, 4), 1.0)
    s = np.linspace(0.1, 3.0, 12)
    rls = ScanningRLS(basis, s, blocks=3, p0=1e8)   # P(0) = p0 I: regularisation ∝ 1/p0
    gen = np.random.default_rng(1)
    theta = gen.normal(size=rls.dim)
    for _ in range(60):
        m = gen.uniform(0.2, 1.5, 3)
        rls.update(rls.regressor(m) @ theta, m)
    assert np.max(np.abs(rls.theta - theta)) < 1e-6
    m = gen.uniform(0.2, 1.5, 3)
    assert np.max(np.abs(rls.update(rls.regressor(m) @ theta, m))) < 1e-6   # healthy: |ε| below any λ > 0
    changed = theta.copy()
    changed[:4] += 0.5                                                        # the u_k block's PDF shifts
    m = gen.uniform(0.2, 1.5, 3)
    assert np.max(np.abs(rls.update(rls.regressor(m) @ changed, m))) > 0.05   # flagged at once
    with pytest.raises(RobofdiError, match="variant"):
        ScanningRLS(basis, s, 3, variant="other")


def test_entropy_diagnosis_converges_with_the_abs_mean_term():
    gen = np.random.default_rng(3)
    F_true = 2.0

    def residual(F, window):
        u, y = np.array(window).T
        return F * u - y

    diag = EntropyDiagnosis(residual, F0=1.0, rate=0.05, window=200, mean_term="abs")
    for _ in range(400):
        u = gen.uniform(0.5, 1.5)
        diag.update((u, F_true * u + gen.uniform(-0.5, 0.5)))
    assert diag.F == pytest.approx(F_true, abs=0.1)
    signed = EntropyDiagnosis(residual, F0=2.0, rate=0.05, window=200, mean_term="signed")
    for _ in range(200):
        u = gen.uniform(0.5, 1.5)
        signed.update((u, F_true * u + gen.uniform(-0.5, 0.5)))
    assert signed.F < F_true - 0.1        # the literal signed mean drags F̂ down (digest W8)


def test_s_domain_criterion_weight_shaping_and_reconfiguration_validate():
    # (76) at hand-computed points; (74) is 0 when model and measurement agree; bad input → one-line errors
    s = np.array([0.0, 0.5, 1.0, 2.0])
    K = criterion_weight(s, 2.0, 3.0, 0.5)
    expected = 3.0 * s[1:] ** 2 * np.exp(-0.5 * s[1:]) / (8 * 4.0 * (np.log(2.0) ** 2 + np.log(s[1:]) ** 2))
    assert K[0] == 0.0 and np.allclose(K[1:], expected, rtol=1e-12)
    grid = np.linspace(0.1, 3.0, 50)
    G = (1 + 0.3 * grid) ** -2
    assert s_domain_criterion(G, G, grid, np.ones_like(grid)) == 0.0
    assert s_domain_criterion(G**2, G, grid, np.ones_like(grid)) == pytest.approx(
        scipy.integrate.simpson(np.log(G) ** 2, x=grid))
    with pytest.raises(RobofdiError, match="'M0'"):
        criterion_weight(s, 1.0)
    with pytest.raises(RobofdiError, match="> 0"):
        s_domain_criterion(-G, G, grid, np.ones_like(grid))
    with pytest.raises(RobofdiError, match="'R'"):
        pdf_shaping_input(lambda s, th, u: G, [1.0], G, grid, np.ones_like(grid), 0.0, (0.1, 1.0))
    with pytest.raises(RobofdiError, match="'bounds'"):
        pdf_shaping_input(lambda s, th, u: G, [1.0], G, grid, np.ones_like(grid), 1.0, (1.0, 0.1))
    B = np.array([[0.0, 0.5], [1.0, 0.2]])
    red = reduced_actuator_set(B, np.zeros((1, 2)), [0.6, 1e-5], 1e-3)
    assert red.kept == (0,) and np.allclose(red.Bf, 0.6 * B[:, [0]]) and np.allclose(red.expand([2.0], 2), [2.0, 0])
    with pytest.raises(RobofdiError, match="no actuator left"):
        reduced_actuator_set(B, np.zeros((1, 2)), [0.0, 0.0], 1e-3)
    with pytest.raises(RobofdiError, match="'f_hat'"):
        reduced_actuator_set(B, np.zeros((1, 2)), [1.0], 1e-3)
