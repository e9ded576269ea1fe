"""Any MJCF arm: a seeded point-to-point motion, faults from the command line, every arm diagnoser online, and
the first fault-tolerant control — compensation of the identified actuator fault after isolation.

    robofdi run arm [--robot MJCF] [--fault SPEC ...] [--joints J1,J2,...] [--torque-motors]
                    [--drive-inertia S2] [--payload KG] [--nominal-payload KG] [--seed N] [--out DIR]

SPEC = KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE] (see :mod:`robofdi.faults.spec`), e.g.
``actuator_additive:joint2:20@1.0``. Without ``--fault``: a step of 25 % of the motor torque limit on a seeded
random joint, at 40 % of the motion (:func:`robofdi.systems.arm.arm_scenario`). The robot's calibration
(thresholds, ripple initialisation) is computed once per robot and seed on motions derived from its joint ranges
and torque limits, and cached; the motion under test is drawn from the seed and plays no part in it.

Three runs with the same noise: no accommodation; compensation with the health of ``HEALTH_SOURCE``; and the
same compensation with the true fault (the oracle bound). summary.json["accommodation"] holds the tracking RMS
of each after the first actuator fault's onset, and summary.json["recovery"] the same in the shape every experiment
shares (:mod:`robofdi.evaluate.headline`; ``robofdi run`` prints it). The table and the replay lead with
``HEALTH_SOURCE``, whose health drives the compensation.

``--payload`` puts a load in the simulated arm only (the truth); ``--nominal-payload`` declares one to the
diagnosers (the nominal model carries it). When either is set, or the consistency scheme's calibration identified a
carried mass, summary.json["payload"] holds the three [kg].
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from robofdi.evaluate import summarize
from robofdi.evaluate.headline import recovery_section
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, write_run_folder
from robofdi.loop import ORACLE
from robofdi.progress import Progress, run_ticks
from robofdi.record import Record
from robofdi.systems.arm import arm_scenario, calibration, calibration_steps, calibration_trajectories, run_scenario

EXPERIMENTS = {"arm": "Any MJCF arm (--robot, --fault SPEC): seeded motion, all arm diagnosers online, fault compensation"}
HEALTH_SOURCE = "consistency"
#: The three runs, as summary.json["recovery"] names them.
RECOVERY_VARIANTS = ("no accommodation", "compensation", "oracle compensation")
OPTIONS = ("robot", "faults", "joints", "torque_motors", "drive_inertia", "payload", "nominal_payload")


def tracking_rms(record: Record, since: float) -> float:
    """RMS joint tracking error [rad] over all joints for t ≥ ``since``."""
    n = record.truth_state.shape[1] // 2
    keep = record.time >= since
    err = record.signals["reference"][keep, :n] - record.truth_state[keep, :n]
    return float(np.sqrt(np.mean(err**2)))


def payload_section(sc, cal) -> dict | None:
    """The loads of a run [kg]: the plant's, the declared one (the nominal model's) and the mass the consistency
    scheme's calibration identified beyond it (:class:`~robofdi.observers.consistency.ConsistencyDesign`); None
    when all three are 0."""
    loads = {"plant": float(sc.plant.payload), "declared": float(sc.nominal_payload),
             "identified_beyond_declared": cal.payload}
    return {**loads, "unit": "kg"} if any(loads.values()) else None


def run(name: str = "arm", out: str | Path = "runs", seed: int = 0, progress: bool = True, replay: bool = True,
        robot: str | Path | None = None, faults=(), joints=None, torque_motors: bool = False,
        drive_inertia: float = 0.0, **overrides):
    """Calibrate (cached), run without and with compensation, evaluate, plot; returns (summary, run folder)."""
    robot = robot or "arm6.xml"
    sc = arm_scenario(robot, faults or (), seed, joints, torque_motors, drive_inertia, **overrides)
    run_dir = prepare_run_dir(out, sc.name, seed)
    progress = Progress.of(progress, sc.name)
    sim = sc.simulator()
    rates = sc.loop_rates(sim)
    motions = calibration_trajectories(sc, sim)
    cal_steps = calibration_steps(sc, sum(m.end for m in motions.values()), rates, motions)
    ticks = run_ticks(sc.run_duration, rates.control_hz)
    with keep_partial(run_dir):
        with progress.stage(f"calibration: {len(motions)} motions", cal_steps, skipped="from the cache") as tick:
            cal, cached = calibration(sc, progress=tick)
        with progress.stage("run: no accommodation", ticks) as tick:
            record = run_scenario(sc, cal, progress=tick)
        with progress.stage(f"run: compensation ({HEALTH_SOURCE})", ticks) as tick:
            compensated = run_scenario(replace(sc, accommodation="compensation", health_source=HEALTH_SOURCE), cal,
                                       progress=tick)
        with progress.stage("run: oracle compensation", ticks) as tick:
            oracle = run_scenario(replace(sc, accommodation="compensation", health_source=ORACLE), cal, progress=tick)
    fault_dicts = [f.to_dict() for f in sc.faults]
    summary = summarize(record, name, fault_dicts, robot=str(robot), joints=list(sim.joint_names),
                        injection=sc.injection, calibration_cached=cached,
                        motion={"start_pose": sc.start_pose.tolist(), "duration": sc.motion.end, "unit": "rad, s"})
    payload = payload_section(sc, cal)
    if payload:
        summary["payload"] = payload
    actuator_onsets = [f.onset for f in sc.faults if f.family == "actuator"]
    if actuator_onsets:
        since = min(actuator_onsets)
        summary["accommodation"] = {
            "method": "compensation of the identified actuator fault after isolation (u = u_cmd − δτ̂)",
            "health_source": HEALTH_SOURCE,
            "tracking_rms_after_onset": {"none": tracking_rms(record, since),
                                         "compensation": tracking_rms(compensated, since),
                                         "oracle_compensation": tracking_rms(oracle, since)},
            "since": since,
            "units": {"tracking_rms_after_onset": "rad", "since": "s"},
        }
        rms = summary["accommodation"]["tracking_rms_after_onset"]
        summary["recovery"] = recovery_section(
            RECOVERY_VARIANTS, [{"quantity": f"joint tracking RMS for t >= {since:g} s (first actuator fault)",
                                 "unit": "rad", "values": dict(zip(RECOVERY_VARIANTS, rms.values()))}],
            health_source=HEALTH_SOURCE, method=summary["accommodation"]["method"])
    with progress.stage("run folder: records, figures" + (", replay" if replay else "")):
        write_run_folder(run_dir, record, summary, {"compensated": compensated}, replay=replay)
    return summary, run_dir


def main(argv=None) -> int:
    from robofdi.cli import main as cli_main

    return cli_main(["run", "arm", *(argv or [])])


if __name__ == "__main__":
    raise SystemExit(main())

