"""Edwards, Alwi & Tan §6 on the chapter-4 AUV: sliding-mode control with on-line control allocation weighted by
the diagnosed thruster effectiveness, side by side with the chapter-4 allocators on the ch4-auv mission.

    robofdi run edwards-auv-ftc [--seed N] [--out DIR]

The mission and faults are those of ``ch4-auv`` (ODIN task of 120 s in a current; thruster 2 (horizontal) and
thruster 6 (vertical) switched off at 78 s and 90 s). Seven runs with the same noise by default: the SMC-CA loop
(``allocation = "smc_ca"``: :class:`robofdi.ftc.smc_auv.SlidingModeAuvControl` +
:class:`robofdi.ftc.smc_auv.HealthWeightedAllocation`) fault-free, without FTC (W = I), with the oracle health and
with the health diagnosed by the voltage residual (W = I − K̂, k̂ = 1 for an isolated thruster, floored at
w_min = 0.05); the chapter-4 controller with its default "constrained" allocator fault-free, without FTC and
diagnosed. ``run(..., full=True)`` adds SMC-CA with the ``current_map`` and ``force_observer`` health, the ch4
oracle, and the other four ch4 allocators (diagnosed): 15 runs.

All runs use the "constrained" allocator's calibration: it comes from fault-free missions with every thruster
healthy, where the allocators differ only when a thruster saturates. The SMC-CA loop shares it too (the
diagnosers' thresholds are on thruster-level residuals); ``own_calibration=True`` calibrates under SMC-CA instead
(three more 240 s missions).

The design-time part of §6 is checked too: (66) on the AUV linearised at rest (B1 = 0: γ1 = γ2 = 0, the condition is
0 and the sliding motion is independent of W), γ0 of Proposition 5, and the thruster patterns for which B W Bᵀ is
singular (the mission's pair 2 + 6 is not one of them).

summary.json["tracking"] holds the ch4 contract {"fault_free_rms", "no_ftc_rms", "oracle_rms", "diagnosed_rms"}
(position RMS [m] after the second failure) for the SMC-CA loop, and ``tracking_by_allocator`` the same for each
chapter-4 allocator.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from robofdi.evaluate.annotate import event_lines
from robofdi.evaluate import summarize
from robofdi.evaluate.headline import recovery_section
from robofdi.evaluate.reproduction import reproduction_check as check
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, write_run_folder
from robofdi.ftc.allocation import ALLOCATORS
from robofdi.ftc.smc_auv import SmcAuvSettings, auv_smc_ca_check
from robofdi.models.auv import AuvModel
from robofdi.progress import Progress, run_ticks
from robofdi.systems.auv import calibration, check_scenario, run_scenario, tracking_rms

EXPERIMENTS = {"edwards-auv-ftc": "Edwards et al. §6 on the ch4 AUV: SMC with on-line allocation W = I − K̂ vs the "
                                  "ch4 allocators, thrusters 2 and 6 off"}

HEALTH_SOURCES = ("voltage_residual", "current_map", "force_observer")
#: Acceptance (issue): diagnosed SMC-CA within this factor of fault-free after both failures.
RATIO = 1.5


def _ticks(sc) -> int:
    return run_ticks(sc.duration, 1.0 / sc.plant.control_dt)


def _figure(records: dict, onsets, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from robofdi.evaluate.figures import save_figure

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name, rec in records.items():
        err = np.linalg.norm(rec.signals["reference"][:, :3] - rec.truth_state[:, :3], axis=1)
        axes[0].plot(rec.time, err, lw=0.7, label=name)
    axes[0].set_ylabel("position error [m]")
    axes[0].set_yscale("log")
    axes[0].legend(fontsize=6, ncol=2)
    axes[0].set_title("ch4-auv mission, thrusters 2 and 6 off: SMC-CA against the ch4 allocators", fontsize=9)
    main = records.get("smc_ca diagnosed (voltage_residual)")
    if main is not None:
        u, cols = main.u_applied, main.columns["truth/u_applied"]
        for i in range(u.shape[1]):
            axes[1].plot(main.time, u[:, i], lw=0.6, label=cols[i])
        axes[1].set_ylabel("thrust [N] (SMC-CA, diagnosed)")
        axes[1].legend(fontsize=6, ncol=4)
    for ax in axes:
        event_lines(ax, onsets, label=ax is axes[0])
    axes[1].set_xlabel("time [s]")
    save_figure(fig, path)


def _scenario(seed: int):
    from robofdi.experiments.ch4_auv import ch4_auv_scenario

    return ch4_auv_scenario(seed)


def run(name: str = "edwards-auv-ftc", out: str | Path = "runs", seed: int = 0, progress: bool = True,
        replay: bool = False, own_calibration: bool = False, full: bool = False):
    """The experiment of the module docstring. ``own_calibration``: calibrate the diagnosers on fault-free
    missions flown under SMC-CA (3 × 240 s more) instead of sharing the ch4 controller's calibration. ``full``:
    all the runs of the module docstring (15); by default the seven that make the comparison — SMC-CA fault-free,
    no FTC, oracle and diagnosed by the voltage residual; the ch4 controller fault-free, no FTC and diagnosed with
    its default "constrained" allocator."""
    run_dir = prepare_run_dir(out, name, seed)
    progress = Progress.of(progress, name)
    ch4 = _scenario(seed)
    smc = replace(ch4, name=name, allocation="smc_ca")
    check_scenario(smc)
    model = AuvModel.from_mjcf(smc.plant.mjcf, smc.mismatch)
    design = auv_smc_ca_check(model, SmcAuvSettings(), samples=2000)
    records, summaries, rms = {}, {}, {}
    since = max(f.onset for f in ch4.faults)
    with keep_partial(run_dir):
        with progress.stage("calibration (ch4 controller, constrained allocation)", skipped="from the cache"):
            cal_ch4, cached_ch4 = calibration(ch4)
        if own_calibration:
            with progress.stage("calibration (SMC-CA loop)", skipped="from the cache"):
                cal_smc, cached_smc = calibration(smc)
        else:
            cal_smc, cached_smc = cal_ch4, cached_ch4
        runs = [("smc_ca fault-free", replace(smc, faults=(), variant="no_ftc"), cal_smc),
                ("smc_ca no FTC", replace(smc, variant="no_ftc"), cal_smc),
                ("smc_ca oracle", replace(smc, variant="oracle"), cal_smc)]
        sources = HEALTH_SOURCES if full else HEALTH_SOURCES[:1]
        allocators = ALLOCATORS if full else ("constrained",)
        runs += [(f"smc_ca diagnosed ({h})", replace(smc, variant="diagnosed", health_source=h), cal_smc)
                 for h in sources]
        runs += [("ch4 fault-free", replace(ch4, faults=(), variant="no_ftc"), cal_ch4),
                 ("ch4 no FTC", replace(ch4, variant="no_ftc"), cal_ch4)]
        if full:
            runs.append(("ch4 constrained oracle", replace(ch4, variant="oracle"), cal_ch4))
        for alloc in allocators:
            runs.append((f"ch4 {alloc} diagnosed", replace(ch4, allocation=alloc, variant="diagnosed"), cal_ch4))
        for label, sc, cal in runs:
            with progress.stage(f"run: {label}", _ticks(sc)) as tick:
                records[label] = run_scenario(sc, cal, progress=tick)
            rms[label] = tracking_rms(records[label], since)
            summaries[label] = summarize(records[label], sc.name)
    base = rms["smc_ca fault-free"]
    tracking = {"fault_free_rms": base, "no_ftc_rms": rms["smc_ca no FTC"], "oracle_rms": rms["smc_ca oracle"],
                "diagnosed_rms": rms["smc_ca diagnosed (voltage_residual)"], "since": since,
                "diagnosed_rms_by_health_source": {h: rms[f"smc_ca diagnosed ({h})"] for h in sources},
                "ratio_to_fault_free": {k: v / base for k, v in rms.items() if k.startswith("smc_ca")},
                "units": {"*_rms": "m", "since": "s", "ratio_to_fault_free": "1"}}
    ch4_base = rms["ch4 fault-free"]
    by_alloc = {alloc: {"fault_free_rms": ch4_base, "no_ftc_rms": rms["ch4 no FTC"],
                        "oracle_rms": rms.get(f"ch4 {alloc} oracle"), "diagnosed_rms": rms[f"ch4 {alloc} diagnosed"],
                        "ratio_diagnosed_to_fault_free": rms[f"ch4 {alloc} diagnosed"] / ch4_base}
                for alloc in allocators}
    main_label = "smc_ca diagnosed (voltage_residual)"
    main = records[main_label]
    pair = ["thruster2", "thruster6"]
    ratio = tracking["diagnosed_rms"] / base
    reproduction = [
        check("(66) on the AUV linearised at rest: γ2γ0/(1 − γ1γ0)", "0 (B1 = 0, seed digest §8)",
              design["condition_66"], 1e-12, design["condition_66"] == 0.0 and design["gamma1"] == 0.0
              and design["gamma2"] == 0.0, note=f"γ0 = {design['gamma0']:.3f} (Proposition 5, sampled over "
                                                "w_i ∈ [0.05, 1])"),
        check("single total failures with B W Bᵀ singular", 0, 0, 0, True,
              note="auv_smc_ca_check refuses otherwise"),
        check("the mission's failure pair (2, 6) keeps B W Bᵀ invertible", True,
              pair not in design["singular_double_failures"], None, pair not in design["singular_double_failures"],
              note=f"{len(design['singular_double_failures'])} of 28 double failures are singular: any two of the "
                   "same group of four"),
        check("SMC-CA, diagnosed health (voltage_residual): position RMS after both failures / fault-free",
              f"≤ {RATIO} (issue acceptance)", ratio, RATIO, ratio <= RATIO,
              note="the paper reports no number for this (its §7 B747 tests are 'good performance maintained')"),
        *[check(f"SMC-CA, diagnosed health ({h}): RMS / fault-free", f"≤ {RATIO}", rms[f"smc_ca diagnosed ({h})"] / base,
                RATIO, rms[f"smc_ca diagnosed ({h})"] / base <= RATIO) for h in sources[1:]],
    ]
    labels = {k: k for k in rms}
    summary = summarize(main, name, tracking=tracking, tracking_by_allocator=by_alloc,
                        tracking_all={k: v for k, v in rms.items()},
                        variants={k: summaries[k]["diagnosers"] for k in summaries if k != main_label},
                        design=design, settings=SmcAuvSettings().__dict__,
                        calibration_cached={"smc_ca": cached_smc, "ch4": cached_ch4},
                        scenario={"duration": ch4.duration, "current": list(ch4.plant.current),
                                  "onsets": [f.onset for f in ch4.faults]})
    summary["recovery"] = recovery_section(
        labels.values(), [{"quantity": f"position tracking RMS for t >= {since:g} s (last fault)", "unit": "m",
                           "values": rms},
                          {"quantity": "ratio to the loop's own fault-free", "unit": "1",
                           "values": {k: v / (base if k.startswith("smc_ca") else ch4_base) for k, v in rms.items()}}],
        health_source="voltage_residual (and current_map, force_observer for SMC-CA)",
        method="SMC with on-line allocation W = I − K̂ (Edwards et al. §6) vs the ch4 reallocators")
    summary["reproduction"] = reproduction
    with progress.stage("run folder: records, figures"):
        others = {k.replace(" ", "_").replace("(", "").replace(")", ""): records[k]
                  for k in ("smc_ca fault-free", "smc_ca no FTC", "smc_ca oracle", "ch4 fault-free", "ch4 no FTC",
                            "ch4 constrained diagnosed")}
        write_run_folder(run_dir, main, summary, others, replay=replay)
        shown = {k: records[k] for k in ("smc_ca fault-free", "smc_ca no FTC", main_label, "ch4 no FTC",
                                         "ch4 constrained diagnosed", "ch4 pseudo_inverse diagnosed") if k in records}
        _figure(shown, ch4.faults, run_dir / "figures" / "smc_ca_vs_ch4.png")
    return summary, run_dir
