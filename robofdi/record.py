"""The run record: labelled time series of one closed-loop run, saved as HDF5.

Layout (readable with plain h5py)::

    /                      attrs: system, scenario, seed, rates (JSON), robofdi version, created, meta (JSON)
    /time                  (N,)              control-rate time stamps [s]
    /truth/state           (N, nx)           true simulator state
    /truth/faults/<name>/{active, value}     ground-truth labels per fault
    /signals/<name>        (N, k)            u_cmd, u, y_meas, y_true, reference, ...
    /diagnosers/<name>/{time, residual, threshold, alarm, isolated, estimate}
                           attrs: components (JSON list), estimate_components (JSON list)

Diagnosers run at their own rate, so each carries its own ``time``.
``load(path)`` returns a :class:`Record` equal to the one that was saved (round trip exact).
"""
from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

__all__ = ["FaultLabels", "DiagnoserTrace", "Record", "load"]


@dataclass
class FaultLabels:
    """Ground truth of one fault at every recorded step: is it active, and its true value (effect on the target)."""

    active: np.ndarray
    value: np.ndarray


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


@dataclass
class Record:
    """One run: metadata, time, truth, signals and every diagnoser's output."""

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
    version: str = ""
    created: str = ""

    def __post_init__(self):
        if not self.version:
            from robofdi import __version__

            self.version = __version__
        if not self.created:
            self.created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")

    def save(self, path: str | Path) -> Path:
        """Write the record to an HDF5 file (parents are created); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with h5py.File(path, "w") as f:
            f.attrs.update(
                system=self.system,
                scenario=self.scenario,
                seed=-1 if self.seed is None else int(self.seed),
                rates=json.dumps(self.rates),
                version=self.version,
                created=self.created,
                meta=json.dumps(self.meta),
            )
            _put(f, "time", self.time)
            _put(f, "truth/state", self.truth_state)
            for name, lab in self.faults.items():
                _put(f, f"truth/faults/{name}/active", lab.active)
                _put(f, f"truth/faults/{name}/value", lab.value)
            for name, arr in self.signals.items():
                _put(f, f"signals/{name}", arr)
            for name, tr in self.diagnosers.items():
                g = f.create_group(f"diagnosers/{name}")
                for key in ("time", "residual", "threshold", "alarm", "estimate"):
                    _put(g, key, getattr(tr, key))
                g["isolated"] = np.asarray(tr.isolated, dtype=object).astype(h5py.string_dtype())
                g.attrs["components"] = json.dumps(list(tr.components))
                g.attrs["estimate_components"] = json.dumps(list(tr.estimate_components))
        return path


def _put(group, name: str, data) -> None:
    """Write one array, losslessly compressed when it is large enough to matter."""
    data = np.asarray(data)
    if data.size >= 1024:
        group.create_dataset(name, data=data, compression="gzip", compression_opts=4, shuffle=True)
    else:
        group[name] = data


def load(path: str | Path) -> Record:
    """Read a record written by :meth:`Record.save`."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"record file {str(path)!r} does not exist")
    with h5py.File(path, "r") as f:
        seed = int(f.attrs["seed"])
        faults = {
            name: FaultLabels(active=g["active"][()], value=g["value"][()])
            for name, g in f.get("truth/faults", {}).items()
        }
        signals = {name: ds[()] for name, ds in f.get("signals", {}).items()}
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
            )
        return Record(
            system=str(f.attrs["system"]),
            scenario=str(f.attrs["scenario"]),
            seed=None if seed < 0 else seed,
            rates=json.loads(f.attrs["rates"]),
            time=f["time"][()],
            truth_state=f["truth/state"][()],
            faults=faults,
            signals=signals,
            diagnosers=diagnosers,
            meta=json.loads(f.attrs["meta"]),
            version=str(f.attrs["version"]),
            created=str(f.attrs["created"]),
        )
