"""The chapter-4 experiment definitions (the runs themselves are measured in the README, ~1 min each)."""
from robofdi.cli import _experiments
from robofdi.experiments.ch4_auv import ODIN_ONSETS, ch4_auv_scenario, ch4_depth_sensor_scenario, ch4_flooded_scenario
from robofdi.systems.auv import check_scenario


def test_the_chapter_4_experiments_are_listed():
    assert {"ch4-auv", "ch4-flooded", "ch4-depth-sensor", "ch4-roby2"} <= set(_experiments())


def test_ch4_auv_keeps_odins_order_and_onset_ratio():
    sc = ch4_auv_scenario()
    (t2, t6) = (f.onset for f in sc.faults)
    assert [f.name for f in sc.faults] == ["thruster2_off", "thruster6_off"]
    assert [f.target for f in sc.faults] == ["thruster2", "thruster6"]
    assert t2 < t6 < sc.duration and t2 / t6 == ODIN_ONSETS[0] / ODIN_ONSETS[1]
    assert sc.variant == "diagnosed" and sc.health_source == "voltage_residual"
    for make in (ch4_auv_scenario, ch4_flooded_scenario, ch4_depth_sensor_scenario):
        check_scenario(make())
