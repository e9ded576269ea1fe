"""SIGINT and SIGTERM as one clean stop, and files written atomically.

* :class:`Interrupted` — a :class:`KeyboardInterrupt` that knows its signal. :func:`stop_on_signals` makes SIGINT
  and SIGTERM raise it (main thread only), so ``robofdi run`` and ``robofdi campaign`` stop the same way on either:
  the run in flight keeps what it recorded (``partial.h5``) and is never journaled as a failed run; the exit code
  is 128 + the signal number (130 for SIGINT, 143 for SIGTERM). A signal whose exception Python had to swallow
  (raised inside a finaliser: "Exception ignored in …") is still remembered by the returned handle.
* :func:`atomic_path` — a temporary name next to the final one, renamed over it only when the write succeeded:
  a crash or a signal never leaves a torn file under a final name.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

__all__ = ["Interrupted", "signal_of", "exit_code", "stop_on_signals", "atomic_path"]

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """SIGINT (Ctrl-C) or SIGTERM: ``signum`` says which."""

    def __init__(self, signum: int = signal.SIGINT, message: str | None = None):
        super().__init__(message or signal.Signals(signum).name)
        self.signum = int(signum)


def signal_of(exc: BaseException) -> int:
    """The signal behind an interruption (a plain KeyboardInterrupt is SIGINT)."""
    return int(getattr(exc, "signum", signal.SIGINT))


def exit_code(exc_or_signum) -> int:
    """128 + the signal number, the shell's convention: 130 for SIGINT, 143 for SIGTERM."""
    signum = exc_or_signum if isinstance(exc_or_signum, int) else signal_of(exc_or_signum)
    return 128 + int(signum)


class _Received:
    signum: int | None = None


@contextmanager
def stop_on_signals():
    """While active, SIGINT and SIGTERM raise :class:`Interrupted`; yields a handle whose ``signum`` is the last
    signal received (None: none). Outside the main thread it changes nothing."""
    received = _Received()
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def handler(signum, frame):
        received.signum = signum
        raise Interrupted(signum)

    def unraisable(info):          # our Interrupted raised inside a finaliser: remembered above, not printed
        if not isinstance(info.exc_value, Interrupted):
            previous_hook(info)

    previous = {s: signal.getsignal(s) for s in SIGNALS}
    previous_hook = sys.unraisablehook
    for s in SIGNALS:
        signal.signal(s, handler)
    sys.unraisablehook = unraisable
    try:
        yield received
    finally:
        sys.unraisablehook = previous_hook
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path next to ``path`` to write to; on success it is renamed to ``path`` (atomic on one
    file system), on any failure or interruption it is removed and ``path`` is left as it was. An OSError names
    ``path`` (not the temporary name)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        if isinstance(exc, OSError) and not isinstance(exc, FileNotFoundError):
            reason = exc.strerror or " ".join(str(exc).split())
            raise OSError(exc.errno, reason, str(path)) from exc
        raise
