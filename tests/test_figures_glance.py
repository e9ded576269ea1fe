"""Figures read at a glance: onsets labelled where they are drawn, a detection trace on its own axes (not a flat
line under ±20 A of raw current), small multiples instead of overlapping curves (ch4 Fig. 10, the campaign's
detection-against-size). The figure functions run here on short synthetic records with the real column layout."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from robofdi.evaluate.annotate import event_lines, events_of  # noqa: E402
from robofdi.experiments.ch4_auv import current_figure, thruster_figure  # noqa: E402
from robofdi.faults import Fault  # noqa: E402
from robofdi.record import DiagnoserTrace, Record  # noqa: E402

THRUSTERS = [f"thruster{i}" for i in range(1, 9)]
FAULTS = (Fault("thruster2_off", "actuator_float", "thruster2", onset=7.8),
          Fault("thruster6_off", "actuator_float", "thruster6", onset=9.0))


def _auv_record(drop: bool, seed: int = 0) -> Record:
    """12 s at 10 Hz: thrust demands, thruster 2 and 6 zeroed from their onsets when ``drop``; motor currents of
    ±20 A, and a current-map trace whose residual steps by 0.6 A at thruster 2's onset against a 0.2 A threshold."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 12.0, 0.1)
    u = 20.0 * np.sin(0.7 * t[:, None] + np.arange(8)) + rng.normal(0, 0.5, (t.size, 8))
    if drop:
        u[t >= FAULTS[0].onset, 1] = 0.0
        u[t >= FAULTS[1].onset, 5] = 0.0
    y = np.zeros((t.size, 13 + 16))
    y[:, 13 + 8:] = u                                     # the motor currents [A] track the demands here
    r = rng.normal(0, 0.05, (t.size, 8))
    r[t >= FAULTS[0].onset, 1] += 0.6
    thr = np.full(8, 0.2)
    trace = DiagnoserTrace(time=t, residual=r, threshold=thr, alarm=np.abs(r) > thr,
                           isolated=np.where(t >= FAULTS[0].onset + 0.3, "thruster2", ""), estimate=np.zeros((t.size, 0)),
                           components=THRUSTERS)
    ref = np.column_stack([np.sin(0.2 * t), np.cos(0.2 * t), np.full(t.size, 2.0)])
    return Record(system="auv", scenario="test", seed=seed, rates={}, time=t, truth_state=ref + 0.01,
                  signals={"y_meas": y, "reference": ref, "u": u}, diagnosers={"current_map": trace}, u_applied=u,
                  columns={"truth/u_applied": THRUSTERS, "signals/u": THRUSTERS})


def _texts(ax) -> list[str]:
    return [t.get_text() for t in ax.texts]


def test_events_of_names_faults_dicts_pairs_and_bare_times():
    """A fault is named with its target unless the name already says it (thruster2_off, not "... on thruster2")."""
    assert events_of([FAULTS[0], {"onset": 2, "name": "bias", "target": "joint3"}, (5.0, "switch"), 1.5]) == [
        (7.8, "thruster2_off"), (2.0, "bias on joint3"), (5.0, "switch"), (1.5, "")]


def test_every_onset_line_gets_a_label_and_close_labels_do_not_sit_on_each_other():
    fig, ax = plt.subplots()
    ax.plot([0, 100], [0, 1])
    texts = event_lines(ax, [(10.0, "a"), (11.0, "b"), (60.0, "c")])
    plt.close(fig)
    assert [t.get_text() for t in texts] == [" a, 10 s", " b, 11 s", " c, 60 s"]
    heights = [t.get_position()[1] for t in texts]
    assert heights[0] != heights[1] and heights[2] == heights[0]      # 1 s apart on 100 s: staggered; 50 s: not


def test_fig10_is_one_panel_per_thruster_with_the_faulty_ones_marked():
    records = {k: _auv_record(drop=True, seed=s) for s, k in enumerate(("no_ftc", "oracle", "diagnosed"))}
    fig = thruster_figure(records, FAULTS)
    axes = fig.axes
    plt.close(fig)
    assert len(axes) == 8
    by_name = {ax.get_ylabel().split("\n")[0]: ax for ax in axes}
    assert sorted(by_name) == sorted(THRUSTERS)
    for name, ax in by_name.items():
        # each panel: this thruster only, each variant's raw thrust and its 1 s mean (legend entries)
        raw = {ln.get_gid()[4:]: ln for ln in ax.get_lines() if (ln.get_gid() or "").startswith("raw:")}
        assert sorted(raw) == sorted(records)
        assert all(np.allclose(ln.get_ydata(), records[k].u_applied[:, THRUSTERS.index(name)]) for k, ln in raw.items())
        means = [ln for ln in ax.get_lines() if ln.get_label().endswith("(1 s mean)")]
        assert len(means) == 3 and all(np.ptp(m.get_ydata()) < np.ptp(raw["oracle"].get_ydata()) for m in means)
    drop = by_name["thruster2"]
    assert "faulty from 7.8 s" in drop.get_title("left") and any("thruster2_off" in s and "7.8 s" in s for s in _texts(drop))
    assert "faulty" not in by_name["thruster3"].get_title("left")


def test_fig8_puts_the_detection_trace_on_its_own_axes_at_its_own_scale():
    rec = _auv_record(drop=False)
    fig = current_figure(rec, FAULTS[:1])
    top, bottom = fig.axes
    plt.close(fig)
    assert "current" in top.get_ylabel() and "residual" in bottom.get_ylabel()
    top_span, bottom_span = np.ptp(top.get_ylim()), np.ptp(bottom.get_ylim())
    assert top_span > 35.0                    # the raw current's ±20 A
    assert bottom_span < 2.0                  # the 0.6 A step and the 0.2 A band fill the trace's panel
    assert any("thruster2_off" in s for s in _texts(top))
    assert any("threshold" in h.get_label() for h in bottom.patches + bottom.collections + bottom.get_lines())


def test_campaign_detection_vs_size_is_small_multiples_of_one_curve_each():
    from robofdi.campaign.results import outcome_grid

    rng = np.random.default_rng(0)
    rows = []
    names = [f"d{i}" for i in range(4)]
    for kind in ("actuator_additive", "sensor_bias"):
        for _ in range(12):
            size = float(rng.uniform(0.05, 1.0))
            for j, name in enumerate(names):
                detected = size > 0.1 * (j + 1)
                rows.append({"kind": kind, "diagnoser": name, "size": size, "detected": detected,
                             "delay": 0.01 * (j + 1) if detected else np.nan})
    fig = outcome_grid(pd.DataFrame(rows), names, "detection_vs_size", level=0.9)
    axes = np.array(fig.axes).reshape(2, 4)
    plt.close(fig)
    assert [ax.get_title() for ax in axes[0]] == names
    for c, ax in enumerate(axes[1]):
        coloured = [ln for ln in ax.get_lines() if ln.get_color() == f"C{c}"]
        faint = [ln for ln in ax.get_lines() if ln.get_color() == "0.85"]
        assert coloured and len(faint) == 3               # its own curve, the three others faint behind it
        assert any("n = 12" == s for s in _texts(ax)) and any("P = 0.9" == s for s in _texts(ax))


def _residual_record() -> Record:
    """Two diagnosers with the same 8-component layout and very different scales, and a third with 3 components."""
    t = np.arange(0.0, 12.0, 0.01)
    rng = np.random.default_rng(1)
    traces = {}
    for name, m, scale in (("big", 8, 1e3), ("small", 8, 1e-4), ("few", 3, 1.0)):
        r = scale * rng.normal(0, 0.3, (t.size, m))
        r[t >= 7.8, 1] += 3 * scale
        thr = np.full(m, scale)
        traces[name] = DiagnoserTrace(time=t, residual=r, threshold=thr, alarm=np.abs(r) > thr,
                                      isolated=np.full(t.size, ""), estimate=np.zeros((t.size, 0)),
                                      components=[f"c{i}" for i in range(m)])
    return Record(system="arm", scenario="test", seed=0, rates={}, time=t, truth_state=np.zeros((t.size, 2)),
                  diagnosers=traces, meta={"faults": [{"name": "f", "target": "c1", "onset": 7.8}]})


def test_residual_figures_drawn_on_reused_axes_equal_figures_drawn_alone(tmp_path):
    """plot_residual_figures draws the diagnosers of one panel layout on one set of axes: nothing of the one drawn
    before may be left in the next (pixel for pixel the same PNG as drawn alone)."""
    from matplotlib.image import imread

    from robofdi.evaluate.figures import decade_label, plot_residual_figures, plot_residuals

    rec = _residual_record()
    together = plot_residual_figures(rec, {d: tmp_path / f"together_{d}.png" for d in ("big", "small", "few")})
    assert [p.name for p in together] == ["together_big.png", "together_small.png", "together_few.png"]
    for d in ("small", "few"):
        alone = imread(plot_residuals(rec, d, tmp_path / f"alone_{d}.png"))
        assert np.array_equal(imread(tmp_path / f"together_{d}.png"), alone)
    assert not np.array_equal(imread(tmp_path / "together_big.png"), imread(tmp_path / "alone_small.png"))
    assert [decade_label(v) for v in (1e-5, 1e-3, 1.0, 100.0, 2.0)] == ["1e-5", "0.001", "1", "100", ""]


def test_outcome_figures_on_reused_panels_are_the_pngs_of_fresh_panels(tmp_path):
    """The campaign draws both outcome figures on one OutcomePanels: the second, drawn after the first was removed,
    is byte for byte the PNG that panels made for it alone give."""
    from robofdi.campaign.results import OUTCOMES, OutcomePanels, outcome_grid
    from robofdi.evaluate.figures import save_figure

    rng = np.random.default_rng(3)
    rows = []
    names = [f"d{i}" for i in range(3)]
    for kind in ("actuator_additive", "sensor_bias", "sensor_drift"):
        for _ in range(9):
            size = float(rng.uniform(0.01, 0.5))
            for j, name in enumerate(names):
                detected = size > 0.05 * (j + 1)
                rows.append({"kind": kind, "diagnoser": name, "size": size, "detected": detected,
                             "delay": float(rng.uniform(0.005, 0.4)) if detected else np.nan})
    table = pd.DataFrame(rows)
    panels = OutcomePanels(table, names)
    try:
        reused = [save_figure(panels.draw(what, 0.9), tmp_path / f"reused-{what}.png", tight=False, close=False)
                  for what in OUTCOMES]
    finally:
        panels.close()
    fresh = [save_figure(outcome_grid(table, names, what, 0.9), tmp_path / f"fresh-{what}.png", tight=False)
             for what in OUTCOMES]
    assert [p.read_bytes() for p in reused] == [p.read_bytes() for p in fresh]
