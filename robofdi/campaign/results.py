"""A campaign's outputs: results.parquet, campaign.json, figures/ and report.md — and reading them back."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from robofdi.campaign.metrics import analyse, at_equal_false_alarms, clopper_pearson, detection_curve
from robofdi.campaign.runs import UNITS
from robofdi.errors import RobofdiError
from robofdi.evaluate.figures import fixed_grid, save_figure
from robofdi.evaluate.summary import _jsonable

__all__ = ["CampaignResult", "load", "write_outputs", "report_markdown"]

FIGURES = "figures"


@dataclass
class CampaignResult:
    """A campaign folder: the results ``table`` (pandas), the ``spec`` (a CampaignSpec, or its dict when loaded)."""

    out: Path
    spec: object
    table: pd.DataFrame

    @property
    def spec_dict(self) -> dict:
        return self.spec if isinstance(self.spec, dict) else self.spec.to_dict()

    def metrics(self, detection_level: float | None = None) -> dict:
        """Per-diagnoser campaign metrics (:func:`robofdi.campaign.metrics.analyse`)."""
        spec = self.spec_dict
        return analyse(self.table, detection_level or spec["detection_level"], spec["diagnosers"])

    def at_equal_false_alarms(self) -> dict | None:
        """The diagnosers at one false-alarm count (:func:`robofdi.campaign.metrics.at_equal_false_alarms`)."""
        return at_equal_false_alarms(self.table, self.spec_dict["diagnosers"])

    @property
    def summary(self) -> dict:
        """campaign.json as written."""
        return json.loads((Path(self.out) / "campaign.json").read_text())


def load(out: str | Path) -> CampaignResult:
    """A campaign folder written by :func:`robofdi.campaign.run_campaign`."""
    out = Path(out)
    for name in ("results.parquet", "spec.json"):
        if not (out / name).is_file():
            raise RobofdiError(f"campaign folder {str(out)!r}: no {name}; expected the --out folder of a finished campaign")
    return CampaignResult(out, json.loads((out / "spec.json").read_text())["spec"], pd.read_parquet(out / "results.parquet"))


def _figures(result: CampaignResult, metrics: dict) -> list[str]:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    folder = Path(result.out) / FIGURES
    folder.mkdir(exist_ok=True)
    table = result.table[result.table["error"].isna() & result.table["faulty"]]
    written = []
    if table.empty:
        return written
    diagnosers = list(metrics)
    # confusion matrices: one panel per diagnoser, all kinds pooled (true target × isolated)
    for name in diagnosers:
        rows = table[table["diagnoser"] == name]
        truth = sorted(set(rows["target"]))
        said = np.where(rows["detected"].fillna(False).astype(bool),
                        rows["isolated"].astype(object).where(rows["isolated"].notna(), "unknown").astype(str), "missed")
        cols = sorted(set(said) - {"missed", "unknown"}) + [c for c in ("unknown", "missed") if c in set(said)]
        counts = pd.crosstab(rows["target"].astype(str).to_numpy(), said).reindex(index=truth, columns=cols, fill_value=0)
        fig, ax = plt.subplots(figsize=(1.2 + 0.45 * len(cols), 1.2 + 0.4 * len(truth)))
        ax.imshow(counts.to_numpy(), cmap="Blues")
        ax.set_xticks(range(len(cols)), cols, rotation=60, ha="right", fontsize=7)
        ax.set_yticks(range(len(truth)), truth, fontsize=7)
        for (i, j), v in np.ndenumerate(counts.to_numpy()):
            if v:
                ax.text(j, i, str(v), ha="center", va="center", fontsize=7)
        ax.set_xlabel("isolated target [runs]")
        ax.set_ylabel("true target")
        ax.set_title(f"{name}: confusion over {len(rows)} faults", fontsize=9)
        path = save_figure(fig, folder / f"confusion_{name}.png")
        written.append(path.name)
    # delay CDFs and detection probability against size: small multiples, one panel per fault kind × diagnoser
    panels = OutcomePanels(table, diagnosers)
    try:
        for what in OUTCOMES:
            fig = panels.draw(what, result.spec_dict["detection_level"])
            path = save_figure(fig, folder / f"{what}.png", tight=False, close=False)     # a fixed layout
            written.append(path.name)
    finally:
        panels.close()
    return written


def _curve(rows: pd.DataFrame, what: str) -> tuple[np.ndarray, np.ndarray]:
    """One diagnoser's curve over one kind's faults: the delay CDF (fraction of all its faults detected within a
    delay [s]) or the detection probability against size (isotonic, :func:`detection_curve`)."""
    det = rows["detected"].fillna(False).astype(bool).to_numpy()
    if what == "delay_cdf":
        d = np.sort(rows.loc[det, "delay"].to_numpy(float))
        return np.concatenate([[0], d]), np.arange(d.size + 1) / max(len(rows), 1)
    return detection_curve(rows["size"].to_numpy(float), det)


def outcome_grid(table: pd.DataFrame, diagnosers, what: str, level: float):
    """Small multiples of a campaign's outcomes: one row per fault kind, one column per diagnoser, shared axes;
    each panel draws its diagnoser's curve (the other diagnosers faint behind it, for comparison) and its n.
    ``what``: ``"delay_cdf"`` or ``"detection_vs_size"`` (with the detection level dotted and labelled)."""
    return OutcomePanels(table, diagnosers).draw(what, level)


#: The outcome figures of a campaign, drawn on one :class:`OutcomePanels`.
OUTCOMES = ("delay_cdf", "detection_vs_size")


class OutcomePanels:
    """The panels of :func:`outcome_grid` for one results table, made once and drawn with each outcome in turn
    (:meth:`draw` removes what the previous outcome drew): both outcome figures have this layout, so the axes and
    their tick artists (most of a panel's cost in matplotlib) are made once, not once per figure."""

    def __init__(self, table: pd.DataFrame, diagnosers):
        self.table, self.kinds, self.names = table, sorted(set(table["kind"])), list(diagnosers)
        # a fixed layout (no tight_layout at saving, which measured every tick label of every panel): shared axes,
        # so only the outer panels carry tick labels; margins for the two-line row labels, the column titles, the title
        self.fig, self.axes = fixed_grid(len(self.kinds), len(self.names), (1.9, 1.45), margins=(0.72, 0.12, 0.42, 0.5),
                                         gaps=(0.12, 0.12), sharex=True, sharey=True)
        self._drawn: list = []

    def draw(self, what: str, level: float):
        """The figure of outcome ``what`` (``"delay_cdf"`` or ``"detection_vs_size"``) on these panels."""
        self._clear()
        for r, kind in enumerate(self.kinds):
            sub = self.table[self.table["kind"] == kind]
            curves = {n: _curve(sub[sub["diagnoser"] == n], what) for n in self.names}
            for c, name in enumerate(self.names):
                self._panel(r, c, curves, int((sub["diagnoser"] == name).sum()), what, level)
        self.fig.suptitle(("fraction of faults detected within a delay" if what == "delay_cdf" else
                           "detection probability against fault size (isotonic fit)")
                          + ": one panel per fault kind (rows) and diagnoser (columns); other diagnosers faint",
                          fontsize=9)
        return self.fig

    def _panel(self, r: int, c: int, curves: dict, n: int, what: str, level: float) -> None:
        """Panel (kind r, diagnoser c): its curve over the other diagnosers' (faint), its ``n`` faults, the detection
        level for ``"detection_vs_size"``; the column's title on the top row, the row's label on the left, the
        outcome's axis label on the bottom row."""
        ax, name, drawn = self.axes[r, c], self.names[c], self._drawn
        for other, (x, y) in curves.items():
            if other != name:
                drawn += ax.step(x, y, where="post", color="0.85", lw=0.7)
        x, y = curves[name]
        drawn += ax.step(x, y, where="post", color=f"C{c}", lw=1.6)
        if what == "detection_vs_size":
            drawn += ax.plot(x, y, ".", ms=3, color=f"C{c}")
            drawn.append(ax.axhline(level, color="k", lw=0.6, ls=":"))
            drawn.append(ax.text(0.98, level, f"P = {level:g}", transform=ax.get_yaxis_transform(), fontsize=6,
                                 ha="right", va="bottom", color="0.3"))
        drawn.append(ax.text(0.02, 0.97, f"n = {n}", transform=ax.transAxes, fontsize=6.5, va="top", color="0.3"))
        ax.set_ylim(-0.03, 1.03)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
        if r == 0:
            ax.set_title(name, fontsize=8, color=f"C{c}")
        if c == 0:
            ax.set_ylabel(f"{self.kinds[r]}\n" + ("detected [fraction]" if what == "delay_cdf" else "P(detect)"),
                          fontsize=7)
        if r == len(self.kinds) - 1:
            ax.set_xlabel("detection delay [s]" if what == "delay_cdf" else "fault size [fraction of limit]", fontsize=7)

    def _clear(self) -> None:
        """Remove the previous outcome's curves and texts; the data limits start afresh (as on new axes)."""
        if not self._drawn:
            return
        for artist in self._drawn:
            artist.remove()
        self._drawn.clear()
        for ax in self.axes.flat:
            ax.relim()
            ax.autoscale_view()

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.fig)


def _pct(rate: dict) -> str:
    return "–" if rate["rate"] is None else f"{100 * rate['rate']:.1f} % ({rate['count']}/{rate['of']})"


def _ms(x) -> str:
    return "–" if x is None else f"{1e3 * x:.0f}"


#: Below this many fault-free runs the report warns that the false-alarm interval is wide (0 of 30 → ≤ 11.6 %).
SMALL_FAULT_FREE = 30
#: Below this many faults on one (kind, target) the report marks the minimum detectable fault as a few draws.
SMALL_FAULTS = 5


def _cautions(summary: dict) -> list[str]:
    """What a reader must know before quoting the numbers: a prefix of the spec, few fault-free runs, few faults."""
    spec, runs = summary["spec"], summary["runs"]
    total = int(spec.get("fault_free_runs", 0)) + int(spec.get("faulty_runs", 0))
    out = []
    if total and runs["finished"] < total:
        out.append(f"- **A prefix:** {runs['finished']} of the spec's {total} runs (run indices 0–{runs['finished'] - 1}, "
                   f"from `--runs` or an interrupted campaign; fault-free and faulty runs are interleaved, so the prefix "
                   f"mixes both). The other {total - runs['finished']} runs are not in these numbers; `--resume` without "
                   "`--runs` completes the campaign.")
    rates = [m["false_alarm_rate"]["of"] for m in summary["diagnosers"].values() if "false_alarm_rate" in m]
    n = int(min(rates)) if rates else int(runs["fault_free"])       # the rate's own n: runs that raised are left out
    if n < SMALL_FAULT_FREE:
        ci = clopper_pearson(0, n)
        width = "no fault-free run: no false-alarm rate" if ci is None else (
            f"even 0 false-alarm runs give a 95 % interval of [0, {100 * ci[1]:.1f}] %")
        out.append(f"- **Few fault-free runs:** {n} ({width}); {SMALL_FAULT_FREE} are needed to bound the rate below "
                   f"{100 * clopper_pearson(0, SMALL_FAULT_FREE)[1]:.1f} %.")
    few = sorted({(k, t, d["faults"]) for m in summary["diagnosers"].values() for k, ts in m.get("detectability", {}).items()
                  for t, d in ts.items() if d["faults"] < SMALL_FAULTS})
    if few:
        listed = ", ".join(f"{k} on {t} (n={c})" for k, t, c in few[:6]) + (" …" if len(few) > 6 else "")
        out.append(f"- **Few faults per target:** the minimum detectable fault of {listed} comes from fewer than "
                   f"{SMALL_FAULTS} draws (marked ⚠ below): a few outcomes, not a fitted curve.")
    return out


def report_markdown(summary: dict) -> str:
    """report.md from campaign.json."""
    spec = summary["spec"]
    lines = [f"# Campaign: {spec['system']} — {summary['runs']['finished']} runs "
             f"({summary['runs']['fault_free']} fault-free, {summary['runs']['faulty']} faulty, "
             f"{summary['runs']['errors']} errors)", "",
             f"Seed {spec['seed']}; system options `{json.dumps(spec['system_options'])}`; results table "
             "`results.parquet` (one row per run × diagnoser × fault).", ""]
    cautions = _cautions(summary)
    if cautions:
        lines += ["## Read with care", "", *cautions, ""]
    lines += ["| diagnoser | false-alarm runs (95 % CI) | detected | correctly isolated | isolation accuracy | "
              "delay median / p90 [ms] |", "|---|---|---|---|---|---|"]
    for name, m in summary["diagnosers"].items():
        fa, f = m["false_alarm_rate"], m["faulty"]
        ci = "–" if fa["ci95"] is None else f"[{100 * fa['ci95'][0]:.1f}, {100 * fa['ci95'][1]:.1f}] %"
        lines.append(f"| {name} | {_pct(fa)} {ci} | {_pct(f['detection'])} | {_pct(f['correctly_isolated'])} | "
                     f"{_pct(f['isolation_accuracy'])} | {_ms(f['delay_median'])} / {_ms(f['delay_p90'])} |")
    kinds = sorted({k for m in summary["diagnosers"].values() for k in m["by_kind_profile"]})
    if kinds:
        names = list(summary["diagnosers"])
        lines += ["", "## Detected / correctly isolated, by fault kind and profile", "",
                  "| kind~profile | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        for k in kinds:
            cells = []
            for n in names:
                b = summary["diagnosers"][n]["by_kind_profile"].get(k)
                cells.append("–" if b is None else f"{b['detection']['count']}/{b['faults']} · "
                             f"{b['correctly_isolated']['count']}/{b['faults']} · {_ms(b['delay_median'])} ms")
            lines.append(f"| {k} | " + " | ".join(cells) + " |")
        lines += ["", "Cells: detected / faults · correctly isolated / faults · median delay.", "",
                  f"## Minimum detectable fault (detection probability ≥ {spec['detection_level']:g}, isotonic fit)", "",
                  "≤: the smallest size drawn was already detected; n: faults of that kind on that target.", "",
                  "| kind | target | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
        pairs = sorted({(k, t) for m in summary["diagnosers"].values() for k, ts in m["detectability"].items() for t in ts})
        for k, t in pairs:
            cells = []
            for n in names:
                d = summary["diagnosers"][n]["detectability"].get(k, {}).get(t)
                unit = "" if d is None or d["unit"] == "1" else f" {d['unit']}"
                warn = "" if d is None or d["faults"] >= SMALL_FAULTS else " ⚠"
                if d is None:
                    cells.append("–")
                elif d["min_detectable_magnitude"] is None:
                    cells.append(f"not reached ≤ {d['size_range'][1] * d['limit']:.3g}{unit} (n={d['faults']}){warn}")
                else:
                    at_most = "≤ " if d.get("min_detectable_at_most") else ""
                    cells.append(f"{at_most}{d['min_detectable_magnitude']:.3g}{unit} (n={d['faults']}){warn}")
            lines.append(f"| {k} | {t} | " + " | ".join(cells) + " |")
    lines += _equal_false_alarms_markdown(summary.get("equal_false_alarms"))
    ex = summary.get("execution", {})
    cal = ex.get("calibration") or {}
    lines += ["", "## Execution", "", f"Backend: {ex.get('backend')}; runs this session: {ex.get('runs_this_session')}; "
              f"throughput: {ex.get('runs_per_minute') and round(ex['runs_per_minute'], 1)} runs/min; calibration "
              f"{cal.get('wall_time') and round(cal['wall_time'], 2)} s for {len(cal.get('keys', []))} key(s) "
              f"(cached: {[v['cached'] for v in cal.get('per_key', {}).values()]})."]
    found = {k: {n: v for n, v in info.get("identified", {}).items() if v} for k, info in cal.get("per_key", {}).items()}
    if any(found.values()):
        lines += ["", "Identified at calibration: " + "; ".join(
            f"{k}: " + ", ".join(f"{n} {v:.3g}" for n, v in notes.items()) for k, notes in found.items() if notes) + "."]
    if summary.get("errors"):
        lines += ["", "## Runs that raised", ""] + [f"- run {e['index']}: {e['error']}" for e in summary["errors"][:20]]
    if summary.get("figures"):
        lines += ["", "## Figures", ""] + [f"![{f}](figures/{f})" for f in summary["figures"]]
    return "\n".join(lines) + "\n"


def _equal_false_alarms_markdown(equal: dict | None) -> list[str]:
    if not equal:
        return []
    names = list(equal["diagnosers"])
    lines = ["", f"## At equal false alarms: {equal['false_alarm_runs']} of {equal['fault_free_runs']} fault-free runs", "",
             "Each diagnoser's thresholds × the smallest factor at which only that many of its fault-free runs alarm "
             "(a point of its ROC curve, chosen on these runs: a comparison, not thresholds to deploy); "
             "detected / faults.", "",
             "| kind~profile | " + " | ".join(names) + " |", "|---|" + "---|" * len(names),
             "| threshold factor | " + " | ".join(f"{equal['diagnosers'][n]['threshold_scale']:.3g}" for n in names) + " |",
             "| all faults | " + " | ".join(_pct(equal["diagnosers"][n]["detection"]) for n in names) + " |"]
    kinds = sorted({k for n in names for k in equal["diagnosers"][n]["by_kind_profile"]})
    for k in kinds:
        cells = []
        for n in names:
            b = equal["diagnosers"][n]["by_kind_profile"].get(k)
            cells.append("–" if b is None else f"{b['detected']}/{b['faults']}")
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    return lines


def write_outputs(result: CampaignResult, execution: dict | None = None) -> dict:
    """results.parquet, campaign.json, figures/ and report.md in the campaign folder; returns campaign.json's dict."""
    out = Path(result.out)
    table = result.table
    table.to_parquet(out / "results.parquet", index=False)
    metrics = result.metrics()
    firsts = table.drop_duplicates("index")
    errors = firsts[firsts["error"].notna()]
    summary = {
        "spec": result.spec_dict,
        "runs": {"finished": int(len(firsts)), "fault_free": int((~firsts["faulty"]).sum()),
                 "faulty": int(firsts["faulty"].sum()), "errors": int(len(errors))},
        "diagnosers": metrics,
        "equal_false_alarms": result.at_equal_false_alarms(),
        "errors": [{"index": int(r["index"]), "error": str(r["error"])} for _, r in errors.iterrows()],
        "execution": execution or {},
        "units": {**UNITS, "rate": "fraction of runs", "ci95": "Clopper–Pearson exact 95 % interval of the rate",
                  "delay_median": "s", "delay_p90": "s", "min_detectable_size": "fraction of the target's limit",
                  "min_detectable_magnitude": "'unit' of the entry",
                  "threshold_scale": "1 (the factor on the diagnoser's thresholds at the equal false-alarm count)"},
    }
    summary["figures"] = _figures(result, metrics)
    (out / "campaign.json").write_text(json.dumps(_jsonable(summary), indent=2, allow_nan=False) + "\n")
    (out / "report.md").write_text(report_markdown(_jsonable(summary)))
    return summary
