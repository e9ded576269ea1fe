"""Jiang & Chowdhury, "Fault estimation and accommodation for linear MIMO discrete-time systems", IEEE TCST 13(3),
2005 — the helicopter example (Sec. V): reduced-order Kalman fault estimation (eqs. (5)–(28)), loss-of-effectiveness
accommodation (eq. (29)) through the loop's accommodation stage, and the unknown-input augmented filter
((31)–(41)). The paper gives no controller: LQR (Q = I, R = I) on the estimator's fault-decoupled x̂ (spec A.7).

Runs (T = 0.01 s, 10 s): noise-free fault-free / faulty without / with accommodation (exactness, FTC effect);
noisy with accommodation (the paper's S, Q; Fig. 1–2); noisy without accommodation, corrected covariances, seeds
seed+1 … seed+3 (the averaged r̂₁); noisy, harness "digest" (ungated element-wise R̂ feeds (29)), seeds seed+1 …
seed+3 (spec A.7 item 4: f̂ − f statistics, LS r̂₁, windowed-LS error RMS); noise-free unknown-input example ζ = 0.1
with r₃ (Figs. 3–4).

    robofdi run jiang2005 --out runs --seed 0
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import time

import numpy as np

from robofdi.evaluate.figures import save_figure
from robofdi.evaluate import summarize
from robofdi.evaluate.reproduction import reproduction_check as check
from robofdi.evaluate.headline import recovery_section
from robofdi.evaluate.run_folder import keep_partial, prepare_run_dir, write_run_folder
from robofdi.progress import Progress
from robofdi.models.linear_examples import helicopter
from robofdi.control.linear import lqr_gain
from robofdi.observers.augmented_error import AugmentedErrorEstimator
from robofdi.observers.kalman import ParameterFaultEKF, reduced_order_design
from robofdi.seeding import rng
from robofdi.systems.helicopter import (
    FAULT_OUTPUTS, UNKNOWN_INPUT_FAULTS, HelicopterScenario, build_loop, calibrate, fault_estimates,
)

#: Closed-loop runs of :func:`run` (progress units): fault-free, no accommodation, noise-free, noisy, 3 LS seeds,
#: 3 harness seeds, the unknown-input example.
RUNS = 11
EXPERIMENTS = {"jiang2005": "Jiang & Chowdhury 2005: reduced-order Kalman fault estimation + LOE accommodation, helicopter"}


def _true_effectiveness(record, names) -> np.ndarray:
    """r(k) per actuator from the labels: label = u·(1 − r) − u = −r u (u the command that reached the fault)."""
    u = record.signals["u"]
    r = np.zeros_like(u)
    for name, target in names.items():
        j = record.columns["signals/u"].index(target)
        lab = record.faults[name].value
        ok = np.abs(u[:, j]) > 1e-9
        r[ok, j] = -lab[ok] / u[ok, j]
    return r


def _ls_effectiveness(record, sc, t0=5.0, t1=10.0) -> float:
    """LS r̂₁ = Σ f̂₁ u₁ / Σ u₁² over [t0, t1] (f̂(k−1) paired with u(k−1))."""
    f, _ = fault_estimates(record, sc)
    u, t = record.signals["u_diag"][:-1], record.time[:-1]
    sel = (t >= t0) & (t <= t1)
    return float(np.sum(f[1:][sel, 0] * u[sel, 0]) / np.sum(u[sel, 0] ** 2))


def _item4(record, sc) -> dict:
    """Spec A.7 item 4 on one noisy run: f̂ − f per-sample std and mean/std, LS r̂₁ over [5, 10] s, and the error
    RMS of the windowed LS r̂ (r̂(k) against r(k−1), samples whose window lies wholly after the onset), u RMS."""
    f, _ = fault_estimates(record, sc)
    labels = {"r1": "collective", "r2": "cyclic"}
    err = f[1:] + np.stack([record.faults[n].value for n in labels], axis=1)[:-1]      # label = −f
    r = _true_effectiveness(record, labels)[:-1]
    e = record.diagnosers["kalman_fe"].residual[1:] - r
    t = record.time[:-1]
    onset = [next(x.onset for x in sc.faults if x.name == n) for n in labels]
    rms = [float(np.sqrt(np.mean(e[t >= t0 + sc.samples * 0.01, j] ** 2))) for j, t0 in enumerate(onset)]
    return {"std": err.std(axis=0).tolist(), "mean_over_std": (err.mean(axis=0) / err.std(axis=0)).tolist(),
            "ls_r1": _ls_effectiveness(record, sc), "window_rms": rms,
            "u_rms": np.round(np.sqrt(np.mean(record.signals["u"] ** 2, axis=0)), 1).tolist()}


def _rms_dev(a, b) -> np.ndarray:
    return np.sqrt(np.mean((a.truth_state - b.truth_state) ** 2, axis=0))



def _item4_checks(item4: dict) -> list[dict]:
    """The reproduction entries of spec A.7 item 4 (digest harness, seeds 1–3 after ``seed``)."""
    per = lambda key: {s: v[key] for s, v in item4.items()}  # noqa: E731
    std_ok = all(abs(a / b - 1) <= 0.2 for v in item4.values() for a, b in zip(v["std"], (56.1, 26.4)))
    note = ("harness='digest': as-printed filter, accommodation fed by the ungated element-wise R̂ ∈ [0, 0.95]; "
            f"u RMS per seed {per('u_rms')} (digest: 600–800; our loop applies a diagnosis one sample late)")
    return [
        check("digest harness: per-sample f̂ − f std [input unit], per seed (relative tolerance)", [56.1, 26.4],
              per("std"), 0.2,
              std_ok, note=note),
        check("digest harness: |mean(f̂ − f)| / std, per seed", 0.01, per("mean_over_std"), 0.05,
              all(abs(x) < 0.05 for v in item4.values() for x in v["mean_over_std"])),
        check("digest harness: LS r̂₁ over [5, 10] s, per seed", 0.4, per("ls_r1"), 0.03,
              all(abs(v["ls_r1"] - 0.4) < 0.03 for v in item4.values())),
        check("digest harness: windowed LS (25 samples) r̂₁ error RMS, per seed (≤ paper)", 0.025,
              {s: v["window_rms"][0] for s, v in item4.items()}, 0.0,
              all(v["window_rms"][0] <= 0.025 for v in item4.values())),
        check("digest harness: windowed LS (25 samples) r̂₂ error RMS, per seed (< 0.12)", 0.085,
              {s: v["window_rms"][1] for s, v in item4.items()}, 0.035,
              all(v["window_rms"][1] < 0.12 for v in item4.values())),
    ]


def _figures(run_dir: Path, noisy, noise_free, ftc_free, noftc, ui, ui_sc, zeta):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = {"r1": "collective", "r2": "cyclic"}
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    tr = noisy.diagnosers["kalman_fe"]
    truth = _true_effectiveness(noisy, names)
    for j, ax in enumerate(axes):
        ax.plot(noisy.time, truth[:, j], "k", lw=2, label=f"r{j + 1}")
        ax.plot(tr.time, tr.residual[:, j], lw=0.8, label=f"r̂{j + 1} (LS, 25 samples, noisy)")
        ax.plot(noise_free.diagnosers["kalman_fe"].time, noise_free.diagnosers["kalman_fe"].residual[:, j], "--",
                lw=0.8, label=f"r̂{j + 1} noise-free")
        ax.set_ylim(-0.5, 1.5)
        ax.set_ylabel("loss of effectiveness [1]")
        ax.legend(fontsize=7)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Fig. 1 (like): estimated vs true loss of effectiveness")
    save_figure(fig, run_dir / "figures" / "fig1_effectiveness.png")
    fig, axes = plt.subplots(4, 1, figsize=(7, 7), sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(ftc_free.time, ftc_free.truth_state[:, i], "k", lw=2, label="fault-free")
        ax.plot(noftc.time, noftc.truth_state[:, i], lw=0.8, label="fault, no accommodation")
        ax.plot(noise_free.time, noise_free.truth_state[:, i], "--", lw=0.8, label="fault, accommodation (29)")
        ax.set_ylabel(noise_free.columns["truth/state"][i], fontsize=8)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Fig. 2 (like): closed-loop states, noise-free (units not given by the paper)")
    save_figure(fig, run_dir / "figures" / "fig2_states.png")
    fig, axes = plt.subplots(2, 1, figsize=(7, 4.5), sharex=True)
    axes[0].plot(ui.time, zeta[:, 0], label="ζ̂")
    axes[0].axhline(ui_sc.unknown_input, color="k", ls="--", label="ζ = 0.1")
    axes[0].set_ylabel("unknown input [1]")
    axes[0].legend(fontsize=7)
    tr = ui.diagnosers["kalman_fe"]
    axes[1].plot(ui.time, _true_effectiveness(ui, {"r3": "collective"})[:, 0], "k", lw=2, label="r3")
    axes[1].plot(tr.time, tr.residual[:, 0], lw=0.8, label="r̂3")
    axes[1].set_ylabel("loss of effectiveness [1]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize=7)
    fig.suptitle("Figs. 3–4 (like): unknown input ζ and r₃, augmented filter, noise-free")
    save_figure(fig, run_dir / "figures" / "fig3_4_unknown_input.png")


#: Remark 5's synthetic modelling error [RECONSTRUCTED]: the vertical-velocity damping of A (A₂₂ − 1 = −0.01 per
#: sample) is θ = 50 % larger in the truth than in the belief: A_true = A + θ A_θ.
REMARK5_DIRECTION = np.zeros((4, 4))
REMARK5_DIRECTION[1, 1] = -0.01
REMARK5_THETA, REMARK5_LOSS = 0.5, np.array([0.4, 0.0])


#: The augmented-error alternative's observer poles (A − LC) and least-squares forgetting factor [HARNESS].
REMARK5_AE_POLES, REMARK5_AE_FORGETTING = (0.5, 0.55, 0.6, 0.65), 0.99


def _remark5_run(seed: int, with_parameter: bool, samples: int = 1500, noise: float = 1e-3,
                 method: str = "ekf") -> dict:
    """One run of a Remark-5 estimator (``method`` "ekf": :class:`ParameterFaultEKF`; "augmented_error":
    :class:`AugmentedErrorEstimator`): the truth with the modelling error, a loss of effectiveness r = [0.4, 0] of
    the collective from 5 s, LQR (Q = I, R = I, on the true state: a harness for this check only) plus the
    excitation [sin πt, cos 0.6πt], process and sensor noise std ``noise`` (the remark's "low-level noise")."""
    model = helicopter()
    gen = rng(seed, "jiang2005", "remark5")
    A_true = model.A + REMARK5_THETA * REMARK5_DIRECTION
    K = lqr_gain(model, np.ones(4), np.ones(2))
    dirs = [REMARK5_DIRECTION] if with_parameter else []
    if method == "ekf":
        ekf = ParameterFaultEKF(model, dirs, noise**2 * np.eye(4), noise**2 * np.eye(3), parameter_drift=1e-10,
                                fault_drift=1e-6, P0=np.eye(6 + len(dirs)))
    else:
        ekf = AugmentedErrorEstimator(model, dirs, poles=REMARK5_AE_POLES, forgetting=REMARK5_AE_FORGETTING)
    x, u_prev, r_hat, theta_5s, cpu = np.array([1.0, 0.5, 0.0, 0.0]), np.zeros(2), [], None, 0.0
    for k in range(samples):
        t = k * model.dt
        y = model.C @ x + gen.normal(scale=noise, size=3)
        c0 = time.process_time()
        r_hat.append(ekf.update(y, u_prev).estimate)
        cpu += time.process_time() - c0
        if k == 499:
            theta_5s = ekf.parameter_estimate.tolist()
        u = -K @ x + np.array([np.sin(np.pi * t), np.cos(0.6 * np.pi * t)])
        loss = REMARK5_LOSS if t >= 5.0 else np.zeros(2)
        x = A_true @ x + model.B @ ((1.0 - loss) * u) + gen.normal(scale=noise, size=4) * np.array([1, 1, 0.1, 0.1])
        u_prev = u
    r_hat = np.array(r_hat)
    return {"r_mean_10_15s": r_hat[1000:].mean(axis=0).tolist(), "r_max_3_5s": np.abs(r_hat[300:500]).max().item(),
            "theta_5s": theta_5s, "theta_15s": ekf.parameter_estimate.tolist(), "cpu_us_per_update": 1e6 * cpu / samples}


def remark5_checks(seed: int, seeds: int = 3) -> list[dict]:
    """Remark 5 (EKF for state and unknown parameters when a modelling error enters multiplicatively)."""
    ekf = {s: _remark5_run(s, True) for s in range(seed + 1, seed + 1 + seeds)}
    plain = {s: _remark5_run(s, False) for s in range(seed + 1, seed + 1 + seeds)}
    aug = {s: _remark5_run(s, True, method="augmented_error") for s in range(seed + 1, seed + 1 + seeds)}
    aug_err = max(float(np.abs(np.array(v["r_mean_10_15s"]) - REMARK5_LOSS).max()) for v in aug.values())
    aug_pre = max(v["r_max_3_5s"] for v in aug.values())
    aug_th = max(abs(v["theta_5s"][0] - REMARK5_THETA) for v in aug.values())
    cpu = {"augmented error": float(np.mean([v["cpu_us_per_update"] for v in aug.values()])),
           "EKF": float(np.mean([v["cpu_us_per_update"] for v in ekf.values()]))}
    err = max(float(np.abs(np.array(v["r_mean_10_15s"]) - REMARK5_LOSS).max()) for v in ekf.values())
    pre = max(v["r_max_3_5s"] for v in ekf.values())
    th = max(abs(v["theta_5s"][0] - REMARK5_THETA) for v in ekf.values())
    err_plain = min(float(np.abs(np.array(v["r_mean_10_15s"]) - REMARK5_LOSS).max()) for v in plain.values())
    pre_plain = min(v["r_max_3_5s"] for v in plain.values())
    note = ("reconstructed (the remark gives no equations): truth A + θ A_θ with θ = 0.5 on the w damping, r = [0.4, "
            "0] from 5 s, noise std 1e-3, LQR on the true state (this check's harness), seeds "
            f"{seed + 1}–{seed + seeds}")
    return [
        check("Remark 5, EKF on col(x, θ, r): worst |mean r̂ − r| on [10, 15] s / max |r̂| on [3, 5] s / |θ̂(5 s) − θ|",
              {"r": REMARK5_LOSS.tolist(), "theta": REMARK5_THETA}, {"r error": err, "pre-fault r̂": pre,
              "θ error": th, "runs": ekf}, {"r error": 0.02, "pre-fault r̂": 0.03, "θ error": 0.05},
              err < 0.02 and pre < 0.03 and th < 0.05, note=note),
        check("Remark 5: the same EKF without θ (the modelling error ignored): best |mean r̂ − r| / max |r̂| before "
              "the fault", "biased (why the remark asks for the EKF)", {"r error": err_plain, "pre-fault r̂": pre_plain,
              "runs": plain}, None, err_plain > 0.05 and pre_plain > 0.1),
        check("Remark 5, the augmented-error alternative (low noise): worst |mean r̂ − r| on [10, 15] s / max |r̂| "
              "on [3, 5] s / |θ̂(5 s) − θ|", {"r": REMARK5_LOSS.tolist(), "theta": REMARK5_THETA},
              {"r error": aug_err, "pre-fault r̂": aug_pre, "θ error": aug_th, "CPU µs per update": cpu, "runs": aug},
              {"r error": 0.02, "pre-fault r̂": 0.03, "θ error": 0.05}, aug_err < 0.02 and aug_pre < 0.03
              and aug_th < 0.05,
              note="reconstructed (the remark names the technique only): AugmentedErrorEstimator — observer, "
                   "sensitivity filter Ξ⁺ = (A − LC)Ξ + Φ, least squares on the augmented error with forgetting "
                   f"{REMARK5_AE_FORGETTING:g}, poles of A − LC {list(REMARK5_AE_POLES)}; the same runs as the EKF "
                   "entry; the CPU times are informational (one process, per update)"),
    ]


def run(name: str = "jiang2005", out: str | Path = "runs", seed: int = 0, progress: bool = True, replay: bool = False):
    """All runs, the reproduction checks and the figures; returns (summary, run folder)."""
    run_dir = prepare_run_dir(out, name, seed)
    model = helicopter()
    design = reduced_order_design(model, -model.B, FAULT_OUTPUTS)
    quiet = HelicopterScenario(seed=seed, noise=False)
    progress = Progress.of(progress, name)
    with keep_partial(run_dir), progress.stage("calibrations and runs", RUNS, unit="run") as tick:
        thr_quiet = calibrate(quiet)
        free = build_loop(replace(quiet, faults=(), accommodation=False)).run(quiet.duration, seed=seed,
                                                                             run_key="fault_free")
        tick()
        noftc = build_loop(replace(quiet, accommodation=False), thr_quiet).run(quiet.duration, seed=seed, run_key="no_ftc")
        tick()
        nf = build_loop(quiet, thr_quiet).run(quiet.duration, seed=seed, scenario="helicopter noise-free")
        tick()
        noisy_sc = HelicopterScenario(seed=seed)
        noisy = build_loop(noisy_sc, calibrate(noisy_sc)).run(noisy_sc.duration, seed=seed, scenario="helicopter")
        tick()
        ls = {}
        for s in (seed + 1, seed + 2, seed + 3):
            sc = HelicopterScenario(seed=s, accommodation=False, covariance_mode="corrected")
            rec = build_loop(sc).run(sc.duration, seed=s, run_key="ls_estimate")
            ls[s] = _ls_effectiveness(rec, sc)
            tick()
        item4 = {}
        for s in (seed + 1, seed + 2, seed + 3):
            sc = HelicopterScenario(seed=s, harness="digest")
            item4[s] = _item4(build_loop(sc).run(sc.duration, seed=s, run_key="digest_harness"), sc)
            tick()
        ui_sc = HelicopterScenario(seed=seed, noise=False, faults=UNKNOWN_INPUT_FAULTS, unknown_input=0.1,
                                   covariance_mode="swapped", accommodation=False)
        ui = build_loop(ui_sc, thr_quiet[:2]).run(ui_sc.duration, seed=seed, run_key="unknown_input")
        _, zeta = fault_estimates(ui, ui_sc)
        tick()
    with progress.stage("checks, run folder: records, figures"):
        # noise-free exactness: f̂(k−1) against f(k−1) = r u (labels), after the first samples
        f, _ = fault_estimates(nf, quiet)
        lab = -np.stack([nf.faults["r1"].value, nf.faults["r2"].value], axis=1)
        exact_err = float(np.max(np.abs(f[2:] - lab[1:-1])))
        r_true = _true_effectiveness(nf, {"r1": "collective", "r2": "cyclic"})
        tr = nf.diagnosers["kalman_fe"]
        u_prev = nf.signals["u_diag"][:-1]
        ok = np.abs(u_prev) > 1e-6
        r_err = float(np.max(np.abs(tr.residual[1:] - r_true[:-1])[ok]))
        dev_ftc, dev_noftc = _rms_dev(nf, free), _rms_dev(noftc, free)
        ratio = dev_ftc / dev_noftc
        zeta_end = float(zeta[-1, 0])
        f_ui, _ = fault_estimates(ui, ui_sc)
        lab_ui = -ui.faults["r3"].value
        ui_err = float(abs(f_ui[-1, 0] - lab_ui[-2]))
        ls_mean = float(np.mean(list(ls.values())))
        reproduction = [
            check("Abar11", 1.0521, float(design.Abar11[0, 0]), 5e-5, abs(design.Abar11[0, 0] - 1.0521) < 5e-5),
            check("Abar21", 10.5091, float(design.Abar21[0, 0]), 5e-5, abs(design.Abar21[0, 0] - 10.5091) < 5e-5),
            check("rank_CE", 2, design.rank_CE, 0, design.rank_CE == 2),
            check("exact_estimate: max |f̂(k−1) − f(k−1)| noise-free after the one-step delay", 0.0, exact_err, 1e-9,
                   exact_err < 1e-9),
            check("max |r̂ − r| noise-free where |u| > 1e-6 (element-wise r̂ = f̂/u)", 0.0, r_err, 1e-9, r_err < 1e-9),
            check("r1_mean: LS r̂₁ over [5, 10] s, noisy, mean over 3 seeds (corrected covariances)", 0.4, ls_mean, 0.02,
                   abs(ls_mean - 0.4) < 0.02, note=f"per seed {ls}; with the as-printed covariances the LS estimate is "
                   "biased up (≈0.56) by the noise the deadbeat filter feeds into u"),
            check("accommodation: RMS deviation from fault-free, with / without (29), per state", "quick recovery (Fig. 2)",
                   {"with": dev_ftc.tolist(), "without": dev_noftc.tolist(), "ratio": ratio.tolist()}, 0.01,
                   bool(np.all(dev_ftc < 0.01) and np.all(dev_noftc[:3] > 0.04))),
            *_item4_checks(item4),
            check("zeta_hat(10 s), unknown-input filter, noise-free (swapped covariances)", 0.1, zeta_end, 0.002,
                   abs(zeta_end - 0.1) < 0.002),
            check("|f̂ − f| at 10 s, unknown-input example", 0.0, ui_err, 1e-4, ui_err < 1e-4),
            *remark5_checks(seed),
        ]
        summary = summarize(noisy, name, [f.to_dict() for f in noisy_sc.faults])
        summary["noise_free"] = summarize(nf, name, [f.to_dict() for f in quiet.faults])["diagnosers"]
        summary["thresholds"] = {"noisy": calibrate(noisy_sc).tolist(), "noise_free": thr_quiet.tolist(), "unit": "1"}
        summary["estimate_note"] = ("estimate_rmse compares r̂ [1] with the injector's additive label −r·u [input unit]; "
                                    "the reproduction list carries the effectiveness checks")
        summary["harness"] = ("LQR Q=I4, R=I2 on the estimator's x̂ (the paper gives no controller); x0=[1,0.5,0,0]; "
                              "excitation [sin πt, cos 0.6πt]; R̂ clipped to [0, 0.95]; LS window 25 samples; "
                              "accommodation fed by the gated LS r̂ (the 'digest harness' checks: by the ungated "
                              "element-wise r̂, spec A.7)")
        summary["reproduction"] = reproduction
        states, units = nf.columns.get("truth/state", []), nf.units.get("truth/state", [])
        summary["recovery"] = recovery_section(
            ("no accommodation", "accommodation (29)"),
            [{"quantity": f"RMS deviation of {states[i] if i < len(states) else f'x{i + 1}'} from the fault-free run",
              "unit": (units[i] if i < len(units) else "") or None,
              "values": {"no accommodation": float(dev_noftc[i]), "accommodation (29)": float(dev_ftc[i])}}
             for i in range(len(dev_ftc))],
            method="eq. (29): the input scaled by the estimated effectiveness (noise-free runs)")
        (run_dir / "figures").mkdir(exist_ok=True)
        write_run_folder(run_dir, noisy, summary, {"noise_free": nf, "no_accommodation": noftc, "fault_free": free,
                                                    "unknown_input": ui}, replay=replay)
        _figures(run_dir, noisy, nf, free, noftc, ui, ui_sc, zeta)
    return summary, run_dir
