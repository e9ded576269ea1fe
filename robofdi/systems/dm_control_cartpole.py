"""dm_control's cart-pole as a system: faults inside the suite environment, the momentum residual on both joints
(:mod:`robofdi.adapters.dm_control_diagnosis`; extra ``dm_control``)."""
from __future__ import annotations

from dataclasses import dataclass

from robofdi.adapters import adapter
from robofdi.calibration import cached
from robofdi.checks import check_fields, check_robot_seeds, is_int
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.systems import RobotInstances, register_system

__all__ = []


@dataclass(frozen=True)
class CartpoleOptions:
    """The ``[system]`` table of a dm_control cartpole campaign (:mod:`robofdi.adapters.dm_control_diagnosis`: the
    momentum residual on both joints of the suite's cart-pole). robot_seeds: one belief (mass ±``mismatch``, damping
    ±4·``mismatch``) and calibration each, on ``calibration_episodes`` fault-free episodes; steps: 10 ms control
    steps per episode; blanking: start-up samples without alarms."""

    robot_seeds: tuple = (0,)
    calibration_episodes: int = 30
    steps: int = 300
    mismatch: float = 0.05
    blanking: int = 5

    def __post_init__(self):
        check_robot_seeds(self)
        check_fields("system", self, [
            ("calibration_episodes", is_int(self.calibration_episodes, 2), "an integer >= 2"),
            ("steps", is_int(self.steps, 20) and self.steps <= 100_000, "an integer in [20, 100000]"),
            ("mismatch", isinstance(self.mismatch, (int, float)) and 0 <= self.mismatch < 0.125, "a fraction in [0, 0.125)"),
            ("blanking", is_int(self.blanking, 0) and self.blanking < self.steps, "an integer in [0, steps)"),
        ])


@register_system
class CartpoleSystem(RobotInstances):
    """dm_control's cartpole (swingup) under a seeded excitation policy (the mission), faults through
    :class:`~robofdi.adapters.dm_control.FaultyEnvironment`, the momentum residual with calibrated thresholds."""

    name = "dm_control-cartpole"
    options_type = CartpoleOptions

    def diagnosers(self, options):
        return ("momentum",)

    def _diagnoser(self, options, key):
        from robofdi.models.manipulator import ModelMismatch

        dc = adapter("robofdi.adapters.dm_control_diagnosis", "dm_control")
        belief = ModelMismatch(mass=options.mismatch, damping=4 * options.mismatch, seed=int(key))
        return dc, dc.CartpoleDiagnoser(dc.suite_model("cartpole", belief), 0.01)

    def targets(self, options):
        dc, _ = self._diagnoser(options, 0)
        env = dc.cartpole_env()
        ranges = {"position[0]": 3.6, "position[1]": 2.0, "position[2]": 2.0, "velocity[0]": 5.0, "velocity[1]": 20.0}
        return {"actuator": {a: TargetLimit(1.0, "1 (action)") for a in env.actuators},
                "sensor": {c: TargetLimit(ranges[c], "observation unit") for c in env.sensors if c in ranges}}

    def calibrate(self, options, key, diagnosers):
        dc, diagnoser = self._diagnoser(options, key)
        seeds = range(1000 * (1 + int(key)), 1000 * (1 + int(key)) + options.calibration_episodes)
        return cached("dm_control-cartpole", {"options": repr(options), "key": int(key)},
                                   lambda: dc.calibrate_cartpole(diagnoser, seeds, options.steps, options.blanking))

    def mission(self, options, key, generator):
        policy = int(generator.integers(2**31))
        return Mission(options.steps * 0.01, policy, {"policy_seed": policy})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        dc, diagnoser = self._diagnoser(options, key)
        loop = dc.CartpoleLoop(diagnoser, calibration, tuple(faults), options.steps, policy_seed=mission.plan)
        return Parts(loop, mission.duration, None, seed, "campaign", "campaign-dm_control-cartpole")
