"""The one-line fault SPEC of the command line: KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE]."""
import pytest

from robofdi import RobofdiError
from robofdi.faults import ExponentialRise, Intermittent, Ramp, Sinusoid, Step, parse_fault_spec, parse_fault_specs
from robofdi.faults.profiles import PROFILE_TYPES, Oscillation, profile_from_dict
from robofdi.faults.spec import PROFILE_HELP


def test_full_spec():
    f = parse_fault_spec("sensor_bias:joint3_pos:0.004@1.5-2.5~ramp(0.5)")
    assert (f.kind, f.target, f.magnitude, f.onset, f.end, f.profile) == ("sensor_bias", "joint3_pos", 0.004, 1.5, 2.5,
                                                                          Ramp(0.5))
    assert f.name == "joint3_pos_bias"


@pytest.mark.parametrize("text, profile", [
    ("actuator_additive:joint2:20@1.0", Step()),
    ("actuator_additive:joint5:40@3~exponential_rise(0.08)", ExponentialRise(0.08)),
    ("actuator_additive:joint5:40@3~exp(0.08)", ExponentialRise(0.08)),             # the short alias
    ("actuator_additive:joint5:40@3~sinusoid(2,0.5)", Sinusoid(2.0, 0.5)),
    ("actuator_loss_of_effectiveness:joint5:1@3~oscillation(0.5,0.3,0.5)", Oscillation(0.5, 0.3, 0.5)),
    ("actuator_additive:joint5:40@3~sin(2,0.5)", Sinusoid(2.0, 0.5)),
    ("actuator_additive:joint5:40@3~intermittent(0.4,0.25)", Intermittent(0.4, 0.25)),
])
def test_profiles(text, profile):
    assert parse_fault_spec(text).profile == profile


def test_one_vocabulary_with_the_toml():
    """Every profile type a campaign TOML (profile_from_dict) accepts is a CLI profile by the same name, and the
    help lists the canonical names; a spec's profile serialises to the TOML's form."""
    for name in PROFILE_TYPES:
        assert PROFILE_HELP.split(", ").count(next(p for p in PROFILE_HELP.split(", ") if p.split("(")[0] == name)) == 1
    assert "exponential_rise(TAU)" in PROFILE_HELP and "exp(" not in PROFILE_HELP
    f = parse_fault_spec("actuator_additive:joint5:40@3~exponential_rise(0.08)")
    assert f.to_dict()["profile"] == {"type": "exponential_rise", "tau": 0.08}
    assert profile_from_dict(f.to_dict()["profile"]) == f.profile


def test_params_and_numbering():
    a, b = parse_fault_specs(["actuator_hard_over:joint1:0@1~ramp(0.2);limit=150"] * 2)
    assert a.params == {"limit": 150.0} and (a.name, b.name) == ("joint1_hard_over", "joint1_hard_over_2")


@pytest.mark.parametrize("text, message", [
    ("actuator_additive:joint2", "expected KIND:TARGET"),
    ("actuator_additive:joint2:x@1", "MAGNITUDE must be a number"),
    ("actuator_explode:joint2:1@1", "unknown kind 'actuator_explode'"),
    ("actuator_additive:joint2:1@1~spike(3)", "unknown profile 'spike'"),
    ("actuator_additive:joint2:1@1~exp(1,2)", "exp takes 1 argument"),
    ("actuator_additive:joint2:1@2-1", "'end'"),
    ("actuator_drift:joint1:1@1~exp(1)", "must be step for actuator_drift"),
    ("actuator_hard_over:joint1:0@1", "requires params\\['limit'\\]"),
])
def test_errors_name_the_part(text, message):
    with pytest.raises(RobofdiError, match=message) as err:
        parse_fault_spec(text)
    assert "\n" not in str(err.value) and text in str(err.value)
