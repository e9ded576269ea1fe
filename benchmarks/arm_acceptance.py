"""Issue 24's acceptance campaigns: benchmarks/arm_acceptance.toml on the shipped arms and robosuite's arms.

    python benchmarks/arm_acceptance.py [--robots arm6.xml arm7.xml panda] [--speed fast] [--workers 2]
                                        [--out runs/arm-acceptance] [--runs N] [--seed S] [--set NAME=VALUE …]
                                        [--spec benchmarks/arm_more_kinds.toml]

A robot is a shipped asset name, an MJCF or URDF path, or the name of a robosuite 1.5 arm (``panda``, ``iiwa``,
``ur5e``, ``kinova3``, ``jaco``, ``sawyer``, ``spot_arm``: its raw ``robot.xml``, servos turned into torque motors;
needs the robosuite extra).
--speed sets the missions' speed ("fast", "normal", "slow" or a duration factor >= 1, as ArmMissions' speed;
fast missions get three segments, the others two; ``--set segments=N`` chooses).
--drive-inertia S2 gives every joint whose armature is below S2 × its torque limit that armature, in the plant and
the belief alike (:func:`robofdi.mjcf.compile_arm`): the reflected rotor inertia of a geared drive, which
robosuite's raw robot.xml files leave out (robosuite's own loader adds 5/(i+1) kg·m² to every joint instead).
The default, "auto", is 0.002 s² (the smallest of robofdi's own drives) for a file that gives none of its arm joints
any armature (robosuite's raw files, a URDF: the links without their drives) and 0 for the other files (their
armature as written); 0 runs such a file as it is.
Each (robot, speed) campaign is resumable: re-running the command continues it. Per diagnoser it prints the
table of benchmarks/arm_quality.py (false-alarm runs with the 95 % Clopper–Pearson upper bound, detection and
correct isolation at ≥ 2× the minimum detectable fault, the median abrupt delay in samples, incipient faults
detected) plus correct isolation at any time after detection ("eventually correct") and the median time to
a correct isolation, then the consistency scheme by fault class. --spec runs another campaign TOML the same way
(benchmarks/arm_more_kinds.toml: the fault kinds the acceptance mix lacks, faulty runs only).
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

try:
    import tomllib
except ModuleNotFoundError:        # Python 3.10
    import tomli as tomllib

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from arm_quality import SAMPLE, per_class, per_class_at_equal_false_alarms, quality, settings_option  # noqa: E402

from robofdi.campaign import run_campaign  # noqa: E402
from robofdi.campaign.results import load  # noqa: E402
from robofdi.control.motions import SPEEDS  # noqa: E402
from robofdi.mjcf import compile_arm  # noqa: E402

ROBOSUITE_ARMS = ("panda", "iiwa", "ur5e", "kinova3", "jaco", "sawyer", "spot_arm")


#: The drive inertia [s²] "auto" gives a file whose arm joints have no armature (--drive-inertia).
LINKS_ONLY_DRIVE_INERTIA = 0.002


def robot_file(name: str) -> tuple[str, bool]:
    """(MJCF path or asset name, torque_motors) of ``name``: a robosuite arm's raw robot.xml, else the name."""
    if name in ROBOSUITE_ARMS:
        spec = importlib.util.find_spec("robosuite")
        if spec is None or not spec.submodule_search_locations:
            raise SystemExit(f"--robots {name}: robosuite is not installed (pip install -e '.[robosuite]')")
        path = Path(spec.submodule_search_locations[0]) / "models" / "assets" / "robots" / name / "robot.xml"
        return str(path), True
    return name, False


def drive_inertia(option: str, name: str) -> float:
    """The --drive-inertia of robot ``name`` [s²]: "auto" (module docstring) or a number >= 0."""
    if option == "auto":
        path, torque_motors = robot_file(name)
        arm = compile_arm(path, torque_motors=torque_motors)
        links_only = not np.any(arm.model.dof_armature[[d.dof for d in arm.drives]])
        return LINKS_ONLY_DRIVE_INERTIA if links_only else 0.0
    try:
        value = float(option)
    except ValueError:
        value = float("nan")
    if not value >= 0:
        raise SystemExit(f'--drive-inertia: expected "auto" or an armature per unit torque limit >= 0 s², '
                         f"got {option!r}")
    return value


def mission_speed(text: str) -> str | float:
    """--speed: a name of :data:`robofdi.control.motions.SPEEDS` or a duration factor >= 1 (ArmMissions' speed)."""
    if text in SPEEDS:
        return text
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value >= 1:
        raise argparse.ArgumentTypeError(f"must be one of {sorted(SPEEDS)} or a number >= 1, got {text!r}")
    return value


def acceptance_spec(name: str, speed: str | float, inertia: str = "auto", seed: int | None = None,
                    diagnosers=None, system: dict | None = None, path: str | Path | None = None) -> dict:
    """benchmarks/arm_acceptance.toml (or the campaign TOML at ``path``) for robot ``name`` at ``speed`` (fast
    missions get three segments, the others two), with its --drive-inertia option, and optionally another seed,
    diagnosers or more [system] fields (``system``, e.g. from :func:`settings_option`)."""
    spec = tomllib.loads(Path(path or HERE / "arm_acceptance.toml").read_text())
    if seed is not None:
        spec["seed"] = seed
    if diagnosers is not None:
        spec["diagnosers"] = list(diagnosers)
    spec["system"]["speed"] = speed
    spec["system"]["segments"] = 3 if speed == "fast" else 2
    spec["system"].update(system or {})      # --set segments=N wins over the speed's default
    spec["system"]["robot"], spec["system"]["torque_motors"] = robot_file(name)
    value = drive_inertia(inertia, name)
    if value:           # else the file's armature as written (and the campaign's options as before the flag)
        spec["system"]["drive_inertia"] = value
    return spec


def eventually(table: pd.DataFrame) -> pd.DataFrame:
    """Per diagnoser: faulty runs detected, correct at first isolation, correct at any time, and the median time
    from onset to the first correct isolation [ms]."""
    faulty = table[table["faulty"] & table["error"].isna()]
    rows = []
    for name, f in faulty.groupby("diagnoser", sort=False):
        detected = f["detected"].fillna(False).astype(bool)
        later = f["time_to_correct_isolation"].notna()
        rows.append({"diagnoser": name, "detected": f"{int(detected.sum())}/{len(f)}",
                     "correct first": int(f["correct"].fillna(False).astype(bool).sum()),
                     "eventually correct": int(later.sum()),
                     "median time to correct isolation [ms]":
                         f"{1e3 * np.median(f.loc[later, 'time_to_correct_isolation']):.0f}" if later.any() else "-"})
    return pd.DataFrame(rows).set_index("diagnoser")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default=str(HERE / "arm_acceptance.toml"),
                    help="the campaign TOML (default: arm_acceptance.toml; arm_more_kinds.toml: fault kinds it lacks)")
    ap.add_argument("--robots", nargs="+", default=["arm6.xml", "arm7.xml"])
    ap.add_argument("--speed", type=mission_speed, default="fast",
                    help='"fast", "normal", "slow" or a duration factor >= 1 (default: fast)')
    ap.add_argument("--drive-inertia", default="auto",
                    help='armature per unit torque limit [s²], or "auto" (module docstring)')
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", default="runs/arm-acceptance")
    ap.add_argument("--runs", type=int, default=None, help="only the first N runs (a prefix of the campaign)")
    ap.add_argument("--seed", type=int, default=None, help="campaign seed (default: the TOML's)")
    ap.add_argument("--set", nargs="+", default=None, metavar="NAME=VALUE",
                    help="more [system] fields, e.g. consistency_tail=exponential consistency_calibration_motions=24")
    args = ap.parse_args()
    for name in args.robots:
        spec = acceptance_spec(name, args.speed, args.drive_inertia, args.seed, system=settings_option(args.set),
                               path=args.spec)
        inertia = spec["system"].get("drive_inertia", 0.0)
        out = Path(args.out) / f"{Path(name).stem}-{args.speed}"
        t0 = time.perf_counter()
        run_campaign(spec, out, workers=args.workers, resume=(out / "runs.jsonl").is_file(), runs=args.runs,
                     progress=True)
        table = load(out).table
        print(f"\n## {name}, {args.speed}, drive inertia {inertia} s²: "
              f"{table['index'].nunique()} runs, {time.perf_counter() - t0:.0f} s wall")
        diagnosis_hz = spec["system"].get("diagnosis_hz")
        print(quality(table, 1.0 / diagnosis_hz if diagnosis_hz else SAMPLE).to_string())
        print(eventually(table).to_string())
        if "consistency" in spec["diagnosers"]:
            print("\nconsistency by fault class:")
            print(per_class(table, "consistency").to_string())
        equal = per_class_at_equal_false_alarms(table)
        if equal is not None:
            print("\nby fault class at equal false alarms (detected/faults; ×: the thresholds' scale):")
            print(equal.to_string())


if __name__ == "__main__":
    main()
