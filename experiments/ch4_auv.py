"""Book chapter 4 (Antonelli, "A Survey of Fault Detection/Tolerance Strategies for AUVs and ROVs"): the ODIN
experiments on an ODIN-like 8-thruster AUV in MuJoCo.

    robofdi run ch4-auv          [--seed N] [--out DIR]
    robofdi run ch4-flooded      [--seed N] [--out DIR]
    robofdi run ch4-depth-sensor [--seed N] [--out DIR]
    robofdi run ch4-roby2        [--seed N] [--out DIR]

ch4-auv (Sec. 6, Figs. 10–11): a 6-DOF square/depth/yaw task in an ocean current; thruster 2 (horizontal) and
thruster 6 (vertical) are switched off by zeroing their drive voltage, as ODIN's were at 260 s and 300 s. The
timeline is shortened to 120 s with the same order and onset ratio (78 s and 90 s = 0.3 × 260 s and 0.3 × 300 s).
Four runs with the same noise: fault-free; no accommodation; allocation with the true health (the oracle bound);
allocation with the health diagnosed by the Hall-voltage residual (the real thing). summary.json["tracking"]
holds the position RMS after the second failure of each.

ch4-flooded (Romeo, Sec. 6 and Fig. 8): a flooded thruster and, later, a rotor failure on another; the current
map detects both and its region map tells them apart (summary.json["regions"]).

ch4-roby2 (Roby 2 [2, 3], Sec. 4): a two-horizontal-thruster vehicle (assets/roby2.xml); the left thruster's drive
is zeroed mid-mission and the bank of EKFs (nominal, left off, right off) isolates it by the windowed NIS
(summary.json["ekf_bank"], figures/nis_bank.png), then a 600 s fault-free run checks the nominal filter for false
alarms at the χ² 99 % level.

ch4-depth-sensor (ODIN [48], Fig. 7): the pressure depth reading is zeroed; pressure, sonar (over a sea floor of
known depth) and an ARX virtual sensor vote, and the faulty sensor is switched out after 1 s while depth control
goes on (summary.json["depth_switch"]).
"""
from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from robofdi.errors import RobofdiError
from robofdi.evaluate.figures import save_figure
from robofdi.evaluate import summarize
from robofdi.evaluate.headline import recovery_section
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, write_run_folder
from robofdi.faults import Fault
from robofdi.ftc.allocation import capability
from robofdi.progress import Progress, run_ticks
from robofdi.record import Record
from robofdi.systems.auv import (
    AuvCalibration, AuvScenario, calibration, check_scenario, current_map_regions, depth_switch_time,
    run_scenario, tracking_rms,
)

EXPERIMENTS = {
    "ch4-auv": "ODIN-like AUV, thrusters 2 and 6 off (Figs. 10-11): no FTC vs oracle vs diagnosed-health allocation",
    "ch4-flooded": "Romeo-like flooded thruster then a rotor failure: current map detects both, regions tell them apart",
    "ch4-depth-sensor": "ODIN depth-sensor zeroing: pressure/sonar/ARX vote, faulty sensor switched out after 1 s",
    "ch4-roby2": "Roby-2-like vehicle, one of two horizontal thrusters off: the EKF bank's NIS isolates it",
}

#: ODIN's switch-off times [s] and the factor of our shortened timeline.
ODIN_ONSETS, TIME_SCALE = (260.0, 300.0), 0.3


def ch4_auv_scenario(seed: int = 0) -> AuvScenario:
    """The ch4-auv configuration: ODIN task of 120 s, thruster2_off and thruster6_off (drive voltage zeroed)."""
    t2, t6 = (round(TIME_SCALE * t, 6) for t in ODIN_ONSETS)
    faults = (Fault("thruster2_off", "actuator_float", "thruster2", onset=t2),
              Fault("thruster6_off", "actuator_float", "thruster6", onset=t6))
    return AuvScenario(name="ch4-auv", duration=120.0, seed=seed, faults=faults)


def ch4_flooded_scenario(seed: int = 0) -> AuvScenario:
    """Flooding (κ = 0.3) on thruster 3 at 30 s, rotor failure on thruster 1 at 70 s; no accommodation, so both
    thrusters stay commanded and visible to the current map."""
    faults = (Fault("thruster3_flooded", "component_thruster_flooding", "thruster3", onset=30.0, magnitude=0.3),
              Fault("thruster1_off", "actuator_float", "thruster1", onset=70.0))
    return AuvScenario(name="ch4-flooded", duration=100.0, seed=seed, faults=faults, variant="no_ftc")


def ch4_depth_sensor_scenario(seed: int = 0) -> AuvScenario:
    """Pressure depth zeroed at 30 s of a 60 s ODIN task; the depth vote switches to the sonar after 1 s."""
    return AuvScenario(name="ch4-depth-sensor", duration=60.0, seed=seed, variant="no_ftc", depth_redundancy=True,
                       diagnosers=("voltage_residual", "current_map", "force_observer", "depth_vote"),
                       faults=(Fault("depth_zero", "sensor_dropout", "depth", onset=30.0),))


def ch4_roby2_scenario(seed: int = 0, duration: float = 120.0, onset: float = 60.0) -> AuvScenario:
    """Roby-2-like vehicle (assets/roby2.xml): surge legs and turns on the spot in a 0.1 m/s head current; the left
    horizontal thruster's drive is zeroed at ``onset`` (mid-mission). No accommodation: with two horizontal
    thrusters, losing one leaves surge and yaw coupled (the chapter's Roby 2 experiments only diagnose)."""
    return AuvScenario(name="ch4-roby2", mjcf="roby2.xml", mission="roby2", duration=duration, seed=seed,
                       current=(0.10, 0.0, 0.0), variant="no_ftc", diagnosers=("ekf_bank", "voltage_residual"),
                       faults=(Fault("thruster_left_off", "actuator_float", "thruster_left", onset=onset),))


SCENARIOS = {"ch4-auv": ch4_auv_scenario, "ch4-flooded": ch4_flooded_scenario, "ch4-depth-sensor": ch4_depth_sensor_scenario,
             "ch4-roby2": ch4_roby2_scenario}


def _ticks(scenario: AuvScenario, duration: float | None = None) -> int:
    """Progress ticks of one run of ``duration`` (default: the scenario's) seconds."""
    return run_ticks(scenario.duration if duration is None else duration, 1.0 / scenario.control_dt)


def _calibration(name: str, sc: AuvScenario, progress: Progress) -> tuple[AuvCalibration, bool]:
    """:func:`calibration` as a progress stage (one line when it comes from the cache)."""
    replays = len([d for d in sc.diagnosers if d != "ekf_bank"])      # the EKF bank's bound is not fitted
    with progress.stage(f"calibration: {sc.calibration_runs} mission{'s' * (sc.calibration_runs != 1)}",
                        sc.calibration_runs * _ticks(sc, sc.calibration_duration) * (1 + replays),
                        skipped="from the cache") as tick:
        return calibration(sc, progress=tick)


def _write(progress: Progress, replay: bool, *args, **kwargs):
    """:func:`write_run_folder` as a progress stage."""
    with progress.stage("run folder: records, figures" + (", replay" if replay else "")):
        return write_run_folder(*args, replay=replay, **kwargs)


def voltage_detectability(record: Record, threshold: np.ndarray, window: float = 0.5) -> dict:
    """Per thruster fault: the commanded drive voltage [V] at onset against the Hall residual's threshold — a
    zeroed drive is only visible when |V_cmd| exceeds it (the survey's ODIN remark)."""
    from robofdi.models.auv import ODIN_THRUSTER

    out = {}
    names = record.columns["signals/u"]
    for f in record.meta.get("faults", []):
        if f["target"] not in names:
            continue
        i = names.index(f["target"])
        k = (record.time >= f["onset"]) & (record.time < f["onset"] + window)
        v = np.abs(ODIN_THRUSTER.voltage_for_thrust(record.signals["u_cmd"][k, i]))
        peak = float(v.max()) if v.size else 0.0
        out[f["name"]] = {"commanded_voltage": peak, "threshold": float(threshold[i]), "detectable": peak > threshold[i]}
    return out


def _save(fig, bottom_axes, path: Path) -> Path:
    """Time axis label on the bottom row, then :func:`save_figure`."""
    for ax in np.atleast_1d(bottom_axes):
        ax.set_xlabel("time [s]")
    return save_figure(fig, path)


def plot_thrusters(records: dict[str, Record], onsets, path: Path) -> Path:
    """Fig. 10 of the survey: thruster demands per group (vertical left, horizontal right), one row per variant."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(records), 2, figsize=(11, 2.3 * len(records)), sharex=True, squeeze=False)
    for row, (name, rec) in enumerate(records.items()):
        u, cols = rec.u_applied, rec.columns["truth/u_applied"]
        for col, group in ((0, range(4, 8)), (1, range(0, 4))):
            ax = axes[row, col]
            for i in group:
                ax.plot(rec.time, u[:, i], lw=0.7, label=cols[i])
            for t in onsets:
                ax.axvline(t, color="0.4", ls=":", lw=0.8)
            ax.set_ylabel(f"{name}\nthrust [N]", fontsize=8)
            ax.legend(fontsize=6, ncol=4, loc="upper left")
    axes[0, 0].set_title("vertical thrusters 5-8", fontsize=9)
    axes[0, 1].set_title("horizontal thrusters 1-4", fontsize=9)
    return _save(fig, axes[-1], path)


def plot_task_space(records: dict[str, Record], onsets, path: Path) -> Path:
    """Fig. 11 of the survey: task-space trajectories (left, with the reference dashed) and errors (right)."""
    import matplotlib.pyplot as plt

    labels, units = ("x", "y", "z"), ("m", "m", "m")
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    ref = next(iter(records.values()))
    for j in range(3):
        axes[j, 0].plot(ref.time, ref.signals["reference"][:, j], "k--", lw=0.8, label="reference")
        for name, rec in records.items():
            axes[j, 0].plot(rec.time, rec.truth_state[:, j], lw=0.8, label=name)
            axes[j, 1].plot(rec.time, rec.signals["reference"][:, j] - rec.truth_state[:, j], lw=0.8, label=name)
        axes[j, 0].set_ylabel(f"{labels[j]} [{units[j]}]")
        axes[j, 1].set_ylabel(f"{labels[j]} error [{units[j]}]")
        for ax in axes[j]:
            for t in onsets:
                ax.axvline(t, color="0.4", ls=":", lw=0.8)
    axes[0, 0].legend(fontsize=7, ncol=2)
    return _save(fig, axes[-1], path)


def _run_ch4_auv(name, run_dir, seed, progress, replay):
    sc = ch4_auv_scenario(seed)
    check_scenario(sc)
    cal, cached = _calibration(name, sc, progress)
    records, summaries = {}, {}
    with progress.stage("run: fault-free", _ticks(sc)) as tick:
        records["fault_free"] = run_scenario(replace(sc, faults=(), variant="no_ftc"), cal, progress=tick)
    for variant in ("no_ftc", "oracle", "diagnosed"):
        with progress.stage(f"run: {variant}", _ticks(sc)) as tick:
            records[variant] = run_scenario(replace(sc, variant=variant), cal, progress=tick)
        summaries[variant] = summarize(records[variant], sc.name)
    since = max(f.onset for f in sc.faults)
    rms = {k: tracking_rms(r, since) for k, r in records.items()}
    base = rms["fault_free"]
    tracking = {"fault_free_rms": base, "no_ftc_rms": rms["no_ftc"], "oracle_rms": rms["oracle"],
                "diagnosed_rms": rms["diagnosed"], "since": since,
                "ratio_to_fault_free": {k: rms[k] / base for k in ("no_ftc", "oracle", "diagnosed")},
                "units": {"fault_free_rms": "m", "no_ftc_rms": "m", "oracle_rms": "m", "diagnosed_rms": "m",
                          "since": "s", "ratio_to_fault_free": "1"}}
    main = records["diagnosed"]
    failed = np.ones(8)
    failed[[1, 5]] = 0.0
    from robofdi.models.auv import AuvModel

    B = AuvModel.from_mjcf(sc.mjcf, sc.mismatch).B
    summary = summarize(main, name, tracking=tracking,
                        variants={k: summaries[k]["diagnosers"] for k in ("no_ftc", "oracle")},
                        voltage_detectability=voltage_detectability(records["no_ftc"], cal.thresholds["voltage_residual"]),
                        allocation={"method": sc.allocation, "health_source": sc.health_source,
                                    "capability_healthy": capability(B, -sc.thrust_limit, sc.thrust_limit)[:, 1],
                                    "capability_after_2_6": capability(B, -sc.thrust_limit, sc.thrust_limit, failed)[:, 1],
                                    "max_abs_thrust": {k: float(np.abs(r.u_applied).max()) for k, r in records.items()},
                                    "units": {"capability": "N, N, N, N·m, N·m, N·m (X Y Z K M N)", "max_abs_thrust": "N"}},
                        scenario={"duration": sc.duration, "current": list(sc.current), "onsets": [f.onset for f in sc.faults],
                                  "odin_onsets": list(ODIN_ONSETS), "time_scale": TIME_SCALE,
                                  "sensors": asdict(sc.sensors), "mismatch": asdict(sc.mismatch)},
                        calibration_cached=cached)
    labels = {"fault_free": "fault-free", "no_ftc": "no accommodation", "oracle": "oracle allocation",
              "diagnosed": "diagnosed allocation"}
    summary["recovery"] = recovery_section(
        labels.values(), [{"quantity": f"position tracking RMS for t >= {since:g} s (last fault)", "unit": "m",
                           "values": {labels[k]: rms[k] for k in labels}},
                          {"quantity": "ratio to fault-free", "unit": "1",
                           "values": {labels[k]: rms[k] / base for k in labels}}],
        health_source=sc.health_source, method=f"reallocation ({sc.allocation}) around the isolated thrusters")
    with progress.stage("run folder: records, figures" + (", replay" if replay else "")):
        write_run_folder(run_dir, main, summary, {k: records[k] for k in ("fault_free", "no_ftc", "oracle")},
                         replay=False)
        onsets = [f.onset for f in sc.faults]
        variants = {k: records[k] for k in ("no_ftc", "oracle", "diagnosed")}
        plot_thrusters(variants, onsets, run_dir / "figures" / "fig10_thrusters.png")
        plot_task_space(variants, onsets, run_dir / "figures" / "fig11_task_space.png")
        if replay:
            from robofdi.viz import write_replay_html

            write_replay_html(main, run_dir / "replay.html", diagnoser=summary.get("lead", {}).get("diagnoser"))
    return summary


def _single_run(name: str, sc: AuvScenario, progress) -> tuple[Record, dict, bool]:
    """Check, calibrate (cached) and run one scenario: (record, summary, calibration came from the cache)."""
    check_scenario(sc)
    cal, cached = _calibration(name, sc, progress)
    with progress.stage("run", _ticks(sc)) as tick:
        record = run_scenario(sc, cal, progress=tick)
    return record, summarize(record, sc.name), cached


def _run_ch4_flooded(name, run_dir, seed, progress, replay):
    sc = ch4_flooded_scenario(seed)
    record, summary, cached = _single_run(name, sc, progress)
    regions = current_map_regions(record, sc.faults)
    summary["regions"] = regions
    summary["calibration_cached"] = cached
    _write(progress, replay, run_dir, record, summary)
    _plot_currents(record, sc, run_dir / "figures" / "fig8_currents.png")
    return summary


def _run_ch4_depth_sensor(name, run_dir, seed, progress, replay):
    sc = ch4_depth_sensor_scenario(seed)
    record, summary, cached = _single_run(name, sc, progress)
    onset = sc.faults[0].onset
    switch = depth_switch_time(record)
    depth_error = np.abs(record.truth_state[:, 2] - record.signals["reference"][:, 2])
    settle = [float(t) for t, e in zip(record.time, depth_error) if switch is not None and t > switch + 1.0 and e < 0.1]
    summary["depth_switch"] = {
        "onset": onset, "switch_time": switch, "switch_delay": None if switch is None else switch - onset,
        "max_depth_error_before_onset": float(depth_error[(record.time > sc.blanking) & (record.time < onset)].max()),
        "max_depth_error_after_onset": float(depth_error[record.time >= onset].max()),
        "depth_error_below_0.1m_from": settle[0] if settle else None,
        "final_depth_error": float(depth_error[-1]),
        "units": {"onset": "s", "switch_time": "s", "switch_delay": "s", "max_depth_error_before_onset": "m",
                  "max_depth_error_after_onset": "m", "depth_error_below_0.1m_from": "s", "final_depth_error": "m"}}
    summary["calibration_cached"] = cached
    _write(progress, replay, run_dir, record, summary)
    _plot_depth(record, sc, switch, run_dir / "figures" / "depth_switch.png")
    return summary


def ekf_bank_isolation(record: Record, faults, window: float) -> dict:
    """Per fault: when the EKF bank declared a hypothesis after onset, which, and whether within W + 1 s [s]; and the
    peak nominal NIS before the first onset against the χ² bound (false alarms)."""
    tr = record.diagnosers["ekf_bank"]
    first = min((f.onset for f in faults), default=float(record.time[-1]) + 1)
    before = (tr.time < first)
    out = {"bound": float(tr.threshold[0]), "window": window,
           "peak_nominal_nis_before_onset": float(tr.residual[before, 0].max()) if before.any() else None,
           "false_alarm_before_onset": bool(np.any(tr.alarm[before, 0])),
           "faults": {}, "units": {"bound": "1", "window": "s", "peak_nominal_nis_before_onset": "1",
                                   "time": "s", "delay": "s"}}
    for f in faults:
        hit = np.flatnonzero((tr.time >= f.onset) & np.array([bool(str(s)) for s in tr.isolated]))
        t = float(tr.time[hit[0]]) if hit.size else None
        declared = str(tr.isolated[hit[0]]) if hit.size else None
        delay = None if t is None else t - f.onset
        out["faults"][f.name] = {"target": f.target, "declared": declared, "time": t, "delay": delay,
                                 "correct_within_W_plus_1s": declared == f.target and delay is not None
                                 and delay <= window + 1.0}
    return out


def _plot_nis(record: Record, sc: AuvScenario, path: Path) -> Path:
    """NIS of every filter of the EKF bank over time (the survey's Roby 2 figure), χ² bound dashed."""
    import matplotlib.pyplot as plt

    tr = record.diagnosers["ekf_bank"]
    fig, ax = plt.subplots(figsize=(9, 3.4))
    for j, c in enumerate(tr.components):
        ax.semilogy(tr.time, tr.residual[:, j], lw=0.9, label=c.replace("nis_", "H: "))
    ax.axhline(tr.threshold[0], color="k", ls="--", lw=0.8, label="χ² 99 % bound")
    for f in sc.faults:
        ax.axvline(f.onset, color="0.4", ls=":", label=f"{f.name} onset")
    ax.set_ylim(bottom=0.5)                       # the first samples, before the window fills, are tiny
    ax.set_ylabel(f"windowed NIS (W = {sc.ekf_window:g} s) [1]")
    ax.legend(fontsize=7, ncol=3)
    return _save(fig, ax, path)


#: Length [s] of ch4-roby2's fault-free check of the EKF bank (digest acceptance 8).
FAULT_FREE_CHECK = 600.0


def _run_ch4_roby2(name, run_dir, seed, progress, replay):
    sc = ch4_roby2_scenario(seed)
    record, summary, cached = _single_run(name, sc, progress)
    cal, _ = calibration(sc)
    summary["ekf_bank"] = ekf_bank_isolation(record, sc.faults, sc.ekf_window)
    summary["ekf_bank"]["process_noise"] = cal.ekf_process_noise
    summary["ekf_bank"]["units"]["process_noise"] = "N²"
    with progress.stage(f"run: fault-free check, {FAULT_FREE_CHECK:g} s", _ticks(sc, FAULT_FREE_CHECK)) as tick:
        free = run_scenario(replace(sc, faults=(), duration=FAULT_FREE_CHECK), cal, progress=tick,
                               run_key="fault_free")
    tr = free.diagnosers["ekf_bank"]
    summary["ekf_bank"]["fault_free"] = {
        "duration": FAULT_FREE_CHECK, "peak_nominal_nis": float(tr.residual[cal.blanking:, 0].max()),
        "nominal_alarm_samples": int(tr.alarm[:, 0].sum()), "declared": sorted({str(s) for s in tr.isolated} - {""}),
        "units": {"duration": "s", "peak_nominal_nis": "1", "nominal_alarm_samples": "1"}}
    summary["calibration_cached"] = cached
    _write(progress, replay, run_dir, record, summary)
    _plot_nis(record, sc, run_dir / "figures" / "nis_bank.png")
    return summary


def _plot_depth(record: Record, sc: AuvScenario, switch, path: Path) -> Path:
    """Depth (true, pressure reading, sonar) around the sensor fault, with onset and switch times."""
    import matplotlib.pyplot as plt

    y = record.signals["y_meas"]
    fig, ax = plt.subplots(figsize=(9, 3.2))
    ax.plot(record.time, -record.signals["reference"][:, 2], "k--", lw=0.8, label="reference")
    ax.plot(record.time, -record.truth_state[:, 2], lw=1.0, label="true depth")
    ax.plot(record.time, y[:, 2], lw=0.6, label="pressure sensor")
    ax.plot(record.time, sc.floor_depth - y[:, 3], lw=0.6, label="sonar (H − altitude)")
    ax.axvline(sc.faults[0].onset, color="0.4", ls=":", label="onset")
    if switch is not None:
        ax.axvline(switch, color="C3", ls="--", lw=0.8, label="switch")
    ax.set_ylabel("depth [m]")
    ax.legend(fontsize=7, ncol=3)
    return _save(fig, ax, path)


def _plot_currents(record: Record, sc: AuvScenario, path: Path) -> Path:
    """Fig. 8 of the survey: expected (identified characteristic) vs measured motor current of the faulty thrusters."""
    import matplotlib.pyplot as plt

    names = record.columns["signals/u"]
    p = len(names)
    tr = record.diagnosers["current_map"]
    fig, axes = plt.subplots(len(sc.faults), 1, figsize=(9, 2.6 * len(sc.faults)), sharex=True, squeeze=False)
    for ax, f in zip(axes[:, 0], sc.faults):
        i = names.index(f.target)
        measured = record.signals["y_meas"][:, 13 + p + i]
        ax.plot(record.time, measured, lw=0.6, color="0.6", label="measured current")
        ax.plot(tr.time, tr.residual[:, i], lw=0.8, color="C3", label="measured − expected (filtered)")
        ax.axhline(tr.threshold[i], color="k", ls="--", lw=0.7)
        ax.axhline(-tr.threshold[i], color="k", ls="--", lw=0.7)
        ax.axvline(f.onset, color="0.3", ls=":")
        ax.set_ylabel(f"{f.target} [A]")
        ax.set_title(f"{f.name} ({f.kind})", fontsize=9)
        ax.legend(fontsize=7)
    return _save(fig, axes[-1], path)


def run(name: str = "ch4-auv", out: str | Path = "runs", seed: int = 0, progress: bool = True, replay: bool = True):
    """Run one chapter-4 experiment; returns (summary, run folder)."""
    if name not in EXPERIMENTS:
        raise RobofdiError(f"unknown experiment {name!r}; expected one of {', '.join(EXPERIMENTS)}")
    run_dir = prepare_run_dir(out, name, seed)
    runner = {"ch4-auv": _run_ch4_auv, "ch4-flooded": _run_ch4_flooded, "ch4-depth-sensor": _run_ch4_depth_sensor,
              "ch4-roby2": _run_ch4_roby2}[name]
    with keep_partial(run_dir):
        summary = runner(name, run_dir, seed, Progress.of(progress, name), replay)
    return summary, run_dir
