"""The one calibration cache: key = (system, configuration, robofdi's code fingerprint); one format; one folder.

Calibrations (thresholds, observer designs, trained networks) are computed once per system configuration and
robot instance and reused by every later run, experiment and campaign worker::

    cal, cached = calibration.cached("arm", {"robot": ..., "seed": 3}, lambda: calibrate(...))

* **Key.** SHA-256 of the system name, a JSON description of everything the calibration depends on, and
  :func:`code_fingerprint` — robofdi's own source — so a changed algorithm never reuses a stale calibration.
* **Format.** One ``.npz`` file per calibration: NumPy arrays stored as arrays, the rest as a JSON tree
  (numbers, strings, lists, tuples, sets, dicts, NumPy random states, dataclasses and plain objects of robofdi, NumPy, SciPy and
  scikit-learn). No pickle: loading a cache file imports only classes of those packages and executes no code
  from the file. A value that cannot be stored is kept in memory for this process only.
* **Folder.** ``$ROBOFDI_CACHE``, else ``~/.cache/robofdi`` (:func:`cache_dir`); :func:`clear` empties it
  (``robofdi cache clear`` at the command line). Writes are atomic (a temporary file renamed), so concurrent
  workers and an interrupted run never leave a torn file; every file carries a SHA-256 of its content, and a torn,
  corrupt or foreign file is reported (a warning naming it) and recomputed.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import os
import warnings
from collections.abc import Callable, Mapping
from importlib import import_module
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["cache_dir", "code_fingerprint", "cache_key", "cached", "is_cached", "dumps", "loads", "clear", "entries"]

#: packages whose classes a cache file may name (nothing else is imported when a file is read)
TRUSTED = ("robofdi", "numpy", "scipy", "sklearn")
SUFFIX = ".cal.npz"
_memory: dict[str, Any] = {}


def cache_dir() -> Path:
    """Where calibrations are cached: ``$ROBOFDI_CACHE``, else ``~/.cache/robofdi``."""
    return Path(os.environ.get("ROBOFDI_CACHE") or Path.home() / ".cache" / "robofdi")


@functools.cache
def code_fingerprint() -> str:
    """SHA-256 of robofdi's own source (every .py file of the installed package, by relative path): part of every
    calibration cache key, so a cached calibration is never reused by code that would compute it differently
    (a hand-bumped format number was once reused after a revert, and a stale cache went unnoticed)."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def cache_key(system: str, description: Mapping) -> str:
    """20 hex digits naming (system, description, code fingerprint); ``description`` must be JSON-able
    (anything else is written with ``repr``, which must then be deterministic)."""
    text = json.dumps({"system": system, "description": description, "code": code_fingerprint()}, sort_keys=True,
                      default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def cached(system: str, description: Mapping, compute: Callable[[], Any], *, cache: bool = True) -> tuple[Any, bool]:
    """``compute()`` once per (system, description, code); returns (calibration, True if it came from the cache).
    ``cache=False`` computes afresh and stores nothing."""
    if not cache:
        return compute(), False
    key = cache_key(system, description)
    path = cache_dir() / f"{system}-{key}{SUFFIX}"
    if key in _memory:
        return _memory[key], True
    if path.is_file():
        try:
            return loads(path.read_bytes()), True
        except Exception as exc:                            # torn, corrupt or foreign: said, recomputed, replaced
            reason = " ".join(str(exc).split()) or type(exc).__name__
            warnings.warn(f"calibration cache: {path} is unreadable ({type(exc).__name__}: {reason}); recomputing it",
                          stacklevel=2)
    value = compute()
    try:
        data = dumps(value)
    except TypeError as exc:                                # not storable: this process keeps it, and says so
        warnings.warn(f"{exc}; the {system} calibration is kept in memory only (recomputed by the next process)",
                      stacklevel=2)
        _memory[key] = value
        return value, False
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{np.random.default_rng().integers(1 << 62)}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        tmp.replace(path)
    except OSError:                                         # a read-only or full cache only costs the next run its
        try:                                                # calibration; no torn temporary file stays behind
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
    return value, False


def is_cached(system: str, description: Mapping) -> bool:
    """Whether :func:`cached` would return a stored calibration (e.g. to size a progress bar)."""
    key = cache_key(system, description)
    return key in _memory or (cache_dir() / f"{system}-{key}{SUFFIX}").is_file()


def entries() -> list[Path]:
    """The calibration files in :func:`cache_dir`."""
    folder = cache_dir()
    return sorted(folder.glob(f"*{SUFFIX}")) if folder.is_dir() else []


def clear() -> int:
    """Delete every cached calibration (and torn temporary files); returns how many files went."""
    _memory.clear()
    folder = cache_dir()
    gone = 0
    for path in entries() + (sorted(folder.glob(f"*{SUFFIX}.*.tmp")) if folder.is_dir() else []):
        path.unlink(missing_ok=True)
        gone += 1
    return gone


# ------------------------------------------------------------------------------------------------ the format
def dumps(value: Any) -> bytes:
    """``value`` as the bytes of an .npz file (arrays as arrays, the rest a JSON tree); TypeError if it holds
    something that is neither data nor an object of :data:`TRUSTED` packages."""
    arrays: dict[str, np.ndarray] = {}
    tree = np.frombuffer(json.dumps(_encode(value, arrays)).encode(), dtype=np.uint8)
    buffer = io.BytesIO()
    np.savez(buffer, __tree__=tree, __sha256__=_digest(tree, arrays), **arrays)
    return buffer.getvalue()


def _digest(tree: np.ndarray, arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """SHA-256 of the tree and of every array (name, dtype, shape, bytes): a flipped byte that still unzips is
    caught too."""
    digest = hashlib.sha256(tree.tobytes())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"\0{name}\0{a.dtype.str}\0{a.shape}\0".encode() + a.tobytes())
    return np.frombuffer(digest.digest(), dtype=np.uint8)


def loads(data: bytes) -> Any:
    """The value :func:`dumps` stored."""
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    if "__tree__" not in arrays or "__sha256__" not in arrays:
        raise ValueError("calibration cache: not a robofdi calibration file (no tree or no checksum)")
    tree, digest = arrays.pop("__tree__"), arrays.pop("__sha256__")
    if not np.array_equal(digest, _digest(tree, arrays)):
        raise ValueError("calibration cache: checksum mismatch (a corrupt file)")
    return _decode(json.loads(tree.tobytes().decode()), arrays)


def _class_path(obj) -> str:
    cls = type(obj)
    path = f"{cls.__module__}:{cls.__qualname__}"
    if cls.__module__.split(".")[0] not in TRUSTED or "<locals>" in cls.__qualname__:
        raise TypeError(f"calibration cache: cannot store a {path}")
    return path


def _encode(v, arrays: dict) -> Any:
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, int) and type(v) is int:
        return v
    if isinstance(v, float) and type(v) is float:
        return v if np.isfinite(v) else {"$float": repr(v)}
    if isinstance(v, (np.ndarray, np.generic)):
        if np.asarray(v).dtype == object:
            raise TypeError("calibration cache: cannot store an object array")
        name = f"a{len(arrays)}"
        arrays[name] = np.asarray(v)
        return {"$array": name, "scalar": isinstance(v, np.generic)}
    if isinstance(v, np.random.RandomState):             # e.g. a trained scikit-learn network's random state
        return {"$random_state": _encode(v.get_state(legacy=True), arrays)}
    if isinstance(v, np.random.Generator):
        return {"$generator": type(v.bit_generator).__name__, "state": _encode(v.bit_generator.state, arrays)}
    if isinstance(v, (list, tuple)):
        items = [_encode(x, arrays) for x in v]
        return items if type(v) is list else {"$tuple": items}
    if isinstance(v, (set, frozenset)):
        return {"$set": sorted((_encode(x, arrays) for x in v), key=json.dumps), "frozen": isinstance(v, frozenset)}
    if isinstance(v, dict) and type(v) is dict:
        return {"$dict": [[_encode(k, arrays), _encode(x, arrays)] for k, x in v.items()]}
    if isinstance(v, type):
        raise TypeError(f"calibration cache: cannot store the class {v.__module__}.{v.__qualname__}")
    if hasattr(v, "__dict__"):                               # the whole instance state, as pickle would keep it
        return {"$object": _class_path(v), "state": _encode(dict(vars(v)), arrays)}
    if dataclasses.is_dataclass(v):                          # a slotted dataclass: its fields are its state
        state = {f.name: getattr(v, f.name) for f in dataclasses.fields(v)}
        return {"$object": _class_path(v), "state": _encode(state, arrays), "slots": True}
    raise TypeError(f"calibration cache: cannot store a {type(v).__module__}.{type(v).__qualname__}")


def _decode(v, arrays: dict) -> Any:
    if isinstance(v, list):
        return [_decode(x, arrays) for x in v]
    if not isinstance(v, dict):
        return v
    if "$float" in v:
        return float(v["$float"])
    if "$array" in v:
        a = arrays[v["$array"]]
        return a[()] if v["scalar"] else a
    if "$random_state" in v:
        state = np.random.RandomState()
        state.set_state(_decode(v["$random_state"], arrays))
        return state
    if "$generator" in v:
        bit_generator = getattr(np.random, v["$generator"])()
        bit_generator.state = _decode(v["state"], arrays)
        return np.random.Generator(bit_generator)
    if "$tuple" in v:
        return tuple(_decode(x, arrays) for x in v["$tuple"])
    if "$set" in v:
        items = [_decode(x, arrays) for x in v["$set"]]
        return frozenset(items) if v["frozen"] else set(items)
    if "$dict" in v:
        return {_decode(k, arrays): _decode(x, arrays) for k, x in v["$dict"]}
    if "$object" in v:
        module, _, qualname = v["$object"].partition(":")
        if module.split(".")[0] not in TRUSTED:
            raise ValueError(f"calibration cache: untrusted class {v['$object']}")
        cls: Any = import_module(module)
        for part in qualname.split("."):
            cls = getattr(cls, part)
        obj = cls.__new__(cls)
        state = _decode(v["state"], arrays)
        if v.get("slots"):
            for k, x in state.items():
                object.__setattr__(obj, k, x)
        else:
            obj.__dict__.update(state)
        return obj
    raise ValueError(f"calibration cache: unknown node {sorted(v)}")
