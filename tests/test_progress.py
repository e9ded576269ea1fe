"""robofdi.progress: a bar per named stage on a terminal that ends at 100 %, a few plain lines elsewhere."""
from __future__ import annotations

import io

import pytest

from robofdi import RobofdiError
from robofdi.progress import Progress, format_seconds


class Stream(io.StringIO):
    """A text stream that says whether it is a terminal."""

    def __init__(self, tty: bool):
        super().__init__()
        self.tty = tty

    def isatty(self):
        return self.tty


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def _job(progress: Progress, clock: Clock, steps: int = 5000, runs: int = 3):
    """Two stages as an experiment runs them: a calibration of ``steps`` ticks, then ``runs`` runs."""
    with progress.stage("calibration: 4 motions", total=steps) as tick:
        for _ in range(steps):
            tick(1)
            clock.t += 0.01
    progress.note("thresholds calibrated")
    with progress.stage("runs", total=runs, unit="run") as tick:
        for _ in range(runs):
            tick(1)
            clock.t += 1.0


def test_not_a_tty_gives_a_few_plain_lines():
    stream, clock = Stream(tty=False), Clock()
    progress = Progress("ch3-actuator", stream=stream, clock=clock, min_interval=5.0)
    assert progress.mode == "plain"
    _job(progress, clock)
    lines = stream.getvalue().splitlines()
    # 50 s of calibration, a line at most every 5 s: start, ≤ 9 intermediate, end; note; start and end of the runs
    assert len(lines) <= 14, lines
    assert lines[0] == "ch3-actuator: calibration: 4 motions: started, 5000 steps"
    assert "ch3-actuator: calibration: 4 motions: done in 50.0 s (5000 steps)" in lines
    assert "ch3-actuator: thresholds calibrated" in lines
    assert lines[-2:] == ["ch3-actuator: runs: started, 3 runs", "ch3-actuator: runs: done in 3.0 s (3 runs)"]
    assert not any("\r" in line or "it/s" in line for line in lines)
    percents = [line for line in lines if " % (" in line]
    assert percents and all(line.split(": ")[-1].split(" %")[0].isdigit() for line in percents)


def test_plain_lines_are_throttled_and_capped_at_ten_per_stage():
    stream, clock = Stream(tty=False), Clock()
    progress = Progress("x", stream=stream, clock=clock, min_interval=0.0)
    with progress.stage("replay", total=100_000) as tick:
        for _ in range(100_000):
            tick(1)
            clock.t += 1.0
    lines = stream.getvalue().splitlines()
    assert len(lines) == 11          # start, 10 % … 90 %, end: never one line per update
    stream, clock = Stream(tty=False), Clock()
    progress = Progress("x", stream=stream, clock=clock, min_interval=1e9)
    with progress.stage("replay", total=100_000) as tick:
        tick(100_000)
    assert len(stream.getvalue().splitlines()) == 2


def test_tty_bar_per_stage_reaches_its_total():
    stream, clock = Stream(tty=True), Clock()
    progress = Progress("arm", stream=stream, clock=clock)
    assert progress.mode == "bar"
    _job(progress, clock, steps=2000)
    out = stream.getvalue()
    finals = [chunk.strip() for chunk in out.replace("\n", "\r").split("\r") if chunk.strip()]
    calibration = [c for c in finals if c.startswith("arm: calibration: 4 motions")]
    runs = [c for c in finals if c.startswith("arm: runs")]
    assert "100%" in calibration[-1] and "2000/2000" in calibration[-1]
    assert "100%" in runs[-1] and "3/3" in runs[-1] and "run" in runs[-1]
    assert "arm: thresholds calibrated" in out


def test_tty_bar_ends_at_100_percent_when_the_estimate_was_high():
    stream = Stream(tty=True)
    progress = Progress("arm", stream=stream)
    with progress.stage("calibration", total=1000) as tick:
        tick(970)                   # the estimate counted a few ticks that never come
    last = [c.strip() for c in stream.getvalue().replace("\n", "\r").split("\r") if c.strip()][-1]
    assert "100%" in last and "970/970" in last
    assert progress.stages[0].n == 970 and progress.stages[0].seconds is not None


def test_failed_stage_says_stopped_and_is_not_completed():
    stream = Stream(tty=False)
    progress = Progress("arm", stream=stream)
    with pytest.raises(ValueError), progress.stage("run", total=10) as tick:
        tick(4)
        raise ValueError("boom")
    assert "arm: run: stopped in" in stream.getvalue()
    stream = Stream(tty=True)
    progress = Progress("arm", stream=stream)
    with pytest.raises(ValueError), progress.stage("run", total=10) as tick:
        tick(4)
        raise ValueError("boom")
    assert "4/10" in stream.getvalue() and "100%" not in stream.getvalue()


def test_quiet_and_mode_override(monkeypatch):
    stream = Stream(tty=True)
    progress = Progress("x", enabled=False, stream=stream)
    _job(progress, Clock(), steps=10)
    assert stream.getvalue() == "" and progress.mode == "off"
    monkeypatch.setenv("ROBOFDI_PROGRESS", "plain")
    assert Progress("x", stream=Stream(tty=True)).mode == "plain"
    monkeypatch.setenv("ROBOFDI_PROGRESS", "loud")
    with pytest.raises(RobofdiError, match="ROBOFDI_PROGRESS"):
        Progress("x", stream=Stream(tty=True))
    monkeypatch.delenv("ROBOFDI_PROGRESS")
    assert Progress.of(False).mode == "off"
    p = Progress("y", mode="off")
    assert Progress.of(p) is p


def test_bad_total_is_a_clear_error():
    with pytest.raises(RobofdiError, match="'total'"), Progress("x", mode="off").stage("s", total=-1):
        pass


def test_format_seconds():
    assert format_seconds(3.21) == "3.2 s"
    assert format_seconds(125) == "2 min 05 s"
    assert format_seconds(3720) == "1 h 02 min"


def test_skipped_stage_is_one_line_and_opens_at_its_first_tick():
    for tty in (False, True):
        stream = Stream(tty=tty)
        progress = Progress("arm", stream=stream)
        with progress.stage("calibration: 6 motions", total=5000, skipped="from the cache"):
            pass                              # the cache answered: no tick
        assert stream.getvalue().strip().startswith("arm: calibration: 6 motions: from the cache (")
        assert len(stream.getvalue().splitlines()) == 1 and "%" not in stream.getvalue()
    stream = Stream(tty=False)
    progress = Progress("arm", stream=stream)
    with progress.stage("calibration: 6 motions", total=5000, skipped="from the cache") as tick:
        tick(5000)
    assert stream.getvalue().splitlines()[0] == "arm: calibration: 6 motions: started, 5000 steps"
    assert "from the cache" not in stream.getvalue()


def test_stage_without_total_is_a_start_and_an_end_line():
    for tty in (False, True):
        stream, clock = Stream(tty=tty), Clock()
        progress = Progress("arm", stream=stream, clock=clock)
        with progress.stage("run folder: figures, replay"):
            clock.t += 4.0
        assert stream.getvalue().splitlines() == ["arm: run folder: figures, replay: started",
                                                  "arm: run folder: figures, replay: done in 4.0 s"]


def test_campaign_stage_resumes_from_initial_and_shows_errors():
    stream = Stream(tty=False)
    progress = Progress("campaign arm", stream=stream)
    with progress.stage("runs", 10, unit="run", initial=4) as bar:
        for _ in range(6):
            bar(1)
        bar.set_postfix(errors=1)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "campaign arm: runs: started, 10 runs (4 already done)"
    assert lines[-1].endswith("(10 runs, errors=1)")


def test_only_the_progress_module_draws_bars():
    """Every long job goes through robofdi.progress: no other module of the package, its experiments or viz
    imports tqdm (which wrote one line per update into pipes and logs)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    users = [p.relative_to(root).as_posix() for folder in ("robofdi", "experiments", "viz")
             for p in sorted((root / folder).rglob("*.py")) if "tqdm" in p.read_text(encoding="utf-8")]
    assert users == ["robofdi/progress.py"]
