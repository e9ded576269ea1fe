"""Progress of long jobs, one named stage at a time — the only place that draws progress.

A job (an experiment, a campaign) makes one :class:`Progress` and runs its work in stages::

    progress = Progress("ch3-actuator")
    with progress.stage("calibration: 2 motions", total=46_012, unit="step", skipped="from the cache") as tick:
        calibration(scenario, progress=tick)         # the library calls tick(n) as it goes
    with progress.stage("run folder: figures, replay"):
        write_run_folder(...)                         # no total: a line when it starts and one when it ends

On a terminal every stage gets its own tqdm bar (``ch3-actuator: calibration: 2 motions 100%|███| …``) with its own
total, unit and rate, so a rate never spans two stages and no ETA mixes them; when the stage ends the bar is set
to what was really done, so it always ends at 100 %, and it stays on screen with the stage's time. A stage
given ``skipped`` shows nothing until its first tick and, if none comes (a cached calibration), one line
``calibration: 2 motions: from the cache``. A stage without a total is two lines. Anywhere else
(a pipe, a log file, a CI job) a few plain lines: the stage's start, every ~10 % at most once per
``min_interval`` seconds, its end with its time. ``ROBOFDI_PROGRESS=bar|plain|off`` overrides the choice.

The library never draws: loops, replays and calibrations take a ``progress`` callable ``(n) -> None`` (n units
done since the last call) and the stage object is one.
"""
from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from typing import TextIO

from robofdi.errors import RobofdiError

__all__ = ["Progress", "Stage", "MODES", "format_seconds", "run_ticks"]

#: ``bar``: tqdm bars (terminals); ``plain``: a few lines (pipes, logs); ``off``: nothing.
MODES = ("bar", "plain", "off")


def format_seconds(seconds: float) -> str:
    """``3.2 s``, ``2 min 05 s``, ``1 h 02 min``."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, sec = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {sec:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


def run_ticks(duration: float, control_hz: float) -> int:
    """Progress ticks of one closed-loop run of ``duration`` s (:meth:`robofdi.loop.ClosedLoop.run` ticks once per
    control sample, both ends included)."""
    return int(round(duration * control_hz)) + 1


def _units(n, unit: str) -> str:
    """``1 run``, ``12 runs``, ``? steps``."""
    return f"{n} {unit}{'' if n == 1 or not unit else 's'}"


def _is_tty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class Stage:
    """One named stage: call it with the units done since the last call (``stage(1)``; ``stage.update(n)`` too)."""

    def __init__(self, owner: Progress, name: str, total: int | None, unit: str, initial: int = 0,
                 skipped: str | None = None):
        if total is not None and (isinstance(total, bool) or int(total) != total or total < 0):
            raise RobofdiError(f"progress stage {name!r}: field 'total' must be an integer >= 0 or None, got {total!r}")
        self.owner, self.name, self.unit = owner, name, unit
        self.total = None if total is None else int(total)
        self.n = int(initial)
        self._start = owner._clock()
        self._bar = None
        self._next_percent = 10
        self._last_line = self._start
        self.postfix: dict = {}
        self.seconds: float | None = None
        self.skipped = skipped
        self._opened = False

    # ------------------------------------------------------------------ what the library calls
    def __call__(self, n: int = 1) -> None:
        if not self._opened:
            self._open()
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
        elif self.owner.mode == "plain" and self.total:
            percent = 100 * self.n // self.total
            if percent >= self._next_percent:
                now = self.owner._clock()
                if percent < 100 and now - self._last_line >= self.owner.min_interval:
                    self.owner._line(f"{self.label}: {percent} % ({self.n}/{_units(self.total, self.unit)}, "
                                     f"{format_seconds(now - self._start)})")
                    self._last_line = now
                self._next_percent = (percent // 10 + 1) * 10

    update = __call__

    def set_postfix(self, **values) -> None:
        """Extra values shown after the bar (e.g. ``errors=2``); plain lines show them at the stage's end."""
        self.postfix = values
        if self._bar is not None:
            self._bar.set_postfix(**values)

    # ------------------------------------------------------------------ drawing
    @property
    def label(self) -> str:
        return f"{self.owner.title}: {self.name}" if self.owner.title else self.name

    def _open(self) -> None:
        self._opened = True
        if self.owner.mode == "bar" and self.total is not None:
            from tqdm.auto import tqdm

            self._bar = tqdm(total=self.total, initial=self.n, desc=self.label, unit=self.unit,
                             unit_scale=bool(self.total and self.total >= 10_000), file=self.owner.stream,
                             leave=True, dynamic_ncols=True, smoothing=0.1, mininterval=0.2)
        elif self.owner.mode != "off":
            start = f" ({self.n} already done)" if self.n else ""
            size = "" if self.total is None else f", {_units(self.total, self.unit)}"
            self.owner._write(f"{self.label}: started{size}{start}")

    def _close(self, failed: bool) -> None:
        self.seconds = self.owner._clock() - self._start
        if not self._opened:                             # skipped: no tick came
            if self.owner.mode != "off" and not failed:
                self.owner._write(f"{self.label}: {self.skipped} ({format_seconds(self.seconds)})")
            return
        if self._bar is not None:
            if not failed and self.total != self.n:      # what was really done: the bar ends at 100 %
                self._bar.total = self.n
                self._bar.refresh()
            self._bar.close()
        elif self.owner.mode != "off":
            extra = "".join(f", {k}={v}" for k, v in self.postfix.items())
            state = "stopped" if failed else "done"
            done = f"{_units(self.n, self.unit)}{extra}" if self.total is not None or self.n else extra[2:]
            self.owner._write(f"{self.label}: {state} in {format_seconds(self.seconds)}" + (f" ({done})" if done else ""))


class Progress:
    """Progress of one job (``title``), drawn on ``stream`` (default: stderr) stage by stage.

    ``enabled=False`` (``--quiet``) draws nothing; ``mode`` forces ``bar``, ``plain`` or ``off`` (default:
    $ROBOFDI_PROGRESS, else ``bar`` when ``stream`` is a terminal and ``plain`` otherwise). ``min_interval``: the
    least time [s] between two intermediate plain lines of a stage.
    """

    def __init__(self, title: str = "", enabled: bool = True, stream: TextIO | None = None, mode: str | None = None,
                 min_interval: float = 10.0, clock=time.monotonic):
        self.title = title
        self.stream = stream if stream is not None else sys.stderr
        mode = mode or os.environ.get("ROBOFDI_PROGRESS") or ("bar" if _is_tty(self.stream) else "plain")
        if mode not in MODES:
            raise RobofdiError(f"progress mode: expected one of {', '.join(MODES)} (ROBOFDI_PROGRESS), got {mode!r}")
        self.mode = mode if enabled else "off"
        self.min_interval = float(min_interval)
        self._clock = clock
        self.stages: list[Stage] = []

    @classmethod
    def of(cls, progress, title: str = "") -> Progress:
        """``progress`` as a Progress: one already (kept), or a bool (an experiment's ``progress=`` argument)."""
        return progress if isinstance(progress, Progress) else cls(title, enabled=bool(progress))

    @contextmanager
    def stage(self, name: str, total: int | None = None, unit: str = "step", initial: int = 0,
              skipped: str | None = None):
        """A stage of ``total`` ``unit``s (``initial`` already done); yields the :class:`Stage` to call.
        ``skipped``: what to say if no tick comes (the stage is drawn from its first tick on)."""
        stage = Stage(self, name, total, unit, initial, skipped)
        self.stages.append(stage)
        if skipped is None:
            stage._open()
        failed = True
        try:
            yield stage
            failed = False
        finally:
            stage._close(failed)

    def note(self, text: str) -> None:
        """One line between stages (e.g. ``calibration: cached``), on a terminal too."""
        if self.mode == "off":
            return
        self._write(f"{self.title}: {text}" if self.title else text)

    def _write(self, text: str) -> None:
        if self.mode == "bar":          # above any open bar
            from tqdm.auto import tqdm

            tqdm.write(text, file=self.stream)
        else:
            self._line(text)

    def _line(self, text: str) -> None:
        print(text, file=self.stream, flush=True)
