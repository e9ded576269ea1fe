"""Composed configuration (robofdi.config): flat and nested names, one rule for specs, keywords and evolve."""
from __future__ import annotations

from dataclasses import dataclass

import pytest

from robofdi.campaign.spec import load_spec
from robofdi.config import accepted, compose, evolve, part
from robofdi.errors import RobofdiError
from robofdi.systems.arm import ARM_MISMATCH, ArmOptions
from robofdi.systems.auv import AuvOptions
from robofdi.systems.helicopter import HelicopterOptions


@dataclass(frozen=True)
class Motor:
    gain: float = 1.0
    limit: float = 5.0

    def __post_init__(self):
        if self.limit <= 0:
            raise RobofdiError(f"Motor: field 'limit' must be > 0, got {self.limit!r}")


@dataclass(frozen=True)
class Sensor:
    noise: float = 0.1
    limit: float = 2.0


@dataclass(frozen=True)
class Rig:
    motor: Motor = part(Motor, lambda: Motor(gain=2.0))
    sensor: Sensor = part(Sensor)
    name: str = "rig"


def test_flat_names_reach_the_one_part_that_declares_them_from_its_declared_default():
    rig = compose(Rig, {"noise": 0.3, "name": "a"})
    assert rig == Rig(Motor(gain=2.0), Sensor(noise=0.3), "a")          # the motor kept its declared gain 2
    assert compose(Rig, {"motor": {"limit": 9.0}}).motor == Motor(gain=2.0, limit=9.0)
    assert accepted(Rig)["gain"] == ("motor", "gain") and accepted(Rig)["limit"] == ()
    assert evolve(rig, gain=3.0, noise=0.0) == Rig(Motor(gain=3.0), Sensor(noise=0.0), "a")


def test_ambiguous_unknown_and_invalid_names_are_refused_with_the_field():
    with pytest.raises(RobofdiError, match="'limit' is declared by several parts.*motor.limit"):
        compose(Rig, {"limit": 1.0}, "system")
    with pytest.raises(RobofdiError, match="system: unknown field 'gian'; expected some of gain, "):
        compose(Rig, {"gian": 1.0}, "system")
    with pytest.raises(RobofdiError, match=r"^system\.motor: field 'limit' must be > 0, got -1"):
        compose(Rig, {"motor": {"limit": -1}}, "system")


def test_system_options_compose_the_simulator_mismatch_and_mission():
    arm = compose(ArmOptions, {"robot": "arm7.xml", "speed": "fast", "mass": 0.05, "velocity_noise": 0.0})
    assert (arm.plant.robot, arm.missions.speed, arm.plant.sensors.velocity_noise) == ("arm7.xml", "fast", 0.0)
    assert (arm.mismatch.mass, arm.mismatch.inertia) == (0.05, ARM_MISMATCH.inertia)
    auv = compose(AuvOptions, {"duration": 30, "current": [0.2, 0.0, 0.0]})
    assert auv.scenario.duration == 30.0 and auv.scenario.plant.current == (0.2, 0.0, 0.0)
    assert compose(HelicopterOptions, {"mismatch": 0.1}).scenario.mismatch == 0.1
    with pytest.raises(RobofdiError, match="field 'seed' is not an option"):
        compose(HelicopterOptions, {"seed": 3}, "system")
    with pytest.raises(RobofdiError, match="system.scenario.plant: field 'current' must be three finite"):
        compose(AuvOptions, {"current": [1.0, 2.0]}, "system")


def test_a_spec_takes_the_same_field_flat_or_nested():
    flat = load_spec('seed = 0\nfault_free_runs = 1\nfaulty_runs = 0\n[system]\nname = "arm"\nrobot = "arm7.xml"\n')
    nested = load_spec('seed = 0\nfault_free_runs = 1\nfaulty_runs = 0\n[system]\nname = "arm"\n'
                       '[system.plant]\nrobot = "arm7.xml"\n[system.missions]\nspeed = "fast"\n')
    assert flat.options.plant == nested.options.plant and nested.options.missions.speed == "fast"
    with pytest.raises(RobofdiError, match="system: unknown field 'robut'"):
        load_spec('seed = 0\nfault_free_runs = 1\nfaulty_runs = 0\n[system]\nname = "arm"\nrobut = "x.xml"\n')


@pytest.mark.parametrize("field, value, expected", [
    ("threshold_margin", 0.5, "'threshold_margin' must be a number >= 1"),
    ("startup_blanking", -1.0, "'startup_blanking' must be a time in"),
    ("injection", "later", "'injection' must be 'online' or 'offline'"),
    ("schemes", (), "'schemes' must be a non-empty subset"),
    ("mass", float("nan"), r"ArmScenario\.mismatch: field 'mass' must be a relative error"),
    ("payload", -2.0, r"ArmScenario\.plant: field 'payload' must be a finite mass"),
])
def test_arm_scenario_options_are_refused_at_construction(field, value, expected):
    from robofdi.control import Quintic
    from robofdi.systems.arm import ArmScenario

    with pytest.raises(RobofdiError, match=expected):
        compose(ArmScenario, {"name": "t", "motion": Quintic((0.0,) * 6, (0.1,) * 6, 1.0), field: value})


def test_a_campaign_sets_the_arm_diagnosers_settings_and_its_scenarios_carry_them():
    from robofdi.systems import get_system

    base = 'seed = 0\nfault_free_runs = 1\nfaulty_runs = 0\n[system]\nname = "arm"\n'
    spec = load_spec(base + "consistency_gain = 50\nconsistency_windows = [0.0, 0.5]\n")
    assert spec.options.settings.consistency_gain == 50 and spec.options.settings.consistency_windows == (0.0, 0.5)
    arm = get_system("arm")
    tuned = arm._scenario(spec.options, 3, ["consistency"])
    default = arm._scenario(load_spec(base).options, 3, ["consistency"])
    assert tuned.settings == spec.options.settings and default.settings.consistency_gain == 100
    with pytest.raises(RobofdiError, match="system: field 'T' is not an option: the diagnosis sample time"):
        load_spec(base + "T = 0.001\n")
    with pytest.raises(RobofdiError, match=r"system\.settings: field 'consistency_gain' must be a finite number > 0"):
        load_spec(base + "consistency_gain = -5\n")
    with pytest.raises(RobofdiError, match=r"consistency_tail' must be one of \['gumbel', 'exponential', 'exponent"):
        load_spec(base + 'consistency_tail = "pareto"\n')


def test_a_campaign_sets_the_arms_loop_rates_and_its_calibration_follows_them():
    """control_hz / diagnosis_hz reach every scenario of the campaign (and so its calibration's key); rates the
    robot cannot run are refused when the spec is read, naming the field and what would do."""
    from robofdi.loop import Rates
    from robofdi.systems import get_system
    from robofdi.systems.arm import _calibration_description, calibration_trajectories

    base = 'seed = 0\nfault_free_runs = 1\nfaulty_runs = 0\n[system]\nname = "arm"\n'
    arm = get_system("arm")
    default = arm._scenario(load_spec(base).options, 3, ["momentum"])
    assert default.rates is None and default.loop_rates(default.simulator()) == Rates(1000.0, 500.0)
    fine = arm._scenario(load_spec(base + "diagnosis_hz = 1000.0\n").options, 3, ["momentum"])
    fast = arm._scenario(load_spec(base + "control_hz = 2000\n").options, 3, ["momentum"])
    assert fine.rates == Rates(1000.0, 1000.0) and fast.rates == Rates(2000.0, 500.0)
    assert fast.simulator().control_dt == pytest.approx(5e-4)
    keys = [_calibration_description(sc, sc.simulator(), calibration_trajectories(sc))["rates"]
            for sc in (default, fine, fast)]
    assert len(set(keys)) == 3
    with pytest.raises(RobofdiError, match="field 'diagnosis_hz' must divide the control rate 1000 Hz, got 300"):
        load_spec(base + "diagnosis_hz = 300.0\n")
    with pytest.raises(RobofdiError, match="field 'control_hz' must make the control period a multiple of the physics "
                                           "step 0.0005 s of arm6.xml"):
        load_spec(base + "control_hz = 1500.0\n")
    with pytest.raises(RobofdiError, match="field 'control_hz' must be none or a rate > 0 Hz"):
        load_spec(base + "control_hz = -1.0\n")
