"""Figures in the style of Caccavale & Villani Figs. 2–13: residual components against their thresholds, and
estimated against true fault, per diagnoser."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullLocator  # noqa: E402

from robofdi.record import Record  # noqa: E402

__all__ = ["plot_residuals", "plot_residual_figures", "plot_estimates", "decade_label"]


def save_figure(fig, path: str | Path, dpi: int = 110, tight: bool = True, close: bool = True) -> Path:
    """Lay out (``tight``: ``tight_layout``; False for a figure made with a fixed layout, :func:`fixed_grid`),
    write and close a figure (every robofdi figure goes through here, but the residual figures, whose reused axes
    close once after the last of them: :func:`plot_residual_figures`; ``close`` False keeps a figure whose axes
    are drawn again); returns the path."""
    path = Path(path)
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    if close:
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


def _onsets(ax, faults, label: bool = False) -> list:
    """Dotted lines at the true fault onsets; ``label``: each named (``<fault> on <target>``) at the panel's top.
    Returns the artists drawn."""
    drawn = []
    for f in faults:
        drawn.append(ax.axvline(f["onset"], color="0.5", lw=0.8, ls=":"))
        if label:
            drawn.append(ax.text(f["onset"], 1.0, f" {f.get('name', 'fault')} on {f.get('target', '?')}",
                                 transform=ax.get_xaxis_transform(), fontsize=6, color="0.3", va="bottom", ha="left",
                                 clip_on=False))
    return drawn


def decade_label(value: float, _position=None) -> str:
    """A log axis' tick label at a power of ten ("0.01", "1", "100"; "1e-5", "1e4" beyond three decades), ""
    elsewhere. Plain text, so the label needs no mathtext parse (matplotlib's default log labels are mathtext, a
    large part of a panel's cost)."""
    if not value > 0:
        return ""
    exponent = int(round(np.log10(value)))
    if abs(value / 10.0 ** exponent - 1) > 1e-9:
        return ""
    return f"{10.0 ** exponent:g}" if -3 <= exponent <= 3 else f"1e{exponent}"


class _ResidualPanels:
    """The panels of residual figures of one layout (rows × cols, m components), drawn once and reused: each
    figure of the layout draws its curves, saves, and removes them again, so the axes and their tick artists (most
    of a panel's cost in matplotlib) are made once per layout, not once per figure."""

    def __init__(self, rows: int, cols: int, m: int):
        self.rows, self.m = rows, m
        self.fig, self.axes = fixed_grid(rows, cols, (4.5, 0.95))
        self.used = [self.axes[j % rows, j // rows] for j in range(m)]
        for j in range(m, rows * cols):
            self.axes[j % rows, j // rows].set_axis_off()
        for j, ax in enumerate(self.used):
            last = j % rows == rows - 1 or j == m - 1          # the lowest panel of its column: time labelled there
            ax.xaxis.set_major_locator(MaxNLocator(5) if last else NullLocator())
            if last:
                ax.set_xlabel("time [s]")
            ax.tick_params(labelsize=7)
            ax.set_yscale("log")
            ax.yaxis.set_major_locator(LogLocator(numticks=3))    # a few decades labelled, no minor ticks
            ax.yaxis.set_minor_locator(NullLocator())
            ax.yaxis.set_major_formatter(FuncFormatter(decade_label))
        self.title = self.fig.suptitle("", fontsize=9)

    def draw(self, record: Record, diagnoser: str, path: str | Path) -> Path:
        tr = record.diagnosers[diagnoser]
        faults = record.meta.get("faults", [])
        span = tr.time[-1] - tr.time[0] if len(tr.time) > 1 else 1.0
        units = tr.units.get("residual") or [""] * self.m
        drawn = []
        for j, (ax, comp) in enumerate(zip(self.used, tr.components)):
            thr = tr.threshold[j] if np.isfinite(tr.threshold[j]) else np.max(np.abs(tr.residual[:, j])) + 1e-12
            floor = thr * 1e-3
            r = np.maximum(np.abs(tr.residual[:, j]), floor)
            drawn += ax.plot(tr.time, r, lw=0.8, color="C0")
            drawn.append(ax.axhline(tr.threshold[j], color="k", ls="--", lw=0.8))
            hit = tr.alarm[:, j]
            if hit.any():
                drawn += ax.plot(tr.time[hit], r[hit], ".", ms=2, color="C3")
            drawn += _onsets(ax, faults, label=j % self.rows == 0)
            ax.set_ylabel(f"|{comp}| [{units[j]}]" if units[j] else comp, fontsize=7)
            ax.set_xlim(tr.time[0] - 0.02 * span, tr.time[-1] + 0.02 * span)
            ax.set_ylim(floor, max(r.max(), thr) * 2)
        self.title.set_text(f"{record.scenario}: {diagnoser} residuals |r_i| vs thresholds (dashed); alarms in red; "
                            "true fault onsets dotted")
        path = Path(path)
        self.fig.savefig(path, dpi=110)
        for artist in drawn:
            artist.remove()
        return path

    def close(self) -> None:
        plt.close(self.fig)


def _layout(record: Record, diagnoser: str) -> tuple[int, int, int]:
    m = len(record.diagnosers[diagnoser].components)
    cols = 2 if m > 6 else 1
    return int(np.ceil(m / cols)), cols, m


def plot_residual_figures(record: Record, paths) -> list[Path]:
    """One residual figure per diagnoser (``paths``: diagnoser → file; see :func:`plot_residuals`), the diagnosers
    of one panel layout drawn on one reused set of axes. Returns the paths written."""
    panels: dict[tuple, _ResidualPanels] = {}
    written = []
    try:
        for diagnoser, path in paths.items():
            key = _layout(record, diagnoser)
            if key not in panels:
                panels[key] = _ResidualPanels(*key)
            written.append(panels[key].draw(record, diagnoser, path))
    finally:
        for p in panels.values():
            p.close()
    return written


def plot_residuals(record: Record, diagnoser: str, path: str | Path) -> Path:
    """One panel per residual component: |r_i| (solid), threshold (dashed), alarm samples (red), fault onsets
    (dotted). Two columns for more than six components; time is labelled on each column's lowest panel."""
    return plot_residual_figures(record, {diagnoser: path})[0]


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
