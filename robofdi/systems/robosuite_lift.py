"""robosuite's Lift with the Panda as a system: arm faults inside robosuite, the momentum diagnosers online,
task success with and without compensation (:mod:`robofdi.adapters.robosuite_diagnosis`; extra ``robosuite``)."""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from robofdi.adapters import adapter
from robofdi.checks import check_fields, check_robot_seeds, is_int
from robofdi.protocols import Mission, Parts, TargetLimit
from robofdi.systems import RobotInstances, register_system

__all__ = []


@dataclass(frozen=True)
class RobosuiteLiftOptions:
    """The ``[system]`` table of a robosuite Lift campaign (:mod:`robofdi.adapters.robosuite_diagnosis`: the Panda
    with OSC_POSE and the scripted grasp). robot_seeds: one calibration each, on ``calibration_episodes``
    fault-free episodes of seeds 1000·(1 + robot seed) + i; episode_steps: policy steps (20 Hz) per episode;
    accommodation: effectiveness compensation fed by ``health_source``."""

    robot_seeds: tuple = (0,)
    calibration_episodes: int = 30
    episode_steps: int = 140
    accommodation: bool = False
    health_source: str = "momentum"

    def __post_init__(self):
        check_robot_seeds(self)
        check_fields("system", self, [
            ("calibration_episodes", is_int(self.calibration_episodes, 2), "an integer >= 2"),
            ("episode_steps", is_int(self.episode_steps, 20) and self.episode_steps <= 2000, "an integer in [20, 2000]"),
            ("accommodation", isinstance(self.accommodation, bool), "true or false"),
            ("health_source", self.health_source in ("momentum", "momentum_friction"), "'momentum' or 'momentum_friction'"),
        ])

    def calibration_seeds(self, key: int) -> tuple:
        return tuple(1000 * (1 + int(key)) + i for i in range(self.calibration_episodes))


@functools.lru_cache(maxsize=1)
def _lift_env():
    """One robosuite Lift per process, reused by every run (robosuite.make takes seconds)."""
    return adapter("robofdi.adapters.robosuite_diagnosis", "robosuite").make_lift()


@register_system
class RobosuiteLiftSystem(RobotInstances):
    """robosuite's Lift with the Panda (OSC_POSE, scripted grasp; the script's variations are the mission), arm
    faults through :class:`~robofdi.adapters.robosuite.FaultyRobosuiteEnv`, the momentum diagnosers online."""

    name = "robosuite-lift"
    options_type = RobosuiteLiftOptions

    def diagnosers(self, options):
        return adapter("robofdi.adapters.robosuite_diagnosis", "robosuite").DIAGNOSERS

    def targets(self, options):
        arm = adapter("robofdi.adapters.robosuite", "robosuite").RobotArm(_lift_env())
        width = arm.joint_range[:, 1] - arm.joint_range[:, 0]
        sensors = {ch: TargetLimit(float(width[i % arm.n]), "rad" if i < arm.n else "rad/s")
                   for i, ch in enumerate(arm.sensor_channels)}          # velocity channels: one range per second
        return {"actuator": {j: TargetLimit(float(np.abs(arm.torque_range[i]).max()), "N·m") for i, j in enumerate(arm.joints)},
                "sensor": sensors,
                "component_friction": {j: TargetLimit(1.0, "1") for j in arm.joints},
                "component_mass": {"payload": TargetLimit(3.0, "kg")}}      # the Panda's rated payload

    def calibrate(self, options, key, diagnosers):
        rd = adapter("robofdi.adapters.robosuite_diagnosis", "robosuite")
        return rd.lift_calibration(options.calibration_seeds(key), steps=options.episode_steps)

    def mission(self, options, key, generator):
        script = int(generator.integers(2**31))
        return Mission(options.episode_steps / 20.0, script, {"script_seed": script})

    def build(self, options, calibration, key, mission, faults, seed, diagnosers):
        rd = adapter("robofdi.adapters.robosuite_diagnosis", "robosuite")
        loop = rd.LiftLoop(calibration, tuple(faults), options.accommodation, options.health_source, tuple(diagnosers),
                           _lift_env(), options.episode_steps, mission.plan)
        return Parts(loop, mission.duration, None, seed, "campaign", "campaign-robosuite-lift", {"robot_seed": int(key)})
