"""The run folder every experiment writes: record.h5, summary.json, figures/, replay.html.

**Figures on demand.** A run folder's generic figures are the residual figure of each diagnoser of the main
record (``figures/residuals_<diagnoser>.png``) and ``figures/estimates.png``. By default a run draws only the lead
diagnoser's residual figure and the estimates (:data:`FIGURE_CHOICES`: ``"lead"``, ``"all"``, ``"none"``; the
command line's ``--figures``); :func:`draw_figures` (``robofdi figures RUN``) draws the others later from the
folder's records, the same PNG as a run with ``--figures all`` writes. The figures an experiment draws with its
own code (a book's figure, e.g. ``fig10_thrusters.png``) are always drawn.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from robofdi.errors import RobofdiError
from robofdi.evaluate.headline import record_lead, settle_lead
from robofdi.evaluate.summary import write_summary
from robofdi.record import Record

__all__ = ["prepare_run_dir", "write_run_folder", "keep_partial", "replay_writer", "PARTIAL", "FIGURE_CHOICES",
           "check_figures", "current_figures", "figures_setting", "residual_figures_left", "draw_figures"]

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


#: which generic figures a run folder draws: the lead diagnoser's residual figure and the estimates (default), every
#: diagnoser's residual figure and the estimates, or none of them (an experiment's own figures are always drawn)
FIGURE_CHOICES = ("lead", "all", "none")
_FIGURES: ContextVar[str] = ContextVar("robofdi_run_figures", default="lead")


def check_figures(where: str, value) -> str:
    """``value`` if it is one of :data:`FIGURE_CHOICES`, else a RobofdiError naming ``where`` (the field or
    option) and the allowed values."""
    if not isinstance(value, str) or value not in FIGURE_CHOICES:
        raise RobofdiError(f"{where} must be one of {', '.join(FIGURE_CHOICES)} (which residual figures a run folder "
                           f"draws), got {value!r}")
    return value


def current_figures() -> str:
    """The figures setting in force (:func:`figures_setting`; default ``"lead"``)."""
    return _FIGURES.get()


@contextmanager
def figures_setting(value: str, where: str = "figures") -> Iterator[str]:
    """Inside this block, :func:`write_run_folder` draws the generic figures ``value`` chooses
    (:data:`FIGURE_CHOICES`) unless it is given its own ``figures``; ``robofdi run --figures`` sets it around an
    experiment. A bad value is a RobofdiError naming ``where``."""
    token = _FIGURES.set(check_figures(where, value))
    try:
        yield value
    finally:
        _FIGURES.reset(token)


def prepare_run_dir(out: str | Path, name: str, seed: int) -> Path:
    """``out/name-seedN``, created; a path that cannot be created is one clear error naming it."""
    run_dir = Path(out) / f"{name}-seed{seed}"
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RobofdiError(f"--out: cannot create the run folder {str(run_dir)!r}: {exc.strerror or exc}") from None
    return run_dir


def write_run_folder(run_dir: Path, record: Record, summary: Mapping, others: Mapping[str, Record] | None = None,
                     replay: bool = True, figures: str | None = None) -> Path:
    """Save the record (and ``others`` as ``<key>.h5``), the summary, the generic figures ``figures`` chooses
    (:data:`FIGURE_CHOICES`; ``None``: the setting in force, :func:`figures_setting`, by default ``"lead"``: the
    lead diagnoser's residual figure and the estimates figure; the others are drawn on demand by
    :func:`draw_figures`) and the self-contained Meshcat replay. The run's lead diagnoser is decided first
    (:func:`~robofdi.evaluate.headline.settle_lead`) and written into the summary and the record, so the printed
    table, the replay and the figure drawn lead with the same one. The summary is written first (small, and all a
    full disk should not cost); every file is written atomically; a stale ``partial.h5`` of an earlier interrupted
    run in this folder is removed once the records are written, and so are the generic figures of an earlier run
    that this one does not draw again."""
    figures = current_figures() if figures is None else check_figures("figures", figures)
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
    folder = run_dir / "figures"
    folder.mkdir(exist_ok=True)
    scored = summary.get("diagnosers") if isinstance(summary, Mapping) else None
    order = list(scored) if isinstance(scored, Mapping) else []   # the estimates' colours, as robofdi figures has them
    if figures == "all":
        names = list(record.diagnosers)
    elif figures == "lead":
        lead = record_lead(record, scored)
        names = [lead] if lead in record.diagnosers else []
    else:
        names = []
    draw = figures != "none"
    _clear_stale(folder, [f"residuals_{d}.png" for d in names] + ["estimates.png"] * draw, list(others or {}))
    if draw:
        _draw(record, folder, names, estimates=True, order=order)
    write = replay_writer() if replay else None
    if write is not None:
        write(record, run_dir / "replay.html")
    return run_dir


# ---- figures on demand ------------------------------------------------------------------------------------------
def _draw(record: Record, folder: Path, names: Sequence[str], estimates: bool, order: Sequence[str] = ()) -> list[Path]:
    """The residual figures of ``names`` and (``estimates``) the estimates figure into ``folder``; ``order``: the
    diagnosers' order in the estimates figure (its colours), names of the record not in it follow in the record's
    order. Returns the paths written."""
    from robofdi.evaluate.figures import plot_estimates, plot_residual_figures

    written = plot_residual_figures(record, {d: folder / f"residuals_{d}.png" for d in names})
    if estimates:
        written.append(plot_estimates(record, folder / "estimates.png", _ordered(record.diagnosers, order)))
    return written


def _clear_stale(folder: Path, drawn: Sequence[str], others: Sequence[str]) -> None:
    """Remove the generic figures of an earlier run in this folder that this run does not draw again (in
    ``figures/`` but ``drawn``, and in ``figures/<record>/`` of the run's other records), so that every generic
    figure in the folder is this run's: ``residuals_*.png`` and ``estimates.png``."""
    for sub in [folder, *(folder / name for name in others)]:
        if not sub.is_dir():
            continue
        for path in [*sub.glob("residuals_*.png"), sub / "estimates.png"]:
            if not (sub == folder and path.name in drawn):
                path.unlink(missing_ok=True)
        if sub != folder and not any(sub.iterdir()):
            sub.rmdir()


def _ordered(names, order: Sequence[str]) -> list[str]:
    """``names`` in ``order``, those not in it after, in their own order."""
    names = list(names)
    first = [d for d in order if d in names]
    return first + [d for d in names if d not in first]


def _diagnoser_names(path: Path) -> list[str]:
    """The diagnosers of a record file, read from its HDF5 groups without loading the record ([] if unreadable)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return list(f.get("diagnosers", {}))
    except OSError:
        return []


def _figure_folder(run_dir: Path, name: str) -> Path:
    """Where the figures of the record ``name`` go: ``figures/`` for the main record, ``figures/<name>/`` else."""
    return run_dir / "figures" if name == "record" else run_dir / "figures" / name


def residual_figures_left(run_dir: str | Path) -> list[str]:
    """The diagnosers of the run folder's main record (``record.h5``) whose residual figure is not in ``figures/``
    (what ``robofdi figures RUN`` would draw); [] for a folder without ``record.h5``."""
    run_dir = Path(run_dir)
    folder = _figure_folder(run_dir, "record")
    names = _ordered(_diagnoser_names(run_dir / "record.h5"), _summary_order(run_dir))
    return [d for d in names if not (folder / f"residuals_{d}.png").is_file()]


def _records(run_dir: Path) -> list[str]:
    """The records of a run folder by name (``record`` first, then ``<name>.h5`` in name order)."""
    names = sorted(p.stem for p in run_dir.glob("*.h5") if p.is_file())
    return sorted(names, key=lambda n: n != "record")


def draw_figures(run: str | Path, diagnosers: Sequence[str] = (), every: bool = False,
                 record: str = "record") -> list[Path]:
    """Draw a run folder's residual figures (and its estimates figure) from its records, as the run would have
    drawn them with ``figures="all"``: ``robofdi figures RUN``.

    ``run`` is a run folder (or one of its ``.h5`` records, which then names ``record``). ``record``: which of the
    folder's records (``record`` = ``record.h5``, the run the summary scores; an experiment's other runs, e.g.
    ``compensated``, ``fault_free``); the main record's figures go to ``RUN/figures/``, another's to
    ``RUN/figures/<record>/``. Which figures: ``diagnosers`` (drawn, or redrawn); else ``every``: every diagnoser's
    and the estimates (redrawn); else those not drawn yet (the estimates too, if missing). A missing folder or
    record, a record without diagnosers and an unknown diagnoser are each one RobofdiError naming what is
    expected. Returns the paths written."""
    from robofdi.record import load

    run_dir = Path(run)
    if run_dir.suffix == ".h5" and run_dir.is_file():
        run_dir, record = run_dir.parent, run_dir.stem
    if not run_dir.is_dir():
        raise RobofdiError(f"RUN: no run folder at {str(run_dir)!r}; expected a folder written by `robofdi run` "
                           "(holding record.h5)")
    names = _records(run_dir)
    where = "RUN" if record == "record" else "--record"
    if record not in names:
        runs = sorted(p.parent.name for p in run_dir.glob("*/record.h5"))
        if runs and not names:
            raise RobofdiError(f"RUN: {str(run_dir)!r} holds no record; its runs are in its folders "
                               f"{', '.join(runs)} (e.g. `robofdi figures {run_dir / runs[0]}`)")
        what = f"--record one of {', '.join(names)}" if names else "a run folder holding record.h5"
        raise RobofdiError(f"{where}: no {record}.h5 in {str(run_dir)!r}; expected {what}")
    rec = load(run_dir / f"{record}.h5")
    order = _summary_order(run_dir) if record == "record" else []     # the run's order: the estimates' colours
    known = _ordered(rec.diagnosers, order)
    if not known:
        raise RobofdiError(f"{where}: {str(run_dir / (record + '.h5'))!r} holds no diagnoser, so no residual figures")
    unknown = [d for d in diagnosers if d not in known]
    if unknown:
        raise RobofdiError(f"--diagnoser: {', '.join(map(repr, unknown))} not in {record}.h5; expected one of "
                           f"{', '.join(known)}")
    folder = _figure_folder(run_dir, record)
    folder.mkdir(parents=True, exist_ok=True)
    if diagnosers:
        names, estimates = list(dict.fromkeys(diagnosers)), False
    elif every:
        names, estimates = known, True
    else:
        names = [d for d in known if not (folder / f"residuals_{d}.png").is_file()]
        estimates = not (folder / "estimates.png").is_file()
    return _draw(rec, folder, _ordered(names, order), estimates, order)


def _summary_order(run_dir: Path) -> list[str]:
    """The diagnosers in the order of the folder's summary.json (the run's own order, which the record file does
    not keep: HDF5 lists its groups by name); [] without one."""
    import json

    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return []
    found = summary.get("diagnosers") if isinstance(summary, dict) else None
    return list(found) if isinstance(found, dict) else []
