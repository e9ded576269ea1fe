"""Hotelling T² (Antonelli's survey, Sec. 4 [7, 29]): the UCL, its false-alarm rate, detection and isolation."""
import numpy as np
import pytest
from scipy.stats import f as fisher

from robofdi.decision.hotelling import HotellingT2Decision, hotelling_fit, hotelling_ucl
from robofdi.errors import RobofdiError
from robofdi.testing import check_decision


def _data(seed, n, shift=(0.0, 0.0, 0.0)):
    g = np.random.default_rng(seed)
    L = np.array([[1.0, 0, 0], [0.6, 0.8, 0], [0.2, -0.3, 0.5]])
    return g.standard_normal((n, 3)) @ L.T + np.asarray(shift)


def test_ucl_is_the_new_observation_limit():
    assert hotelling_ucl(3, 200, 0.01) == pytest.approx(3 * 201 * 199 / (200 * 197) * fisher.ppf(0.99, 3, 197))
    with pytest.raises(RobofdiError, match="p < m"):
        hotelling_ucl(5, 5, 0.01)


def test_false_alarm_rate_detection_and_nearest_class():
    fit = hotelling_fit(_data(0, 2000), alpha=0.01)
    dec = HotellingT2Decision(["u", "v", "r"], fit, {"jam_a": [3, 0, 0], "jam_b": [0, 0, 2]})
    alarms = np.mean([dec.update(x).alarm.any() for x in _data(1, 5000)])
    assert 0.005 < alarms < 0.02                                  # ≈ α on fresh fault-free data
    dec.reset()
    hits = [dec.update(x) for x in _data(2, 200, (0, 0, 3.0))]
    assert np.mean([a.alarm.any() for a in hits]) > 0.9
    assert hits[-1].isolated[0] == "jam_b"
    plain = HotellingT2Decision(["u", "v", "r"], fit)
    assert plain.update(np.array([10.0, 0, 0])).isolated == ("unknown",)


def test_conforms_and_refuses_bad_input():
    fit = hotelling_fit(_data(0, 300))
    check_decision(lambda: HotellingT2Decision(["u", "v", "r"], fit, {"a": [3, 0, 0]}), _data(3, 60) * 2)
    with pytest.raises(RobofdiError, match="m > p"):
        hotelling_fit(np.zeros((2, 3)))
    with pytest.raises(RobofdiError, match="singular"):
        hotelling_fit(np.column_stack([_data(0, 50)[:, :2], np.ones(50)]))
    with pytest.raises(RobofdiError, match="finite values"):
        HotellingT2Decision(["u", "v", "r"], fit).update(np.array([np.nan, 0, 0]))
