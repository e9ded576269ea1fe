"""The run record: labelled time series of one closed-loop run, saved as HDF5.

Layout (readable with plain h5py; every dataset carries ``units`` and ``columns`` attributes, JSON lists)::

    /                      attrs: system, scenario, seed, rates (JSON), robofdi version, meta (JSON)
    /time                  (N,)              control-rate time stamps [s]
    /truth/state           (N, nx)           true simulator state
    /truth/u_applied       (N, nu)           what the plant really received (after saturation)
    /truth/faults/<name>/{active, value}     ground-truth labels per fault (value in the fault's unit)
    /signals/<name>        (N, k)            reference, u_cmd, u, u_diag, y_meas (after noise and sensor faults),
                                             y_true (the noise-free output)
    /diagnosers/<name>/{time, residual, threshold, alarm, isolated, estimate}

Diagnosers run at their own rate, so each carries its own ``time``.
``load(path)`` returns a :class:`Record` equal to the one that was saved (round trip exact). The file holds no
wall-clock time, so the same seed gives a byte-identical file.
"""
from __future__ import annotations

import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from robofdi.errors import RobofdiError

__all__ = ["FaultLabels", "DiagnoserTrace", "Record", "RecordWriter", "load", "partial_name"]


@dataclass
class FaultLabels:
    """Ground truth of one fault at every recorded step: is it active, and its true value (effect on the target)."""

    active: np.ndarray
    value: np.ndarray
    unit: str = ""


@dataclass
class DiagnoserTrace:
    """What one diagnoser produced, sample by sample, at the diagnosis rate."""

    time: np.ndarray
    residual: np.ndarray                 # (M, m)
    threshold: np.ndarray                # (m,)
    alarm: np.ndarray                    # (M, m) bool
    isolated: np.ndarray                 # (M,) str, "" while nothing is isolated
    estimate: np.ndarray                 # (M, e) identified fault magnitudes (0 before isolation)
    components: list[str] = field(default_factory=list)
    estimate_components: list[str] = field(default_factory=list)
    units: dict[str, list[str]] = field(default_factory=dict)   # "residual", "estimate" -> unit per entry


@dataclass
class Record:
    """One run: metadata, time, truth, signals and every diagnoser's output.

    ``columns`` and ``units`` map a dataset path ("truth/state", "truth/u_applied", "signals/u", ...) to the
    name and the unit of each of its columns.
    """

    system: str
    scenario: str
    seed: int | None
    rates: dict
    time: np.ndarray
    truth_state: np.ndarray
    faults: dict[str, FaultLabels] = field(default_factory=dict)
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    diagnosers: dict[str, DiagnoserTrace] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    u_applied: np.ndarray | None = None
    columns: dict[str, list[str]] = field(default_factory=dict)
    units: dict[str, list[str]] = field(default_factory=dict)
    version: str = ""

    def __post_init__(self):
        if not self.version:
            from robofdi import __version__

            self.version = __version__

    def column(self, dataset: str, name: str) -> np.ndarray:
        """One column of a dataset by name, e.g. ``record.column("signals/u", "joint3")``."""
        names = self.columns.get(dataset)
        if names is None or name not in names:
            raise RobofdiError(f"record: dataset {dataset!r} has no column {name!r}; columns: {names}")
        return self._dataset(dataset)[:, names.index(name)]

    def _dataset(self, path: str) -> np.ndarray:
        if path == "truth/state":
            return self.truth_state
        if path == "truth/u_applied":
            return self.u_applied
        if path.startswith("signals/"):
            return self.signals[path.split("/", 1)[1]]
        raise RobofdiError(f"record: unknown dataset {path!r}")

    def save(self, path: str | Path) -> Path:
        """Write the record to an HDF5 file (parents are created); returns the path. The file is written under a
        temporary name and renamed, so an interrupted or failed save never leaves a torn file under ``path``; a
        partial record (``meta["aborted"]``, a run that stopped part-way) carries the top-level attribute
        ``partial = 1``."""
        from robofdi.interrupts import atomic_path

        path = Path(path)
        data = self.to_bytes()
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:           # one plain write: a full disk is one OSError naming the file
            with open(tmp, "wb") as fh:
                fh.write(data)
        return path

    def to_bytes(self) -> bytes:
        """The HDF5 file :meth:`save` writes, built in memory (HDF5 never meets the disk, so a full or failing
        device cannot leave it half-flushed)."""
        from robofdi.seeding import check_seed

        if self.seed is not None:
            check_seed("record: field 'seed'", self.seed)
        buffer = io.BytesIO()
        self._write(buffer)
        return buffer.getvalue()

    def _write(self, path) -> None:
        with h5py.File(path, "w") as f:
            if self.meta.get("aborted"):
                f.attrs["partial"] = 1
            f.attrs.update(
                system=self.system,
                scenario=self.scenario,
                seed=-1 if self.seed is None else int(self.seed),
                rates=json.dumps(self.rates),
                version=self.version,
                meta=json.dumps(self.meta),
            )
            _put(f, "time", self.time, ["time"], ["s"])
            for key in ("truth/state", "truth/u_applied") + tuple(f"signals/{k}" for k in self.signals):
                data = self._dataset(key)
                if data is not None:
                    _put(f, key, data, self.columns.get(key), self.units.get(key))
            for name, lab in self.faults.items():
                _put(f, f"truth/faults/{name}/active", lab.active, [name], ["1"])
                _put(f, f"truth/faults/{name}/value", lab.value, [name], [lab.unit])
            for name, tr in self.diagnosers.items():
                g = f.create_group(f"diagnosers/{name}")
                ru, eu = tr.units.get("residual"), tr.units.get("estimate")
                _put(g, "time", tr.time, ["time"], ["s"])
                _put(g, "residual", tr.residual, tr.components, ru)
                _put(g, "threshold", tr.threshold, tr.components, ru)
                _put(g, "alarm", tr.alarm, tr.components, ["1"] * len(tr.components))
                _put(g, "estimate", tr.estimate, tr.estimate_components, eu)
                g["isolated"] = np.asarray(tr.isolated, dtype=object).astype(h5py.string_dtype())
                g["isolated"].attrs.update(columns=json.dumps(["isolated"]), units=json.dumps([""]))
                g.attrs["components"] = json.dumps(list(tr.components))
                g.attrs["estimate_components"] = json.dumps(list(tr.estimate_components))


def _put(group, name: str, data, columns=None, units=None) -> None:
    """Write one array with its column names and units, losslessly compressed when large enough to matter."""
    data = np.asarray(data)
    if data.size >= 1024:
        ds = group.create_dataset(name, data=data, compression="gzip", compression_opts=4, shuffle=True)
    else:
        group[name] = data
        ds = group[name]
    if not columns:
        width = data.shape[1] if data.ndim == 2 else 1
        columns = [f"{name.rsplit('/', 1)[-1]}[{i}]" for i in range(width)]
    units = list(units) if units else [""] * len(columns)
    ds.attrs["columns"] = json.dumps(list(columns))
    ds.attrs["units"] = json.dumps(units)


def partial_name(path: str | Path) -> Path:
    """Where :class:`RecordWriter` keeps a record while it is written, and a run that stopped keeps it:
    ``record.h5`` → ``record.partial.h5``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial{path.suffix or '.h5'}")


class RecordWriter:
    """A record written to HDF5 chunk by chunk as its run goes — the layout, columns and units of
    :meth:`Record.save` (datasets chunked along time, gzip-compressed; :func:`load` reads both alike), with
    memory bounded by one chunk whatever the run length.

    The file is ``partial_name(path)`` with the top-level attribute ``partial = 1`` until :meth:`close` renames
    it to ``path``; after every :meth:`append` of a whole chunk it is flushed, so a run that crashes keeps
    everything up to its last chunk (under the partial name, marked partial). ``attrs``: system, scenario,
    seed, rates, version, meta — as :meth:`Record.save` writes them."""

    def __init__(self, path: str | Path, attrs: dict):
        self.path = Path(path)
        self.partial = partial_name(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.meta = dict(attrs.get("meta") or {})
        try:
            self._file = h5py.File(self.partial, "w")
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror or str(exc), str(self.partial)) from None
        f = self._file
        f.attrs["partial"] = 1
        f.attrs.update(system=attrs["system"], scenario=attrs["scenario"],
                       seed=-1 if attrs["seed"] is None else int(attrs["seed"]), rates=json.dumps(attrs["rates"]),
                       version=attrs["version"], meta=json.dumps(self.meta))

    def _extend(self, name: str, rows, columns=None, units=None, strings: bool = False) -> None:
        f = self._file
        rows = np.asarray(rows, dtype=object) if strings else np.asarray(rows)
        ds = f.get(name)
        if ds is None:
            shape = rows.shape[1:]
            dtype = h5py.string_dtype() if strings else rows.dtype
            chunk_rows = max(1, min(4096, 65536 // max(1, int(np.prod(shape, dtype=int)))))
            ds = f.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape), dtype=dtype,
                                  chunks=(chunk_rows, *shape), compression="gzip", compression_opts=4,
                                  shuffle=not strings)
            if not columns:
                width = shape[0] if len(shape) == 1 else 1
                columns = [f"{name.rsplit('/', 1)[-1]}[{i}]" for i in range(width)]
            ds.attrs["columns"] = json.dumps(list(columns))
            ds.attrs["units"] = json.dumps(list(units) if units else [""] * len(columns))
        n = ds.shape[0]
        if len(rows):
            ds.resize(n + len(rows), axis=0)
            ds[n:] = rows.astype(h5py.string_dtype()) if strings else rows

    def append(self, series: dict, columns: dict, units: dict, faults: dict, diagnosers: dict,
               traces: dict) -> None:
        """One chunk: ``series`` dataset path ("time", "truth/state", "signals/u", ...) → rows; ``faults`` name →
        (active rows, value rows, unit); ``diagnosers`` name → {time, residual, alarm, isolated, estimate} rows,
        ``traces`` name → the :class:`DiagnoserTrace` giving its threshold, components and units (rows ignored)."""
        for key, rows in series.items():
            self._extend(key, rows, columns.get(key, ["time"] if key == "time" else None),
                         units.get(key, ["s"] if key == "time" else None))
        for name, (active, value, unit) in faults.items():
            self._extend(f"truth/faults/{name}/active", active, [name], ["1"])
            self._extend(f"truth/faults/{name}/value", value, [name], [unit])
        for name, rows in diagnosers.items():
            tr = traces[name]
            ru, eu = tr.units.get("residual"), tr.units.get("estimate")
            base = f"diagnosers/{name}"
            if base not in self._file:
                g = self._file.create_group(base)
                _put(g, "threshold", tr.threshold, tr.components, ru)
                g.attrs["components"] = json.dumps(list(tr.components))
                g.attrs["estimate_components"] = json.dumps(list(tr.estimate_components))
            self._extend(f"{base}/time", rows["time"], ["time"], ["s"])
            self._extend(f"{base}/residual", rows["residual"], tr.components, ru)
            self._extend(f"{base}/alarm", rows["alarm"], tr.components, ["1"] * len(tr.components))
            self._extend(f"{base}/isolated", rows["isolated"], ["isolated"], [""], strings=True)
            self._extend(f"{base}/estimate", rows["estimate"], tr.estimate_components, eu)
        self._file.flush()

    def close(self, aborted: bool = False) -> Path:
        """Finish the file: complete, it is renamed to ``path`` (returned); ``aborted``, it stays under the partial
        name with ``meta["aborted"]`` set (returned)."""
        f = self._file
        if aborted:
            self.meta["aborted"] = True
            f.attrs["meta"] = json.dumps(self.meta)
        else:
            del f.attrs["partial"]
        f.close()
        if aborted:
            return self.partial
        os.replace(self.partial, self.path)
        return self.path


def _attr_list(ds, key: str) -> list[str]:
    return json.loads(ds.attrs[key]) if key in ds.attrs else []


def load(path: str | Path) -> Record:
    """Read a record written by :meth:`Record.save`."""
    path = Path(path)
    if not path.is_file():
        raise RobofdiError(f"record file {str(path)!r} does not exist")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise RobofdiError(f"record file {str(path)!r} is not a readable HDF5 file: {exc}") from None
    with f:
        seed = int(f.attrs["seed"])
        faults = {
            name: FaultLabels(active=g["active"][()], value=g["value"][()], unit=(_attr_list(g["value"], "units") or [""])[0])
            for name, g in f.get("truth/faults", {}).items()
        }
        columns, units = {}, {}
        datasets = {"truth/state": f["truth/state"]}
        if "truth/u_applied" in f:
            datasets["truth/u_applied"] = f["truth/u_applied"]
        for name, ds in f.get("signals", {}).items():
            datasets[f"signals/{name}"] = ds
        for key, ds in datasets.items():
            columns[key], units[key] = _attr_list(ds, "columns"), _attr_list(ds, "units")
        diagnosers = {}
        for name, g in f.get("diagnosers", {}).items():
            diagnosers[name] = DiagnoserTrace(
                time=g["time"][()],
                residual=g["residual"][()],
                threshold=g["threshold"][()],
                alarm=g["alarm"][()],
                isolated=np.array([s.decode() if isinstance(s, bytes) else s for s in g["isolated"][()]], dtype=object),
                estimate=g["estimate"][()],
                components=json.loads(g.attrs["components"]),
                estimate_components=json.loads(g.attrs["estimate_components"]),
                units={"residual": _attr_list(g["residual"], "units"), "estimate": _attr_list(g["estimate"], "units")},
            )
        return Record(
            system=str(f.attrs["system"]),
            scenario=str(f.attrs["scenario"]),
            seed=None if seed < 0 else seed,
            rates=json.loads(f.attrs["rates"]),
            time=f["time"][()],
            truth_state=f["truth/state"][()],
            faults=faults,
            signals={name: ds[()] for name, ds in f.get("signals", {}).items()},
            diagnosers=diagnosers,
            meta=json.loads(f.attrs["meta"]),
            u_applied=f["truth/u_applied"][()] if "truth/u_applied" in f else None,
            columns=columns,
            units=units,
            version=str(f.attrs["version"]),
        )
