"""Any registered system as an experiment: ``robofdi run SYSTEM [--fault SPEC ...] [--seed N]``.

For a system without an experiment of its own (a user's plug-in, or ``package.module:attribute``): the system's
default options, the calibration of its first robot instance (cached, :mod:`robofdi.calibration`), one mission
drawn from the seed (the same draw a campaign makes: :mod:`robofdi.campaign.runs`), the ``--fault`` specs
checked against the system's fault targets, every diagnoser online. The run folder holds summary.json,
record.h5 and the lead diagnoser's residual figure (``robofdi figures RUN`` draws the others).
"""
from __future__ import annotations

import time
from pathlib import Path

from robofdi.errors import RobofdiError
from robofdi.evaluate import summarize
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, write_run_folder
from robofdi.faults import check_faults, parse_fault_specs
from robofdi.progress import Progress
from robofdi.seeding import rng
from robofdi.systems import fault_limit, get_system

__all__ = ["run_system", "run"]

EXPERIMENTS: dict = {}          # the registered systems are listed by the CLI itself


def run_system(name: str, out: str | Path = "runs", seed: int = 0, progress: bool = True, faults=(),
               options=None) -> tuple[dict, Path]:
    """Calibrate (cached), draw the seed's mission, run it with ``faults`` (CLI specs or Fault objects) and every
    diagnoser online; returns (summary, run folder)."""
    system = get_system(name)
    options = system.options_type() if options is None else options
    faults = parse_fault_specs(list(faults)) if faults and isinstance(next(iter(faults)), str) else tuple(faults)
    targets = system.targets(options)
    for f in faults:
        try:
            fault_limit(targets, f.kind, f.target)
        except RobofdiError as exc:
            raise RobofdiError(f"--fault {f.name!r}: {exc}") from None
    key = system.calibration_keys(options)[0]
    diagnosers = tuple(getattr(system, "default_diagnosers", system.diagnosers)(options))   # opt-in ones only by name
    label = name.rsplit(":", 1)[-1] if ":" in name else name
    run_dir = prepare_run_dir(out, label, seed)
    t0 = time.perf_counter()
    progress = Progress.of(progress, label)
    mission = system.mission(options, key, rng(seed, "mission"))
    check_faults(faults, duration=mission.duration, label="--fault")
    with progress.stage(f"calibration (robot {key})"):
        calibration, cached = system.calibrate(options, key, diagnosers)
    with keep_partial(run_dir), progress.stage(f"run: {mission.duration:g} s"):
        record = system.run(options, calibration, key, mission, faults, seed, diagnosers)
    summary = summarize(record, label, [f.to_dict() for f in faults], calibration_cached=cached,
                        mission=mission.description, wall_time=round(time.perf_counter() - t0, 3))
    with progress.stage("run folder: record, figures"):
        write_run_folder(run_dir, record, summary, replay=False)
    return summary, run_dir


OPTIONS = ("faults",)


def run(name: str, out: str | Path = "runs", seed: int = 0, progress: bool = True, faults=()) -> tuple[dict, Path]:
    """``robofdi run SYSTEM``: :func:`run_system`."""
    return run_system(name, out, seed, progress, faults)
