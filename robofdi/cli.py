"""`robofdi list | run NAME | demo | view RUN | figures RUN | diagnose LOG | campaign SPEC | cache` — the command line.

``run NAME``: an experiment (:func:`robofdi.experiments.experiments`: the shipped ones and those of installed
plug-ins), else a registered system (:mod:`robofdi.systems`, or ``package.module:attribute``) run once with the
given faults (:mod:`robofdi.experiments.system_run`).

Errors print one line ``robofdi: error: …`` and exit with code 2 (bad input, including a file or folder that
cannot be read or written) or 1 (a run that failed; what it had recorded is saved as ``partial.h5`` in the run
folder; also any unexpected failure, whose traceback ``ROBOFDI_TRACEBACK=1`` shows). SIGINT and SIGTERM stop any
command the same way (:mod:`robofdi.interrupts`): one line, exit code 130 or 143, a run in flight kept as
``partial.h5``.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path

from robofdi import RobofdiError, __version__
from robofdi.interrupts import exit_code, signal_of, stop_on_signals
from robofdi.faults.spec import PROFILE_HELP

# options of `robofdi run` that only some experiments take (module attribute OPTIONS lists them)
EXPERIMENT_OPTIONS = {"robot": "--robot", "faults": "--fault", "joints": "--joints", "torque_motors": "--torque-motors",
                      "drive_inertia": "--drive-inertia", "payload": "--payload", "nominal_payload": "--nominal-payload"}


def _experiments() -> dict[str, tuple[str, object]]:
    from robofdi.experiments import experiments

    return experiments()


def _cmd_list(args) -> int:
    from robofdi.systems import SYSTEMS, system_names

    found = _experiments()
    for name, (description, _) in found.items():
        print(f"{name:16s} {description}")
    others = [n for n in system_names() if n not in found]
    if others:
        print("\nsystems (robofdi run SYSTEM --fault SPEC; robofdi campaign SPEC):")
        for name in others:
            doc = " ".join((type(SYSTEMS[name]).__doc__ or "").split("\n\n")[0].split())
            print(f"{name:16s} {doc if len(doc) <= 110 else doc[:109] + '…'}")
    return 0


def _is_system(name: str) -> bool:
    from robofdi.systems import system_names

    return ":" in name or name in system_names()


def _cmd_run(args) -> int:
    from robofdi.evaluate.headline import run_report
    from robofdi.evaluate.run_folder import check_figures, figures_setting
    from robofdi.loop import RunAborted, RunInterrupted
    from robofdi.seeding import check_seed

    experiments = _experiments()
    check_seed("--seed", args.seed)
    check_figures("--figures", args.figures)
    if args.name in experiments:
        _, mod = experiments[args.name]
    elif _is_system(args.name):
        from robofdi.experiments import system_run as mod
    else:
        raise RobofdiError(f"unknown experiment or system {args.name!r}; expected one of {', '.join(experiments)}, "
                           "a system of `robofdi list` or 'package.module:attribute'")
    accepted = getattr(mod, "OPTIONS", ())
    options = {k: getattr(args, k) for k in EXPERIMENT_OPTIONS if getattr(args, k) not in (None, False, [])}
    refused = sorted(set(options) - set(accepted))
    if refused:
        flags = ", ".join(EXPERIMENT_OPTIONS[k] for k in refused)
        raise RobofdiError(f"{flags}: not an option of experiment {args.name!r} (only of: "
                           f"{', '.join(n for n, (_, m) in experiments.items() if getattr(m, 'OPTIONS', ()))})")
    if "joints" in options:
        options["joints"] = [j.strip() for j in options["joints"].split(",") if j.strip()]
        if not options["joints"]:
            raise RobofdiError(f"--joints: expected comma-separated joint names, got {args.joints!r}")
    try:
        with figures_setting(args.figures, "--figures"):
            summary, run_dir = mod.run(args.name, args.out, args.seed, progress=not args.quiet, **options)
    except RunInterrupted as exc:        # a calibration run, or a run whose partial record could not be saved
        where = f"recorded so far: {exc.partial_path}" if exc.partial_path else "nothing of it was saved"
        print(f"robofdi: {exc} ({where})", file=sys.stderr)
        return exit_code(exc)
    except RunAborted as exc:
        where = f"recorded so far: {exc.partial_path}" if exc.partial_path else "the partial record could not be saved"
        print(f"robofdi: error: {exc} ({where})", file=sys.stderr)
        return 1
    print(run_report(summary))
    _payload_note(summary)
    _armature_note(args.name, options)
    print(f"\nrun folder: {run_dir}  ({', '.join(sorted(p.name + '/' * p.is_dir() for p in run_dir.iterdir()))})")
    for replay in sorted(run_dir.glob("replay.html")) + sorted(run_dir.glob("*/replay.html")):   # ch6: per system
        record = replay.parent / "record.h5"
        view = f", or `robofdi view {record}`" if record.is_file() else ""
        print(f"3-D replay: open {replay} in a browser{view}")
    _figures_note(run_dir)
    return 0


def _payload_note(summary: dict) -> None:
    """One line when an arm run carried or declared a load, or its calibration identified one (summary["payload"])."""
    load = summary.get("payload")
    if load:
        print(f"\npayload: the plant carries {load['plant']:g} kg, the nominal model {load['declared']:g} kg (declared); "
              f"the consistency scheme's calibration identified {load['identified_beyond_declared']:+.3g} kg beyond it")


def _armature_note(name: str, options: dict) -> None:
    """One line when an arm run's file gives its joints no rotor inertia and ``--drive-inertia`` was not given."""
    if name != "arm" or options.get("drive_inertia") or "robot" not in options:
        return
    from robofdi.mjcf import compile_arm

    bare = compile_arm(options["robot"], options.get("joints"), bool(options.get("torque_motors"))).without_armature
    if bare:
        print(f"\nnote: {options['robot']} gives the arm joints {', '.join(bare)} no rotor inertia (armature), as if "
              f"their drives had no rotors; --drive-inertia 0.002 gives each 0.002 s² per N·m of its torque limit "
              f"(the shipped URDF arm's fast acceptance campaign: 89.5 % correct first isolation without, 97.8 % with; "
              f"docs/howto/own-arm.md)")


def _figures_note(run_dir: Path) -> None:
    """One line when the run folder's residual figures are not all drawn: how to draw the others."""
    from robofdi.evaluate.run_folder import residual_figures_left

    left = residual_figures_left(run_dir) if (run_dir / "figures").is_dir() else []
    if left:
        other = "other " if any((run_dir / "figures").glob("residuals_*.png")) else ""
        whose = f"{other}diagnoser's" if len(left) == 1 else f"{len(left)} {other}diagnosers'"
        print(f"figures: `robofdi figures {run_dir}` draws the {whose} residual figures ({', '.join(left)})")


def _cmd_figures(args) -> int:
    from robofdi.evaluate.run_folder import draw_figures

    if args.all and args.diagnosers:
        raise RobofdiError("--all and --diagnoser: give one (--all redraws every diagnoser's residual figure)")
    written = draw_figures(args.run, diagnosers=args.diagnosers or (), every=args.all, record=args.record)
    if not written:
        print(f"nothing to draw: every residual figure of {args.run} is in its figures folder (--all redraws them)")
    for path in written:
        print(path)
    return 0


def _cmd_cache(args) -> int:
    from robofdi import calibration

    if args.action == "clear":
        print(f"removed {calibration.clear()} cached calibrations from {calibration.cache_dir()}")
        return 0
    files = calibration.entries()
    size = sum(p.stat().st_size for p in files)
    print(f"{len(files)} cached calibrations, {size / 1e6:.1f} MB, in {calibration.cache_dir()} (ROBOFDI_CACHE)")
    for path in files:
        print(f"  {path.name}")
    return 0


def _cmd_view(args) -> int:
    path = Path(args.run)
    if path.is_dir():
        path = path / "record.h5"
    if not path.is_file():
        raise RobofdiError(f"RUN: no record at {str(path)!r}; expected a record .h5 file or a run folder holding record.h5")
    if args.rerun is not None:
        from robofdi.adapters import adapter

        rrd = adapter("robofdi.viz.rerun_export", "rerun").export_rrd(
            path, args.rerun or path.parent / "run.rrd", diagnoser=args.diagnoser)
        print(f"rerun recording: {rrd} (open it with: rerun {rrd})")
        return 0
    from robofdi.adapters import adapter

    adapter("robofdi.viz", "viz").view(path, diagnoser=args.diagnoser, open_browser=not args.no_browser)
    return 0


def _cmd_campaign(args) -> int:
    from robofdi.campaign import CampaignInterrupted, load_spec, run_campaign

    spec = load_spec(args.spec)
    out = Path(args.out) if args.out else Path("runs") / f"campaign-{Path(spec.source).stem or spec.system}"
    try:
        result = run_campaign(spec, out, workers=args.workers, scheduler=args.scheduler, resume=args.resume,
                              runs=args.runs, progress=not args.quiet, batch=args.batch)
    except CampaignInterrupted as exc:
        print(f"robofdi: {exc}", file=sys.stderr)
        return exit_code(exc.signum)
    summary = result.summary
    print((out / "report.md").read_text().split("\n## ", 1)[0].rstrip())
    print(f"\ncampaign folder: {out}  (results.parquet, campaign.json, report.md, figures/)")
    return 1 if summary["runs"]["errors"] else 0


def _segment(text: str) -> tuple[float, float]:
    t0, sep, t1 = str(text).partition(":")
    try:
        if not sep:
            raise ValueError
        return float(t0), float(t1)
    except ValueError:
        raise RobofdiError(f"--fault-free: {text!r} is not T0:T1 (seconds from the log's start)") from None


def _cmd_diagnose(args) -> int:
    import json

    from robofdi.evaluate.run_folder import check_figures, keep_partial, write_run_folder
    from robofdi.logs import LOG_SCHEMES, diagnose_log, print_table

    check_figures("--figures", args.figures)
    columns = args.columns
    if columns and columns.endswith(".json"):
        try:
            loaded = json.loads(Path(columns).read_text())
        except (OSError, ValueError) as exc:
            raise RobofdiError(f"--columns: cannot read the JSON file {columns!r} ({exc})") from None
        columns = loaded.get("columns", loaded) if isinstance(loaded, dict) else None
        if not isinstance(columns, dict):
            raise RobofdiError(f"--columns: {args.columns!r} holds no mapping of log names to robofdi names")
    schemes = tuple(s.strip() for s in args.diagnosers.split(",") if s.strip()) if args.diagnosers else LOG_SCHEMES
    joints = [j.strip() for j in args.joints.split(",") if j.strip()] if args.joints else None
    record, summary = diagnose_log(args.log, args.robot, _segment(args.fault_free), columns=columns, rate=args.rate,
                                   schemes=schemes, margin=args.margin, joints=joints,
                                   torque_motors=args.torque_motors, drive_inertia=args.drive_inertia or 0.0,
                                   topics=args.topics)
    run_dir = Path(args.out) / f"diagnose-{Path(args.log).name.split('.')[0]}"
    run_dir.mkdir(parents=True, exist_ok=True)
    with keep_partial(run_dir):
        write_run_folder(run_dir, record, summary, replay=not args.no_replay, figures=args.figures)
    print(print_table(summary))
    log = summary["log"]
    print(f"\nlog: {log['rows']} rows at {log['rate_hz']:g} Hz ({log['dropouts']} dropouts, longest "
          f"{1e3 * log['longest_gap_s']:.1f} ms; jitter {1e6 * log['jitter_s']:.0f} µs)\nrun folder: {run_dir}")
    _figures_note(run_dir)
    return 0


#: which generic figures a run folder draws (robofdi.evaluate.run_folder.FIGURE_CHOICES)
FIGURES_HELP = ("lead (default): the lead diagnoser's residual figure and the estimates; all: every diagnoser's; "
                "none: neither (an experiment's own figures are always drawn); `robofdi figures RUN` draws the others "
                "later")

#: progress: bars on a terminal, a few lines in a pipe or log (robofdi.progress; ROBOFDI_PROGRESS=bar|plain|off)
QUIET_HELP = "no progress output (otherwise: a bar per stage on a terminal, a few lines in a pipe or a log)"


class _Parser(argparse.ArgumentParser):
    """argparse, with its usage errors on one line like every other error of the command line."""

    def error(self, message):
        self.exit(2, f"robofdi: error: {message} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="robofdi", description="Model-based fault diagnosis and fault-tolerant control of simulated robots."
    )
    p.add_argument("--version", action="version", version=f"robofdi {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the experiments").set_defaults(func=_cmd_list)
    run = sub.add_parser("run", help="run one experiment, or one run of a system")
    run.add_argument("name", help="an experiment or a system of `robofdi list`, or 'package.module:attribute'")
    run.add_argument("--out", default="runs", help="parent folder of the run folder (default: ./runs)")
    run.add_argument("--seed", type=int, default=0, help="the run's seed: the same seed gives the same results (default: 0)")
    run.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    run.add_argument("--figures", default="lead", metavar="{lead,all,none}", help=FIGURES_HELP)
    arm = run.add_argument_group("options of `run arm` (--fault also of `run robosuite-lift` and of systems)")
    arm.add_argument("--robot", help="the arm's MJCF or URDF file (default: the shipped arm6.xml)")
    arm.add_argument("--fault", dest="faults", action="append", metavar="SPEC",
                     help="KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE], repeatable; PROFILE: "
                          f"{PROFILE_HELP}; e.g. actuator_additive:joint2:20@1.0 or "
                          "actuator_additive:joint5:40@3~exponential_rise(0.08)")
    arm.add_argument("--joints", help="comma-separated arm joints (default: every joint driven by a motor)")
    arm.add_argument("--torque-motors", action="store_true",
                     help="replace the arm's position/velocity servos by torque motors (limit: their forcerange)")
    arm.add_argument("--drive-inertia", type=float, metavar="S2",
                     help="rotor inertia floor per N·m of torque limit [s²] for files without armature (e.g. 0.002)")
    arm.add_argument("--payload", type=float, metavar="KG",
                     help="a load the simulated arm carries at its payload point [kg] (the truth; default 0)")
    arm.add_argument("--nominal-payload", type=float, metavar="KG",
                     help="the load you declare to the diagnosers [kg]: the nominal model carries it, motions are "
                          "planned with it (default 0: the robot file's model)")
    run.set_defaults(func=_cmd_run)
    demo = sub.add_parser("demo", help="the chapter-3 actuator-fault experiment (= run ch3-actuator)")
    demo.add_argument("--out", default="runs")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    demo.add_argument("--figures", default="lead", metavar="{lead,all,none}", help=FIGURES_HELP)
    demo.set_defaults(func=_cmd_run, name="ch3-actuator", **dict.fromkeys(EXPERIMENT_OPTIONS))
    cache = sub.add_parser("cache", help="the calibration cache: list it, or clear it")
    cache.add_argument("action", nargs="?", choices=("list", "clear"), default="list")
    cache.set_defaults(func=_cmd_cache)
    view = sub.add_parser("view", help="open a recorded run in the live Meshcat viewer")
    view.add_argument("run", help="a record .h5 file or a run folder")
    view.add_argument("--diagnoser", default=None,
                      help="whose detections light up the joints (default: the run's lead diagnoser, as in the table)")
    view.add_argument("--no-browser", action="store_true")
    view.add_argument("--rerun", nargs="?", const="", default=None, metavar="RRD",
                      help="write the run as a rerun recording instead (default RUN/run.rrd; needs robofdi[rerun])")
    view.set_defaults(func=_cmd_view)
    figs = sub.add_parser("figures", help="draw a run folder's residual figures from its records (those a run left out)")
    figs.add_argument("run", metavar="RUN", help="a run folder (or one of its .h5 records)")
    figs.add_argument("--diagnoser", dest="diagnosers", action="append", metavar="NAME",
                      help="draw (or redraw) this diagnoser's residual figure; repeatable (default: every one not drawn "
                           "yet, and the estimates if missing)")
    figs.add_argument("--all", action="store_true", help="redraw every diagnoser's residual figure and the estimates")
    figs.add_argument("--record", default="record", metavar="NAME",
                      help="which record of the folder: record (default: the scored run, figures into RUN/figures/) "
                           "or another run, e.g. compensated or fault_free (figures into RUN/figures/NAME/)")
    figs.set_defaults(func=_cmd_figures)
    diag = sub.add_parser("diagnose", help="diagnose a real robot's log (CSV, Parquet or ROS 2 bag of q, q̇, commanded τ)")
    diag.add_argument("log", metavar="LOG", help="a .csv, .csv.gz or .parquet file: time [s], <joint>_q [rad], "
                                                 "<joint>_qd [rad/s], <joint>_tau [N·m] (see --columns); or a ROS 2 "
                                                 "bag (.mcap) of sensor_msgs/JointState (see --topics)")
    diag.add_argument("--robot", required=True, metavar="FILE", help="the robot's MJCF or URDF (the nominal model)")
    diag.add_argument("--fault-free", required=True, metavar="T0:T1",
                      help="a segment of the log [s] known to be fault-free: the thresholds are calibrated on it")
    diag.add_argument("--columns", metavar="MAP", help="LOG_NAME=NAME,... or a JSON file with such a mapping")
    diag.add_argument("--topics", metavar="STATE[,COMMAND]",
                      help="a bag's JointState topics: positions and velocities, and the commanded torques as effort "
                           "(default: /joint_states, its own effort; needs robofdi[mcap])")
    diag.add_argument("--rate", type=float, metavar="HZ", help="resample to this rate (default: the log's median)")
    diag.add_argument("--diagnosers", metavar="A,B", help="default: momentum,recursive,simple,time_delayed,position_only")
    diag.add_argument("--margin", type=float, default=1.2, help="threshold = margin × the segment's max |r| (1.2)")
    diag.add_argument("--joints", metavar="J1,J2,...", help="the arm joints (default: every motor-driven joint)")
    diag.add_argument("--torque-motors", action="store_true", help="as for robofdi run arm")
    diag.add_argument("--drive-inertia", type=float, metavar="S2", help="as for robofdi run arm")
    diag.add_argument("--figures", default="lead", metavar="{lead,all,none}", help=FIGURES_HELP)
    diag.add_argument("--out", default="runs", metavar="DIR")
    diag.add_argument("--no-replay", action="store_true", help="no Meshcat replay of the logged motion")
    diag.set_defaults(func=_cmd_diagnose)
    camp = sub.add_parser("campaign", help="many seeded fault scenarios, locally or on a Dask cluster")
    camp.add_argument("spec", metavar="SPEC",
                      help="a campaign TOML file, or a shipped one by name (arm, auv, flight-surrogate, helicopter, hydraulic, "
                           "linear, robosuite-lift, dm_control-cartpole)")
    camp.add_argument("--workers", type=int, default=None, help="local worker processes (default: the core count)")
    camp.add_argument("--scheduler", metavar="ADDRESS", help="run on the Dask scheduler at ADDRESS (tcp://HOST:8786)")
    camp.add_argument("--out", metavar="DIR", help="campaign folder (default: runs/campaign-<spec name>)")
    camp.add_argument("--resume", action="store_true", help="continue the campaign in DIR, skipping finished runs")
    camp.add_argument("--runs", type=int, metavar="N", help="only the first N runs by index (a prefix of the campaign)")
    camp.add_argument("--batch", type=int, metavar="N",
                      help="runs a worker diagnoses in lockstep (default: automatic, at most 32; 1: each run alone); the "
                           "results are the same")
    camp.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    camp.set_defaults(func=_cmd_campaign)
    return p


def _os_error(exc: OSError) -> str:
    """One line: the path(s) and the operating system's reason."""
    if exc.filename is None:
        return " ".join(str(exc).split())
    paths = repr(os.fsdecode(exc.filename))
    if exc.filename2 is not None:
        paths += f" -> {os.fsdecode(exc.filename2)!r}"
    return f"{paths}: {exc.strerror or type(exc).__name__}"


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    with stop_on_signals() as received:
        code = _main(args)
        if received.signum is not None and code in (0, 1):     # the signal's exception was swallowed somewhere
            print(f"robofdi: interrupted by {signal.Signals(received.signum).name}", file=sys.stderr)
            code = exit_code(received.signum)
    return code


def _main(args) -> int:
    try:
        return args.func(args)
    except RobofdiError as exc:
        print(f"robofdi: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"robofdi: error: {_os_error(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:        # SIGINT or SIGTERM outside a run (calibration, saving): nothing half-written
        print(f"robofdi: interrupted by {signal.Signals(signal_of(exc)).name}", file=sys.stderr)
        return exit_code(exc)
    except Exception as exc:
        if os.environ.get("ROBOFDI_TRACEBACK"):
            raise
        message = " ".join(str(exc).split())
        print(f"robofdi: error: unexpected {type(exc).__name__}: {message} (ROBOFDI_TRACEBACK=1 shows the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
