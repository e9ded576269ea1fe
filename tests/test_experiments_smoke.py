"""A cheap smoke test per experiment: every registered experiment resolves to a module with the ``run`` contract,
and what each one builds before its first calibration is built and stepped a few ticks (``edwards-auv-ftc``
crashed at its first line for a whole session with no test noticing). No calibration runs here: the full runs
are the experiments themselves (`robofdi run NAME`)."""
from __future__ import annotations

import inspect
from dataclasses import replace

import numpy as np
import pytest

from robofdi.experiments import experiments

SHIPPED = experiments()


def test_every_experiment_resolves_to_a_run_function_with_the_contract():
    assert len(SHIPPED) >= 20
    for name, (description, module) in SHIPPED.items():
        assert isinstance(description, str) and description, name
        run = getattr(module, "run_system", None) if module.__name__.endswith("system_run") else module.run
        params = list(inspect.signature(module.run).parameters)
        assert params[:4] == ["name", "out", "seed", "progress"], (name, params)
        assert callable(run)


AUV_BUILDERS = {
    "ch4-auv": "ch4_auv_scenario", "ch4-flooded": "ch4_flooded_scenario",
    "ch4-depth-sensor": "ch4_depth_sensor_scenario", "ch4-roby2": "ch4_roby2_scenario",
}


@pytest.mark.parametrize("name", [*AUV_BUILDERS, "edwards-auv-ftc"])
def test_auv_experiments_build_their_scenario_and_fly_a_few_ticks(name):
    # the scenario each AUV experiment builds first, its checks, and 0.2 s of its loop (plant, controller,
    # allocation; no diagnoser, no calibration)
    from robofdi.experiments import ch4_auv, edwards_auv
    from robofdi.systems.auv import check_scenario

    if name == "edwards-auv-ftc":
        from robofdi.ftc.smc_auv import SmcAuvSettings, auv_smc_ca_check
        from robofdi.models.auv import AuvModel

        sc = replace(edwards_auv._scenario(0), name=name, allocation="smc_ca")      # its first lines
        check_scenario(sc)
        auv_smc_ca_check(AuvModel.from_mjcf(sc.plant.mjcf, sc.mismatch), SmcAuvSettings(), samples=20)
    else:
        sc = getattr(ch4_auv, AUV_BUILDERS[name])(0)
        check_scenario(sc)
    assert sc.faults
    rec, ctl = ch4_auv._supervised_run(sc, 0.2, "smoke")
    assert rec.time[-1] == pytest.approx(0.2) and np.all(np.isfinite(rec.truth_state)) and ctl.mode == "mission"


def test_arm_chapter3_experiments_build_their_scenarios():
    from robofdi.experiments.ch3_industrial_robot import EXPERIMENTS, scenario

    for name in EXPERIMENTS:
        sc = scenario(name, seed=0)
        assert sc.faults and sc.schemes
