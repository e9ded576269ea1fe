"""Threshold calibration and signature isolation (robofdi.decision)."""
import numpy as np
import pytest

from robofdi import RobofdiError
from robofdi.decision import Alarms, Signature, ThresholdDecision, calibrate_thresholds, extreme_value_thresholds
from robofdi.decision.isolation import startup_samples

TORQUES = [f"joint{i}_tau" for i in range(1, 4)]
COMPONENTS = TORQUES + ["joint3_pos"]


def arm_signatures():
    actuators = [Signature(f"joint{i}", frozenset({f"joint{i}_tau"})) for i in range(1, 4)]
    sensor = Signature("joint3_pos", frozenset({"joint3_pos"}), frozenset(TORQUES))
    return actuators + [sensor]


def decision(latch=True):
    return ThresholdDecision(COMPONENTS, np.ones(4), arm_signatures(), latch=latch)


# --- calibrate_thresholds -------------------------------------------------------------------------

def test_calibrate_is_margin_times_max_abs_after_skip():
    run1 = np.array([[100.0, -100.0], [0.5, -2.0], [1.0, 0.0]])  # first sample is a start-up transient
    run2 = np.array([[50.0, 50.0], [-3.0, 1.0]])
    thr = calibrate_thresholds([run1, run2], margin=1.5, skip=1)
    np.testing.assert_allclose(thr, [1.5 * 3.0, 1.5 * 2.0])


def test_calibrate_without_skip_and_zero_component_gets_positive_floor():
    thr = calibrate_thresholds([np.array([[-2.0, 0.0], [1.0, 0.0]])])
    assert thr[0] == pytest.approx(2.4)
    assert 0 < thr[1] < 1e-9


@pytest.mark.parametrize(
    "runs, kwargs, field",
    [
        ([np.array([[1.0, np.nan]])], {}, "residuals[0]"),
        ([np.ones((3, 2)), np.ones((3, 3))], {}, "residuals[1]"),
        ([np.ones((3, 2))], {"margin": 0.9}, "margin"),
        ([np.ones((3, 2))], {"skip": 3}, "skip"),
        ([], {}, "residuals"),
        ([np.ones(3)], {}, "residuals[0]"),
    ],
)
def test_calibrate_rejects_bad_input(runs, kwargs, field):
    with pytest.raises(RobofdiError, match=field.replace("[", r"\[").replace("]", r"\]")):
        calibrate_thresholds(runs, **kwargs)


# --- Signature / ThresholdDecision ---------------------------------------------------------------

def test_signature_normalises_sets_and_rejects_a_bare_string():
    s = Signature("joint1", ["joint1_tau"], ("joint2_tau",))
    assert s.required == frozenset({"joint1_tau"}) and s.explains == {"joint1_tau", "joint2_tau"}
    with pytest.raises(RobofdiError, match="required"):
        Signature("joint1", "joint1_tau")
    with pytest.raises(RobofdiError, match="required"):
        Signature("joint1", frozenset())


def test_no_alarm_below_threshold():
    out = decision().update(np.array([0.5, -0.9, 1.0, 0.0]))  # |r| == threshold is not an alarm
    assert isinstance(out, Alarms)
    assert not out.alarm.any() and out.isolated == () and out.new == ()


def test_single_actuator_fault_is_isolated():
    d = decision()
    out = d.update(np.array([0.1, -4.0, 0.2, 0.3]))
    np.testing.assert_array_equal(out.alarm, [False, True, False, False])
    assert out.isolated == ("joint2",) and out.new == ("joint2",)


def test_sensor_signature_beats_actuator_signatures_when_position_alarms():
    d = decision()
    # torque residuals react more than the position residual, yet one sensor fault explains all of them
    out = d.update(np.array([3.0, 5.0, 8.0, 2.0]))
    assert out.alarm.all()
    assert out.isolated == ("joint3_pos",)


def test_two_actuator_faults_are_both_isolated_largest_first():
    out = decision().update(np.array([2.0, 0.0, 6.0, 0.0]))
    assert out.isolated == ("joint3", "joint1") and out.new == ("joint3", "joint1")


def test_latching_keeps_faults_and_new_reports_only_fresh_ones():
    d = decision(latch=True)
    assert d.update(np.array([0.0, 3.0, 0.0, 0.0])).new == ("joint2",)
    out = d.update(np.zeros(4))
    assert out.isolated == ("joint2",) and out.new == () and not out.alarm.any()
    out = d.update(np.array([2.0, 3.0, 0.0, 0.0]))
    assert out.isolated == ("joint2", "joint1") and out.new == ("joint1",)
    d.reset()
    assert d.update(np.zeros(4)).isolated == ()


def test_without_latch_isolation_follows_the_current_sample():
    d = decision(latch=False)
    assert d.update(np.array([0.0, 3.0, 0.0, 0.0])).isolated == ("joint2",)
    assert d.update(np.zeros(4)).isolated == ()
    assert d.update(np.array([0.0, 3.0, 0.0, 0.0])).new == ("joint2",)


def test_blanking_suppresses_the_first_samples_after_each_reset():
    d = ThresholdDecision(COMPONENTS, np.ones(4), arm_signatures(), blanking=2)
    big = np.array([0.0, 10.0, 0.0, 0.0])
    for _ in range(2):                                      # a fresh decision, then the same after reset()
        assert [d.update(big).alarm.any() for _ in range(3)] == [False, False, True]
        assert d.update(big).isolated == ("joint2",)
        d.reset()
    assert startup_samples(0.002) == 5 and startup_samples(0.002, 0.0) == 0   # 10 ms default at 500 Hz


def test_nan_residual_names_residual_and_component():
    d = decision()
    with pytest.raises(RobofdiError, match=r"residual.*joint2_tau"):
        d.update(np.array([0.0, np.nan, 0.0, 0.0]))
    with pytest.raises(RobofdiError, match="residual"):
        d.update(np.array([0.0, np.inf, 0.0, 0.0]))
    with pytest.raises(RobofdiError, match="residual"):
        d.update(np.zeros(3))


def test_unknown_signature_component_is_named():
    with pytest.raises(RobofdiError, match="joint9_tau"):
        ThresholdDecision(COMPONENTS, np.ones(4), [Signature("joint9", frozenset({"joint9_tau"}))])


@pytest.mark.parametrize(
    "components, threshold, field",
    [
        (["a", "a"], [1.0, 1.0], "components"),
        (["a", "b"], [1.0], "threshold"),
        (["a", "b"], [1.0, 0.0], "threshold"),
        (["a", "b"], [1.0, np.nan], "threshold"),
    ],
)
def test_decision_configuration_is_validated(components, threshold, field):
    with pytest.raises(RobofdiError, match=field):
        ThresholdDecision(components, np.array(threshold), [])


def _velocity_sensor_case(confirm):
    """A velocity-sensor fault: the dynamic row j alarms one sample before the kinematic row j_kin."""
    sigs = [Signature("j", {"j"}), Signature("j_pos", {"j_kin"}, {"j"}), Signature("j_vel", {"j_kin", "j"})]
    d = ThresholdDecision(["j", "j_kin"], np.ones(2), sigs, confirm=confirm)
    out = [d.update(r) for r in ([0.1, 0.1], [3.0, 0.2], [2.0, 4.0], [1.5, 3.0], [1.2, 2.0], [1.1, 1.5])]
    return out


def test_confirmation_decides_over_all_hypotheses_on_the_window():
    hasty, confirmed = _velocity_sensor_case(0), _velocity_sensor_case(3)
    assert hasty[1].isolated == ("j",)                       # the first crossing decides: an actuator fault
    assert [a.alarm.any() for a in confirmed] == [a.alarm.any() for a in hasty]   # alarms are not delayed
    assert all(a.isolated == () for a in confirmed[:4])
    assert confirmed[4].isolated == ("j_vel",) and confirmed[4].new == ("j_vel",)


def test_confirm_is_validated():
    with pytest.raises(RobofdiError, match="confirm"):
        ThresholdDecision(["a"], [1.0], [Signature("a", {"a"})], confirm=-1)


def test_extreme_value_threshold_keeps_its_false_alarm_rate_on_fresh_data():
    """Gaussian white residuals, 2 ms samples, 40 s of calibration: the threshold for λ = 7.2 exceedances per hour
    (beyond anything the calibration saw) is exceeded by 7 h of fresh data at most at rate λ — the Gumbel tail
    is conservative for Gaussian maxima — and not absurdly less (> λ/20); never below the calibration maximum."""
    rng = np.random.default_rng(1)
    calib = [rng.normal(0, 1, (2500, 2)) for _ in range(8)]
    h = extreme_value_thresholds(calib, 0.002, rate_per_hour=7.2, block=0.25)
    assert np.all(h > np.max([np.abs(c).max(axis=0) for c in calib], axis=0))
    fresh = np.abs(rng.normal(0, 1, (100_000 * 125, 2))).reshape(-1, 125, 2).max(axis=1)    # 100 000 blocks of 0.25 s
    rate = (fresh > h).mean(axis=0) / 0.25 * 3600
    assert np.all((rate <= 7.2) & (rate > 7.2 / 20)), rate


def test_exponential_tail_follows_the_upper_maxima_where_the_bulk_spreads_from_zero():
    """Half the calibration motions fit the bound tightly (residual ×0.05), half loosely (×1): the block maxima
    spread from ≈ 0 to ≈ 4. The level that Gaussian maxima of 125 samples exceed with probability p (λ = 7.2 per
    hour, 0.25 s blocks) is known exactly. The Gumbel fit lets the spread set its scale and lands ≈ 2× above it;
    the exponential tail of the upper 30 % stays within 30 % above it (never below)."""
    from scipy.optimize import brentq
    from scipy.stats import norm

    p = 7.2 * 0.25 / 3600
    exact = brentq(lambda x: 1 - (1 - 2 * norm.sf(x)) ** 125 - p, 2.0, 10.0)
    rng = np.random.default_rng(1)
    calib = [s * rng.normal(0, 1, (2500, 2)) for s in (0.05, 1.0) * 8]
    exponential = extreme_value_thresholds(calib, 0.002, rate_per_hour=7.2, tail="exponential")
    gumbel = extreme_value_thresholds(calib, 0.002, rate_per_hour=7.2)
    assert np.all((exponential >= exact) & (exponential <= 1.3 * exact)), exponential / exact
    assert np.all(gumbel > 1.6 * exact), gumbel / exact
    mixed = extreme_value_thresholds(calib, 0.002, rate_per_hour=7.2, tail=["exponential", "gumbel"])
    assert mixed[0] == exponential[0] and mixed[1] == gumbel[1]


@pytest.mark.parametrize("kwargs, field", [({"rate_per_hour": 0.0}, "rate_per_hour"), ({"block": 0.001}, "block"),
                                           ({"tail": "pareto"}, "tail"), ({"tail": ["gumbel"] * 2}, "tail"),
                                           ({"tail_fraction": 1.0}, "tail_fraction")])
def test_extreme_value_thresholds_reject_bad_input(kwargs, field):
    with pytest.raises(RobofdiError, match=field):
        extreme_value_thresholds([np.ones((5000, 1))], 0.002, **kwargs)
    with pytest.raises(RobofdiError, match="20 blocks"):
        extreme_value_thresholds([np.ones((100, 1))], 0.002)


def test_confirmation_ignores_a_single_crossing_and_reports_unknown():
    """An actuator step raises its dynamic row for good, and a kinematic row for one sample only (integration
    error of the step in acceleration): isolated as the actuator. A lone one-sample crossing isolates nothing."""
    sigs = [Signature("j", {"j"}), Signature("j_pos", {"j_kin"}, {"j"}), Signature("j_vel", {"j_kin", "j"})]
    d = ThresholdDecision(["j", "j_kin"], np.ones(2), sigs, confirm=3)
    out = [d.update(r) for r in ([3.0, 1.5], [3.0, 0.2], [3.0, 0.2], [3.0, 0.2])]
    assert out[3].isolated == ("j",)
    d.reset()
    out = [d.update(r) for r in ([0.2, 1.5], [0.2, 0.2], [0.2, 0.2], [0.2, 0.2], [0.2, 0.2])]
    assert all(a.isolated == () for a in out) and out[0].alarm.any()


def _encoder_or_velocity(evidence):
    """The kinematic row alarms for good; the step row stays at 0.6 of its alarm threshold (a velocity jump the
    false-alarm threshold does not reach) and decays after four samples."""
    sigs = [Signature("j_pos", {"j_kin"}), Signature("j_vel", {"j_kin", "j_step"})]
    d = ThresholdDecision(["j_kin", "j_step"], np.ones(2), sigs, confirm=3, evidence=evidence)
    return [d.update(r) for r in ([0.1, 0.1], [3.0, 0.6], [3.0, 0.6], [3.0, 0.6], [3.0, 0.1], [3.0, 0.1])]


def test_evidence_threshold_tells_hypotheses_apart_without_raising_alarms():
    plain, graded = _encoder_or_velocity(None), _encoder_or_velocity([1.0, 0.5])
    assert plain[4].isolated == ("j_pos",)
    assert [a.alarm.tolist() for a in graded] == [a.alarm.tolist() for a in plain]    # alarms unchanged
    assert graded[4].isolated == ("j_vel",)
    # latched and confirmed: the kinematic row alone later does not add the encoder fault it would suggest
    assert graded[5].isolated == ("j_vel",) and graded[5].new == ()


@pytest.mark.parametrize("evidence", [[1.0], [1.0, 0.0], [1.0, 1.5], [1.0, np.nan]])
def test_evidence_is_validated(evidence):
    sigs = [Signature("j_pos", {"j_kin"})]
    with pytest.raises(RobofdiError, match="evidence"):
        ThresholdDecision(["j_kin", "j_step"], np.ones(2), sigs, evidence=evidence)


def _episode(decision, rows, samples):
    return [decision.update(np.array(rows, dtype=float)) for _ in range(samples)]


def test_a_false_isolation_is_revised_by_a_later_fault_once_its_episode_is_over():
    """An encoder hypothesis confirmed on a short fault-free transient may raise every dynamic row (allowed); latched,
    it explains — and so masks — a later actuator fault. With ``release`` the quiet time ends the episode, the next
    alarm is decided afresh, and the stale hypothesis, whose row did not persist, is dropped."""
    comps = ["j1", "j2", "j1_kin"]
    sigs = [Signature("j1", {"j1"}), Signature("j2", {"j2"}), Signature("j1_pos", {"j1_kin"}, {"j1", "j2"})]
    latched = ThresholdDecision(comps, np.ones(3), sigs, confirm=3)
    revisable = ThresholdDecision(comps, np.ones(3), sigs, confirm=3, release=20)
    out = {}
    for name, d in (("latched", latched), ("revisable", revisable)):
        _episode(d, [0, 0, 2], 5)            # the false alarm: the kinematic row alone
        _episode(d, [0, 0, 0], 30)           # quiet
        out[name] = _episode(d, [0, 3, 0], 10)       # the real fault: actuator j2
    assert latched.update(np.zeros(3)).isolated == ("j1_pos",)
    assert out["latched"][-1].isolated == ("j1_pos",)
    assert out["revisable"][-1].isolated == ("j2",) and any(a.new == ("j2",) for a in out["revisable"])
    assert out["revisable"][0].isolated == ("j1_pos",)       # reported until the new window decides


def test_revision_keeps_a_hypothesis_its_evidence_still_supports():
    comps = ["j1", "j2", "j1_kin"]
    sigs = [Signature("j1", {"j1"}), Signature("j2", {"j2"}), Signature("j1_pos", {"j1_kin"}, {"j1"})]
    d = ThresholdDecision(comps, np.ones(3), sigs, confirm=3, release=20)
    _episode(d, [0, 0, 2], 5)
    _episode(d, [0, 0, 0], 30)
    assert _episode(d, [0, 3, 2], 10)[-1].isolated == ("j1_pos", "j2")
    d.reset()
    _episode(d, [0, 0, 2], 5)
    _episode(d, [0, 0, 0], 30)
    assert _episode(d, [0, 0, 0.5], 10)[-1].isolated == ("j1_pos",)      # nothing new alarmed: unchanged
    with pytest.raises(RobofdiError, match="release"):
        ThresholdDecision(comps, np.ones(3), sigs, release=-1)


def test_a_later_row_overturns_the_hypothesis_it_refines_while_alarmed():
    """An encoder fault confirmed on its kinematic row alone becomes a velocity fault when the step row alarms later
    in the same episode for ``overturn`` samples in a row (a velocity-gain error's evidence accumulates after its
    onset): the velocity hypothesis requires the encoder hypothesis's evidence and more. A later sensor fault of
    another joint joins an actuator fault and does not replace it: it requires none of its rows."""
    comps = ["j1", "j2", "j1_kin", "j1_step", "j2_kin"]
    sigs = [Signature("j1", {"j1"}, {"j1_step"}), Signature("j2", {"j2"}),
            Signature("j1_pos", {"j1_kin"}, {"j1", "j2"}), Signature("j1_vel", {"j1_kin", "j1_step"}, {"j1", "j2"}),
            Signature("j2_pos", {"j2_kin"}, {"j1", "j2"})]
    d = ThresholdDecision(comps, np.ones(5), sigs, confirm=3, overturn=4)
    assert _episode(d, [0, 0, 2, 0, 0], 10)[-1].isolated == ("j1_pos",)
    assert _episode(d, [0, 0, 2, 3, 0], 3)[-1].isolated == ("j1_pos",)       # not yet: 3 of 4 samples
    _episode(d, [0, 0, 2, 0, 0], 1)
    out = _episode(d, [0, 0, 2, 3, 0], 5)
    assert [a.isolated for a in out[:3]] == [("j1_pos",)] * 3
    assert out[3].isolated == ("j1_vel",) and out[3].new == ("j1_vel",)
    assert _episode(d, [0, 0, 2, 0, 0], 3)[-1].isolated == ("j1_vel",)       # latched once the step row decays
    d.reset()
    assert _episode(d, [3, 0, 0, 0, 0], 10)[-1].isolated == ("j1",)
    assert d.overturn == 4 and ThresholdDecision(comps, np.ones(5), sigs).overturn == 0
    with pytest.raises(RobofdiError, match="overturn"):
        ThresholdDecision(comps, np.ones(5), sigs, overturn=-1)
    assert _episode(d, [3, 0, 0, 0, 2], 5)[-1].isolated == ("j1", "j2_pos")


def test_an_overturn_is_not_blocked_by_another_fault_that_may_raise_the_same_row():
    """The refining hypothesis's rows count whichever isolated fault may also account for them: an encoder fault
    isolated beside a fault that may raise its joint's step row (a payload change) still becomes a velocity fault,
    and the other fault stays."""
    comps = ["j1", "j1_kin", "j1_step", "p"]
    sigs = [Signature("j1", {"j1"}, {"j1_step"}), Signature("j1_pos", {"j1_kin"}, {"j1"}),
            Signature("j1_vel", {"j1_kin", "j1_step"}, {"j1"}), Signature("p", {"p"}, {"j1", "j1_step"})]
    d = ThresholdDecision(comps, np.ones(4), sigs, confirm=3, overturn=4)
    assert _episode(d, [0, 2, 0, 0], 10)[-1].isolated == ("j1_pos",)
    assert _episode(d, [0, 2, 0, 3], 3)[-1].isolated == ("j1_pos", "p")
    out = _episode(d, [0, 2, 3, 3], 4)
    assert [a.isolated for a in out] == [("j1_pos", "p")] * 3 + [("j1_vel", "p")] and out[-1].new == ("j1_vel",)
    assert _episode(d, [0, 0, 3, 0], 10)[-1].isolated == ("j1_vel", "p")      # a step row alone refines nothing
    d.reset()
    _episode(d, [0, 2, 0, 0], 10)
    _episode(d, [0, 2, 3, 0], 3)
    _episode(d, [0, 0, 0, 0], 1)                   # a quiet sample: the rows did not alarm in a row
    assert _episode(d, [0, 2, 3, 0], 3)[-1].isolated == ("j1_pos",)
    assert _episode(d, [0, 2, 3, 0], 1)[-1].isolated == ("j1_vel",)


def _gain_error(defer):
    """The kinematic row alarms for good from sample 1; the step row (a velocity-gain error's gain evidence, which
    needs motion) crosses its evidence level 0.5 from sample 6 on."""
    sigs = [Signature("j_pos", {"j_kin"}), Signature("j_vel", {"j_kin", "j_step"})]
    d = ThresholdDecision(["j_kin", "j_step"], np.ones(2), sigs, confirm=3, evidence=[1.0, 0.5], defer=defer)
    rows = [[0.1, 0.1]] + [[3.0, 0.1]] * 5 + [[3.0, 0.8]] * 6
    return [d.update(r) for r in rows]


def test_deferral_lets_the_refining_hypothesis_show_before_an_encoder_is_named():
    """Without deferral the window ends at sample 4 on the kinematic row alone: the encoder. Deferred by 4 samples
    it ends at sample 8, the step row evident at samples 6–8: the velocity sensor, named first. Alarms are not
    delayed; a hypothesis nothing refines is not deferred (the actuator of the velocity-sensor case)."""
    hasty, deferred = _gain_error(0), _gain_error(4)
    assert hasty[4].isolated == ("j_pos",)
    assert [a.alarm.tolist() for a in deferred] == [a.alarm.tolist() for a in hasty]
    assert all(a.isolated == () for a in deferred[:8])
    assert deferred[8].isolated == ("j_vel",) and deferred[8].new == ("j_vel",)
    sigs = [Signature("j", {"j"}), Signature("j_pos", {"j_kin"}, {"j"})]
    d = ThresholdDecision(["j", "j_kin"], np.ones(2), sigs, confirm=3, defer=10)
    out = [d.update(r) for r in ([3.0, 0.2], [3.0, 0.2], [3.0, 0.2], [3.0, 0.2])]
    assert out[3].isolated == ("j",)


def test_defer_is_validated():
    with pytest.raises(RobofdiError, match="defer"):
        ThresholdDecision(["a"], [1.0], [Signature("a", {"a"})], confirm=1, defer=-2)
