"""robosuite's Panda doing Lift with the operational-space controller (OSC_POSE) and a scripted grasp; a shoulder
motor loses effectiveness mid-task; momentum diagnosers from a nominal Pinocchio model of the environment's own
MJCF run online; the task is run without and with the core's effectiveness compensation.

    robofdi run robosuite-lift [--fault SPEC ...] [--seed N] [--out DIR]      (needs: pip install 'robofdi[robosuite]')

Default fault: ``actuator_loss_of_effectiveness:joint2:0.6@1.0`` — joint 2 (the Panda's shoulder pitch, the joint
that holds the arm up) keeps 40 % of its torque from 1 s, while the gripper approaches the cube. The seed draws the
cube pose, robosuite's initial joint noise, the script's variations and the sensor noise. Diagnosers
(:mod:`robofdi.adapters.robosuite_diagnosis`): ``momentum`` and ``momentum_friction``, thresholds calibrated on 30
fault-free scripted episodes with grasps (cached per belief and versions).

Three episodes with the same seed: fault-free; faulty without accommodation; faulty with
:class:`~robofdi.ftc.EffectivenessCompensation` fed by the loss of effectiveness ``HEALTH_SOURCE`` identifies after
isolation (one 2 ms substep late). summary.json["task"] holds robosuite's success (cube lifted more than 4 cm
above the table at the end of the 7 s episode) of each, summary.json["accommodation"] the identified loss, and
summary.json["recovery"] the task results in the shape every experiment shares (``robofdi run`` prints it).
The record is the faulty episode without accommodation (``compensated.h5``: with it). ``replay.html`` (self-contained
Meshcat, offline) replays that episode: the Panda's meshes, fingers and cube from the recorded qpos, the faulty
joint ringed from the onset and lit red from its isolation by ``momentum``; ``replay_compensated.html`` the same
with compensation (the cube is lifted). Both are drawn from the environment's own MJCF, written as ``model.xml``
into the run folder (so ``robofdi view`` works on the folder, with the installed robosuite's mesh files).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from robofdi.evaluate.annotate import event_lines
from robofdi.evaluate import summarize
from robofdi.evaluate.headline import recovery_section
from robofdi.evaluate.figures import save_figure
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, replay_writer, write_run_folder
from robofdi.progress import Progress

EXPERIMENTS = {"robosuite-lift": "robosuite Panda Lift (OSC_POSE, scripted grasp): joint-2 loss of effectiveness mid-task, "
                                 "momentum diagnosers online, task success without vs with compensation"}
OPTIONS = ("faults",)
DEFAULT_FAULT = "actuator_loss_of_effectiveness:joint2:0.6@1.0"
HEALTH_SOURCE = "momentum"


def plot_cube_heights(episodes: dict, faults, path: Path) -> Path:
    """Cube height above the table [m] of each episode, with the success height and the fault onsets."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.2))
    for label, ep in episodes.items():
        ax.plot(ep.step_times, ep.cube_height, label=f"{label} ({'success' if ep.success else 'failure'})")
    ax.axhline(0.04, color="0.4", ls="--", lw=0.8, label="success height")
    event_lines(ax, faults)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("cube height above table [m]")
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def run(name: str = "robosuite-lift", out: str | Path = "runs", seed: int = 0, progress: bool = True,
        replay: bool = True, faults=()):
    """Calibrate (cached), run fault-free, faulty, faulty + compensation; evaluate, plot; returns (summary, run folder)."""
    from robofdi.adapters import robosuite_diagnosis as rd
    from robofdi.adapters.robosuite import FaultyRobosuiteEnv, write_mjcf
    from robofdi.faults import parse_fault_spec

    faults = [parse_fault_spec(f) if isinstance(f, str) else f for f in (faults or [DEFAULT_FAULT])]
    env = rd.make_lift()
    FaultyRobosuiteEnv(env, faults).detach()          # bad targets fail here, before anything is simulated
    run_dir = prepare_run_dir(out, name, seed)
    progress = Progress.of(progress, name)
    steps = rd.EPISODE_STEPS
    seeds = len(rd.CALIBRATION_SEEDS)
    with keep_partial(run_dir):
        # one episode per seed for the plain momentum residuals, the same again with friction compensation
        with progress.stage(f"calibration: {seeds} seeds, 2 passes", 2 * seeds, unit="episode",
                            skipped="from the cache") as tick:
            cal, cached = rd.lift_calibration(rd.CALIBRATION_SEEDS, steps=steps, progress=tick)
        episodes, records = {}, {}
        with progress.stage("episodes: fault-free, no accommodation, compensation", 3, unit="episode") as tick:
            for label, fs, acc in (("fault-free", [], False), ("no accommodation", faults, False),
                                   ("compensation", faults, True)):
                episodes[label], records[label] = rd.run_lift(cal, fs, seed, accommodation=acc,
                                                             health_source=HEALTH_SOURCE, env=env, steps=steps,
                                                             scenario=name, meta={"variant": label})
                tick(1)
        write_mjcf(env, run_dir)                     # the model the records name (meta["mjcf"]) for the replays
        env.close()
    record = records["no accommodation"]
    summary = summarize(record, name, [f.to_dict() for f in faults], controller=record.meta["controller"],
                        calibration={"episodes": len(cal.seeds), "cached": cached, "fault_free_successes": cal.success,
                                     "thresholds": cal.thresholds, "thresholds_unit": "N·m", "belief": repr(cal.belief)})
    summary["task"] = {label: {"success": ep.success, "lifted_at": ep.lifted_at,
                               "max_cube_height": float(np.max(ep.cube_height))} for label, ep in episodes.items()}
    compensated = records["compensation"]
    trace = compensated.diagnosers[HEALTH_SOURCE]
    summary["accommodation"] = {
        "method": "effectiveness compensation u = u_cmd / (1 − k̂) of the isolated joints (robofdi.ftc.EffectivenessCompensation)",
        "health_source": HEALTH_SOURCE,
        "isolated_at_end": str(trace.isolated[-1]),
        "diagnosed_in_compensated_run": summarize(compensated, name, [f.to_dict() for f in faults],
                                                  [HEALTH_SOURCE])["diagnosers"][HEALTH_SOURCE]["detections"],
        "true_loss": {f.target: f.magnitude for f in faults if f.kind == "actuator_loss_of_effectiveness"},
        "identified_loss_at_end": compensated.meta["identified_loss"][HEALTH_SOURCE],
        "units": {"lifted_at": "s", "max_cube_height": "m above the table", "loss": "1 (fraction of torque lost)"},
    }
    summary["recovery"] = recovery_section(
        episodes, [{"quantity": "task success (cube lifted > 4 cm at the end)", "unit": None,
                    "values": {k: ep.success for k, ep in episodes.items()}},
                   {"quantity": "cube lifted at", "unit": "s", "values": {k: ep.lifted_at for k, ep in episodes.items()}},
                   {"quantity": "highest cube height above the table", "unit": "m",
                    "values": {k: float(np.max(ep.cube_height)) for k, ep in episodes.items()}}],
        health_source=HEALTH_SOURCE, method=summary["accommodation"]["method"])
    with progress.stage("run folder: records, figures" + (", replays" if replay else "")):
        write_run_folder(run_dir, record, summary, {"compensated": compensated, "fault_free": records["fault-free"]},
                         replay=replay)
        plot_cube_heights(episodes, faults, run_dir / "figures" / "cube_height.png")
        write = replay_writer() if replay else None
        if write is not None:
            write(run_dir / "compensated.h5", run_dir / "replay_compensated.html")
    return summary, run_dir


def main(argv=None) -> int:
    from robofdi.cli import main as cli_main

    return cli_main(["run", "robosuite-lift", *(argv or [])])


if __name__ == "__main__":
    raise SystemExit(main())
