"""`robofdi list | run NAME | demo | view RUN | campaign SPEC` — the command line.

Errors print one line ``robofdi: error: …`` and exit with code 2 (bad input, including a file or folder that
cannot be read or written) or 1 (a run that failed; what it had recorded is saved as ``partial.h5`` in the run
folder; also any unexpected failure, whose traceback ``ROBOFDI_TRACEBACK=1`` shows).
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from robofdi import RobofdiError, __version__

# experiment name → module of robofdi.experiments (the repository's experiments/); each module has
# EXPERIMENTS {name: description} and run().
MODULES = ("robofdi.experiments.ch3_industrial_robot", "robofdi.experiments.arm", "robofdi.experiments.ch4_auv",
           "robofdi.experiments.ch6_hydraulic", "robofdi.experiments.jiang2005", "robofdi.experiments.guo2008",
           "robofdi.experiments.ch2_wang", "robofdi.experiments.adaptive_fe", "robofdi.experiments.robosuite_lift")
# options of `robofdi run` that only some experiments take (module attribute OPTIONS lists them)
EXPERIMENT_OPTIONS = {"robot": "--robot", "faults": "--fault", "joints": "--joints", "torque_motors": "--torque-motors"}


def _experiments() -> dict[str, tuple[str, object]]:
    found = {}
    for mod_name in MODULES:
        mod = importlib.import_module(mod_name)
        for name, description in mod.EXPERIMENTS.items():
            found[name] = (description, mod)
    return found


def _cmd_list(args) -> int:
    for name, (description, _) in _experiments().items():
        print(f"{name:16s} {description}")
    return 0


def _cmd_run(args) -> int:
    from robofdi.evaluate import results_table
    from robofdi.loop import RunAborted

    experiments = _experiments()
    if args.name not in experiments:
        raise RobofdiError(f"unknown experiment {args.name!r}; expected one of {', '.join(experiments)} (see `robofdi list`)")
    if args.seed < 0:
        raise RobofdiError(f"--seed must be an integer >= 0, got {args.seed}")
    _, mod = experiments[args.name]
    accepted = getattr(mod, "OPTIONS", ())
    options = {k: getattr(args, k) for k in EXPERIMENT_OPTIONS if getattr(args, k) not in (None, False, [])}
    refused = sorted(set(options) - set(accepted))
    if refused:
        flags = ", ".join(EXPERIMENT_OPTIONS[k] for k in refused)
        raise RobofdiError(f"{flags}: not an option of experiment {args.name!r} (only of: "
                           f"{', '.join(n for n, (_, m) in experiments.items() if getattr(m, 'OPTIONS', ()))})")
    if "joints" in options:
        options["joints"] = [j.strip() for j in options["joints"].split(",") if j.strip()]
    try:
        summary, run_dir = mod.run(args.name, args.out, args.seed, progress=not args.quiet, **options)
    except RunAborted as exc:
        where = f"recorded so far: {exc.partial_path}" if exc.partial_path else "the partial record could not be saved"
        print(f"robofdi: error: {exc} ({where})", file=sys.stderr)
        return 1
    print(results_table(summary))
    for check in summary.get("reproduction", []):
        print(f"  [{'pass' if check['pass'] else 'FAIL'}] {check['quantity']}")
    print(f"\nrun folder: {run_dir}  ({', '.join(sorted(p.name + '/' * p.is_dir() for p in run_dir.iterdir()))})")
    for replay in sorted(run_dir.glob("replay.html")) + sorted(run_dir.glob("*/replay.html")):   # ch6: per system
        record = replay.parent / "record.h5"
        view = f", or `robofdi view {record}`" if record.is_file() else ""
        print(f"3-D replay: open {replay} in a browser{view}")
    return 0


def _cmd_view(args) -> int:
    path = Path(args.run)
    if path.is_dir():
        path = path / "record.h5"
    if not path.is_file():
        raise RobofdiError(f"RUN: no record at {str(path)!r}; expected a record .h5 file or a run folder holding record.h5")
    from robofdi.viz import view

    view(path, diagnoser=args.diagnoser, open_browser=not args.no_browser)
    return 0


def _cmd_campaign(args) -> int:
    from robofdi.campaign import CampaignInterrupted, load_spec, run_campaign

    spec = load_spec(args.spec)
    out = Path(args.out) if args.out else Path("runs") / f"campaign-{Path(spec.source).stem or spec.system}"
    try:
        result = run_campaign(spec, out, workers=args.workers, scheduler=args.scheduler, resume=args.resume,
                              runs=args.runs, progress=not args.quiet)
    except CampaignInterrupted as exc:
        print(f"robofdi: {exc}", file=sys.stderr)
        return 143
    summary = result.summary
    print((out / "report.md").read_text().split("\n## ", 1)[0].rstrip())
    print(f"\ncampaign folder: {out}  (results.parquet, campaign.json, report.md, figures/)")
    return 1 if summary["runs"]["errors"] else 0


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
    run = sub.add_parser("run", help="run one experiment")
    run.add_argument("name")
    run.add_argument("--out", default="runs", help="parent folder of the run folder (default: ./runs)")
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    arm = run.add_argument_group("options of `run arm` (--fault also of `run robosuite-lift`)")
    arm.add_argument("--robot", help="the arm's MJCF or URDF file (default: the shipped arm6.xml)")
    arm.add_argument("--fault", dest="faults", action="append", metavar="SPEC",
                     help="KIND:TARGET:MAGNITUDE@ONSET[-END][~PROFILE][;NAME=VALUE], repeatable, "
                          "e.g. actuator_additive:joint2:20@1.0 or sensor_bias:joint3_pos:0.004@1.5~ramp(0.5)")
    arm.add_argument("--joints", help="comma-separated arm joints (default: every joint driven by a motor)")
    arm.add_argument("--torque-motors", action="store_true",
                     help="replace the arm's position/velocity servos by torque motors (limit: their forcerange)")
    run.set_defaults(func=_cmd_run)
    demo = sub.add_parser("demo", help="the chapter-3 actuator-fault experiment (= run ch3-actuator)")
    demo.add_argument("--out", default="runs")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--quiet", action="store_true")
    demo.set_defaults(func=_cmd_run, name="ch3-actuator", **dict.fromkeys(EXPERIMENT_OPTIONS))
    view = sub.add_parser("view", help="open a recorded run in the live Meshcat viewer")
    view.add_argument("run", help="a record .h5 file or a run folder")
    view.add_argument("--diagnoser", default=None, help="whose detections light up the joints (default: adaptive)")
    view.add_argument("--no-browser", action="store_true")
    view.set_defaults(func=_cmd_view)
    camp = sub.add_parser("campaign", help="many seeded fault scenarios, locally or on a Dask cluster")
    camp.add_argument("spec", metavar="SPEC",
                      help="a campaign TOML file, or a shipped one by name (arm, auv, helicopter, hydraulic, linear, "
                           "robosuite-lift, dm_control-cartpole)")
    camp.add_argument("--workers", type=int, default=None, help="local worker processes (default: the core count)")
    camp.add_argument("--scheduler", metavar="ADDRESS", help="run on the Dask scheduler at ADDRESS (tcp://HOST:8786)")
    camp.add_argument("--out", metavar="DIR", help="campaign folder (default: runs/campaign-<spec name>)")
    camp.add_argument("--resume", action="store_true", help="continue the campaign in DIR, skipping finished runs")
    camp.add_argument("--runs", type=int, metavar="N", help="only the first N runs by index (a prefix of the campaign)")
    camp.add_argument("--quiet", action="store_true", help="no progress bar")
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
    try:
        return args.func(args)
    except RobofdiError as exc:
        print(f"robofdi: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"robofdi: error: {_os_error(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("robofdi: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if os.environ.get("ROBOFDI_TRACEBACK"):
            raise
        message = " ".join(str(exc).split())
        print(f"robofdi: error: unexpected {type(exc).__name__}: {message} (ROBOFDI_TRACEBACK=1 shows the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
