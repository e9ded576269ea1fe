"""The run folder every experiment writes: record.h5, summary.json, figures/, replay.html."""
from __future__ import annotations

from collections.abc import Mapping
from contextlib import contextmanager
from pathlib import Path

from robofdi.errors import RobofdiError
from robofdi.evaluate.figures import plot_estimates, plot_residual_figures
from robofdi.evaluate.headline import settle_lead
from robofdi.evaluate.summary import write_summary
from robofdi.record import Record

__all__ = ["prepare_run_dir", "write_run_folder", "keep_partial", "replay_writer", "PARTIAL"]

#: what an interrupted or failed run recorded, in its run folder
PARTIAL = "partial.h5"


#: what a run prints (once) when it writes no replay because the optional viz extra is not installed
NO_REPLAY_NOTE = ("robofdi: no replay.html: the Meshcat replay needs the viz extra (pip install 'robofdi[viz]'; "
                  "then `robofdi view RUN` replays the saved record)")
_noted = False


def replay_writer(name: str = "write_replay_html", module: str = "robofdi.viz"):
    """The replay writer ``module.name`` (``robofdi.viz.write_replay_html``, or ``robofdi.viz.hydraulic.
    write_hydraulic_replay``), or ``None`` when meshcat (the optional ``viz`` extra) is not installed — then the
    run goes on without its replay and says so once, on stderr."""
    global _noted
    import importlib
    import importlib.util
    import sys

    if importlib.util.find_spec("meshcat") is None:
        if not _noted:
            print(NO_REPLAY_NOTE, file=sys.stderr)
            _noted = True
        return None
    return getattr(importlib.import_module(module), name)


@contextmanager
def keep_partial(run_dir: Path):
    """A run that fails (or is interrupted) inside this block keeps what it recorded: ``run_dir/partial.h5``
    (its top-level attribute ``partial`` is 1). A second signal while it is saved leaves no torn file."""
    from robofdi.loop import RunAborted, RunInterrupted

    try:
        yield
    except (RunAborted, RunInterrupted) as exc:
        if exc.record is None:               # a streamed run (ClosedLoop.run_to_file) kept its own partial file
            raise
        try:
            exc.partial_path = exc.record.save(run_dir / PARTIAL)
        except (OSError, RobofdiError, KeyboardInterrupt):
            exc.partial_path = None
        raise


def prepare_run_dir(out: str | Path, name: str, seed: int) -> Path:
    """``out/name-seedN``, created; a path that cannot be created is one clear error naming it."""
    run_dir = Path(out) / f"{name}-seed{seed}"
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RobofdiError(f"--out: cannot create the run folder {str(run_dir)!r}: {exc.strerror or exc}") from None
    return run_dir


def write_run_folder(run_dir: Path, record: Record, summary: Mapping, others: Mapping[str, Record] | None = None,
                     replay: bool = True) -> Path:
    """Save the record (and ``others`` as ``<key>.h5``), the summary, one residual figure per diagnoser, the
    estimates figure and the self-contained Meshcat replay. The run's lead diagnoser is decided first
    (:func:`~robofdi.evaluate.headline.settle_lead`) and written into the summary and the record, so the printed
    table and the replay lead with the same one. The summary is written first (small, and all a full disk
    should not cost); every file is written atomically; a stale ``partial.h5`` of an earlier interrupted run in
    this folder is removed once the records are written."""
    if isinstance(summary, dict):
        settle_lead(summary, record)
    write_summary(summary, run_dir / "summary.json")
    failed = None
    for name, rec in {"record": record, **(others or {})}.items():
        try:
            rec.save(run_dir / f"{name}.h5")
        except OSError as exc:              # a full disk: keep trying the others (a smaller one may fit), then say so
            failed = failed or exc
    if failed is not None:
        raise failed
    (run_dir / PARTIAL).unlink(missing_ok=True)
    figures = run_dir / "figures"
    figures.mkdir(exist_ok=True)
    plot_residual_figures(record, {d: figures / f"residuals_{d}.png" for d in record.diagnosers})
    plot_estimates(record, figures / "estimates.png")
    write = replay_writer() if replay else None
    if write is not None:
        write(record, run_dir / "replay.html")
    return run_dir
