"""The one calibration cache (robofdi.calibration): key, format (no pickle), atomic files, clearing."""
from __future__ import annotations

import numpy as np
import pytest

from robofdi import calibration
from robofdi.decision import Signature


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOFDI_CACHE", str(tmp_path / "cache"))
    calibration._memory.clear()
    yield tmp_path / "cache"
    calibration._memory.clear()


def test_a_cached_calibration_is_not_reused_by_other_code(cache, monkeypatch):
    """The cache key holds a hash of robofdi's source: the same options under changed code recompute."""
    assert len(calibration.code_fingerprint()) == 64
    calls = []

    def compute():
        calls.append(1)
        return {"calibration": len(calls)}

    first, cached_first = calibration.cached("probe", {"option": 1}, compute)
    again, cached_again = calibration.cached("probe", {"option": 1}, compute)
    assert (cached_first, cached_again) == (False, True) and again == first
    other_options, cached_other_options = calibration.cached("probe", {"option": 2}, compute)
    assert not cached_other_options and other_options == {"calibration": 2}
    monkeypatch.setattr(calibration, "code_fingerprint", lambda: "0" * 64)
    other, cached_other = calibration.cached("probe", {"option": 1}, compute)
    assert not cached_other and other == {"calibration": 3}
    assert len(calibration.entries()) == 3


def test_the_format_round_trips_data_and_library_objects_exactly():
    rng = np.random.default_rng(4)
    value = {"thresholds": {"momentum": rng.normal(size=6), ("a", 1): np.arange(3, dtype=np.int32)},
             "theta0": rng.normal(size=(2, 3)), "blanking": 12, "margin": 1.2, "inf": float("inf"),
             "names": ("joint1", "joint2"), "list": [1, "x", None, True], "scalar": np.float64(0.1 + 0.2),
             "signature": Signature("tau1", frozenset({"r1", "r2"})), "empty": np.zeros((0, 4))}
    back = calibration.loads(calibration.dumps(value))
    assert back["blanking"] == 12 and back["margin"] == 1.2 and back["inf"] == float("inf")
    assert back["names"] == ("joint1", "joint2") and back["list"] == [1, "x", None, True]
    np.testing.assert_array_equal(back["thresholds"]["momentum"], value["thresholds"]["momentum"])
    assert back["thresholds"][("a", 1)].dtype == np.int32
    assert back["scalar"] == value["scalar"] and isinstance(back["scalar"], np.float64)
    assert back["signature"] == value["signature"] and back["empty"].shape == (0, 4)


def test_random_states_round_trip_and_go_on_with_the_same_numbers():
    legacy, generator = np.random.RandomState(7), np.random.default_rng(7)
    legacy.normal(size=3), generator.normal(size=3)
    back = calibration.loads(calibration.dumps({"legacy": legacy, "generator": generator}))
    np.testing.assert_array_equal(back["legacy"].normal(size=5), legacy.normal(size=5))
    np.testing.assert_array_equal(back["generator"].normal(size=5), generator.normal(size=5))


def test_an_object_comes_back_with_its_whole_state_and_works():
    """Not only a dataclass's fields: what __post_init__ derived too (a decision's signature map, its counters)."""
    from robofdi.decision import ThresholdDecision

    decision = ThresholdDecision(["a", "b"], np.array([1.0, 1.0]), [Signature("f", frozenset({"a"}))], confirm=2)
    back = calibration.loads(calibration.dumps(decision))
    for r in ([0.1, 0.0], [2.0, 0.0], [2.0, 0.1], [2.0, 0.0]):
        ours, theirs = decision.update(np.array(r)), back.update(np.array(r))
        assert ours.isolated == theirs.isolated and np.array_equal(ours.alarm, theirs.alarm)
    assert back.update(np.array([2.0, 0.0])).isolated == ("f",)


def test_the_format_refuses_what_it_would_have_to_pickle():
    class Local:
        pass

    for bad in (lambda: 0, Local(), np.array([object()]), {"f": print}):
        with pytest.raises(TypeError, match="calibration cache"):
            calibration.dumps(bad)


def test_an_untrusted_class_in_a_file_is_refused_not_imported(cache):
    data = calibration.dumps({"x": Signature("tau1", frozenset({"r1"}))})
    forged = data.replace(b"robofdi.decision", b"os.pathxxxxxxxxx")     # same length: the zip stays valid
    with pytest.raises((ValueError, Exception)):
        calibration.loads(forged)


def test_a_torn_file_is_recomputed_and_an_unstorable_value_kept_in_memory(cache):
    calibration.cached("probe", {"n": 1}, lambda: {"v": np.ones(3)})
    (path,) = calibration.entries()
    path.write_bytes(path.read_bytes()[:40])                            # torn
    value, from_cache = calibration.cached("probe", {"n": 1}, lambda: {"v": np.zeros(3)})
    assert not from_cache and value["v"].sum() == 0
    with pytest.warns(UserWarning, match="kept in memory only"):
        closure = calibration.cached("probe", {"n": 2}, lambda: (lambda: 7))
    assert closure[1] is False and calibration.cached("probe", {"n": 2}, lambda: None)[0]() == 7
    assert calibration.is_cached("probe", {"n": 1}) and not calibration.is_cached("probe", {"n": 3})


def test_clear_empties_the_cache(cache):
    for n in range(3):
        calibration.cached("probe", {"n": n}, lambda n=n: n)
    assert calibration.clear() == 3 and calibration.entries() == []
    assert not calibration.cached("probe", {"n": 0}, lambda: 0)[1]


def test_a_trained_hydraulic_calibration_is_stored_and_predicts_the_same(cache):
    """The hydraulic rig's calibration holds a trained scikit-learn network (and its random state): it is stored,
    not kept in memory, and the loaded network predicts exactly what the trained one does."""
    from robofdi.systems.hydraulic import HydraulicScenario, calibration as hydraulic_calibration

    base = HydraulicScenario("probe", duration=3.0)
    cal, cached = hydraulic_calibration(base, 2, 1000)
    again, cached_again = hydraulic_calibration(base, 2, 1000)
    assert (cached, cached_again) == (False, True) and len(calibration.entries()) == 1
    calibration._memory.clear()
    loaded = calibration.loads(calibration.entries()[0].read_bytes())
    x = np.random.default_rng(0).normal(size=(40, cal.mlp_ar.regressor_.n_features_in_))
    np.testing.assert_array_equal(loaded.mlp_ar.predict(x), cal.mlp_ar.predict(x))
    np.testing.assert_array_equal(loaded.thresholds["nlar"], cal.thresholds["nlar"])
