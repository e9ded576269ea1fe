"""Labelled event lines on time axes: each fault onset (or switch, or phase edge) named where it is drawn, so a
figure reads without its caption. Shared by the experiments' and the campaign's figures."""
from __future__ import annotations

from collections.abc import Iterable, Mapping

__all__ = ["events_of", "event_lines"]


def events_of(items: Iterable) -> list[tuple[float, str]]:
    """``(time [s], label)`` pairs from faults (:class:`~robofdi.faults.Fault` or its dict form: the label is
    ``<name> on <target>``), ``(time, label)`` pairs, or bare times (no label)."""
    out = []
    for item in items:
        if isinstance(item, Mapping):
            t, name, target = item["onset"], item.get("name", "fault"), item.get("target")
        elif hasattr(item, "onset"):
            t, name, target = item.onset, getattr(item, "name", "fault"), getattr(item, "target", None)
        elif isinstance(item, tuple):
            (t, name), target = item, None
        else:
            t, name, target = item, "", None
        label = f"{name} on {target}" if target and target not in str(name) else str(name)
        out.append((float(t), label))
    return out


def event_lines(ax, items: Iterable, label: bool = True, color: str = "0.35", ls: str = ":", lw: float = 0.9,
                fontsize: float = 6.5) -> list:
    """A vertical line per event on ``ax``; with ``label``, its name and time (``thruster2_off on thruster2,
    78 s``) just right of the line at the top of the panel, staggered downwards when events are close. Returns the
    text artists."""
    events = sorted(events_of(items))
    lo, hi = ax.get_xlim()
    span = max(hi - lo, 1e-12)
    texts, level, last = [], 0, None
    for t, text in events:
        ax.axvline(t, color=color, ls=ls, lw=lw)
        if not (label and text):
            continue
        level = level + 1 if last is not None and (t - last) < 0.12 * span else 0
        last = t
        texts.append(ax.text(t, 0.97 - 0.11 * (level % 4), f" {text}, {t:g} s", transform=ax.get_xaxis_transform(),
                             fontsize=fontsize, color=color, va="top", ha="left", clip_on=True,
                             bbox={"boxstyle": "square,pad=0.1", "facecolor": "white", "edgecolor": "none", "alpha": 0.7}))
    return texts
