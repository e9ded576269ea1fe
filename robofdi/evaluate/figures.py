"""Figures in the style of Caccavale & Villani Figs. 2–13: residual components against their thresholds, and
estimated against true fault, per diagnoser."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import LogLocator, MaxNLocator, NullLocator  # noqa: E402

from robofdi.record import Record  # noqa: E402

__all__ = ["plot_residuals", "plot_estimates"]


def save_figure(fig, path: str | Path, dpi: int = 110, tight: bool = True) -> Path:
    """Lay out (``tight``: ``tight_layout``; False for a figure made with a fixed layout, :func:`fixed_grid`),
    write and close a figure (every robofdi figure goes through here); returns the path."""
    path = Path(path)
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def fixed_grid(rows: int, cols: int, axes_size: tuple[float, float], margins=(0.85, 0.15, 0.5, 0.45),
               gaps: tuple[float, float] = (0.95, 0.28), **subplots):
    """A figure of rows × cols axes of ``axes_size`` (width, height) [in] with fixed ``margins`` (left, right,
    bottom, top) [in] and ``gaps`` (between columns, between rows) [in]: a layout set once, so saving needs no
    ``tight_layout`` (which measures every tick label of every axis, the most of a figure's cost). Returns (fig,
    axes) as ``plt.subplots(..., squeeze=False)``."""
    (w, h), (left, right, bottom, top), (gx, gy) = axes_size, margins, gaps
    width, height = left + right + cols * w + (cols - 1) * gx, bottom + top + rows * h + (rows - 1) * gy
    fig = plt.figure(figsize=(width, height))
    axes = fig.subplots(rows, cols, squeeze=False, gridspec_kw=dict(
        left=left / width, right=1 - right / width, bottom=bottom / height, top=1 - top / height,
        wspace=gx / w, hspace=gy / h), **subplots)
    return fig, axes


def _onsets(ax, faults, label: bool = False):
    """Dotted lines at the true fault onsets; ``label``: each named (``<fault> on <target>``) at the panel's top."""
    for f in faults:
        ax.axvline(f["onset"], color="0.5", lw=0.8, ls=":")
        if label:
            ax.text(f["onset"], 1.0, f" {f.get('name', 'fault')} on {f.get('target', '?')}", transform=ax.get_xaxis_transform(),
                    fontsize=6, color="0.3", va="bottom", ha="left", clip_on=False)


def plot_residuals(record: Record, diagnoser: str, path: str | Path) -> Path:
    """One panel per residual component: |r_i| (solid), threshold (dashed), alarm samples (red), fault onsets."""
    tr = record.diagnosers[diagnoser]
    m = len(tr.components)
    cols = 2 if m > 6 else 1
    rows = int(np.ceil(m / cols))
    fig, axes = fixed_grid(rows, cols, (4.5, 0.95), sharex=True)
    faults = record.meta.get("faults", [])
    for j, comp in enumerate(tr.components):
        ax = axes[j % rows, j // rows]
        thr = tr.threshold[j] if np.isfinite(tr.threshold[j]) else np.max(np.abs(tr.residual[:, j])) + 1e-12
        floor = thr * 1e-3
        r = np.maximum(np.abs(tr.residual[:, j]), floor)
        ax.plot(tr.time, r, lw=0.8, color="C0")
        ax.axhline(tr.threshold[j], color="k", ls="--", lw=0.8)
        hit = tr.alarm[:, j]
        if hit.any():
            ax.plot(tr.time[hit], r[hit], ".", ms=2, color="C3")
        _onsets(ax, faults, label=j % rows == 0)
        unit = (tr.units.get("residual") or [""] * m)[j]
        ax.set_ylabel(f"|{comp}| [{unit}]" if unit else comp, fontsize=7)
        ax.tick_params(labelsize=7)
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(LogLocator(numticks=3))    # a few decades labelled, no minor ticks: cheap to draw
        ax.yaxis.set_minor_locator(NullLocator())
        ax.set_ylim(floor, max(r.max(), thr) * 2)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].xaxis.set_major_locator(MaxNLocator(5))       # shared by every panel (sharex)
    fig.suptitle(f"{record.scenario}: {diagnoser} residuals |r_i| vs thresholds (dashed); alarms in red; true fault "
                 "onsets dotted", fontsize=9)
    return save_figure(fig, path, tight=False)


def plot_estimates(record: Record, path: str | Path, diagnosers=None) -> Path:
    """For each fault: its true value and every diagnoser's identified magnitude after isolation."""
    faults = record.meta.get("faults", [])
    names = list(diagnosers or record.diagnosers)
    fig, axes = plt.subplots(max(len(faults), 1), 1, figsize=(7, 2.4 * max(len(faults), 1)), squeeze=False)
    for ax, f in zip(axes[:, 0], faults):
        lab = record.faults[f["name"]]
        ax.plot(record.time, lab.value, color="k", lw=2, label="true")
        for i, name in enumerate(names):
            tr = record.diagnosers[name]
            if f["target"] in tr.estimate_components:
                est = tr.estimate[:, tr.estimate_components.index(f["target"])]
                ax.plot(tr.time, est, lw=0.9, color=f"C{i}", label=name)
        ax.set_title(f"{f['name']} ({f['kind']} on {f['target']})", fontsize=9)
        ax.set_ylabel(f"fault [{lab.unit}]" if lab.unit else "fault", fontsize=8)
        ax.set_xlim(f["onset"] - 0.2, record.time[-1])
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, ncol=3)
    axes[-1, 0].set_xlabel("time [s]")
    return save_figure(fig, path)
