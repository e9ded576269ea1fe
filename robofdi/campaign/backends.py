"""Where runs execute: in this process, on a local process pool, or on a Dask distributed cluster.

Every backend has the same shape — a context manager with ``map_unordered(fn, args_list)`` yielding results as
they complete — and none changes a result: each task is a pure function of its arguments.
"""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
import os
import signal
import threading
from collections.abc import Callable, Iterable, Iterator

from robofdi.errors import RobofdiError

__all__ = ["LocalPool", "DaskCluster", "backend", "default_workers"]

INSTALL_CLUSTER = "pip install 'robofdi[cluster]' (or: pip install 'dask[distributed]')"


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:      # not on Linux
        return os.cpu_count() or 1


_STARTED = None       # in a worker: the barrier every worker of the pool meets once, when the pool starts


def _import_engine() -> None:
    """Import what every task runs (the campaign engine, lockstep diagnosis), once as a worker starts, so that a
    campaign's runs do not wait for it."""
    import robofdi.campaign.runs  # noqa: F401
    import robofdi.lockstep  # noqa: F401


#: A Dask worker's statistical profiler: it samples the task thread's stack every 10 ms (and folds the samples
#: every second). Paused, a 200-run arm campaign's run phase on 2 local workers took 0.8 s longer to 2.3 s shorter
#: (mean 1.1 s of 28–31 s) in five paired runs on the 2-vCPU machine (docs/performance.md).
PROFILER_CALLBACKS = ("profile", "profile-cycle")


def _pause_profiler(dask_worker=None) -> list[str]:
    """Stop this Dask worker's profiler callbacks that are running; returns their names (to start them again)."""
    stopped = []
    for name in PROFILER_CALLBACKS:
        callback = dask_worker.periodic_callbacks.get(name)
        if callback is not None and callback.is_running():
            callback.stop()
            stopped.append(name)
    return stopped


def _resume_profiler(names: list[str], dask_worker=None) -> None:
    for name in names:
        callback = dask_worker.periodic_callbacks.get(name)
        if callback is not None:
            callback.start()


def _worker_init(started) -> None:
    global _STARTED
    # Ctrl-C and SIGTERM are the driver's to handle: it terminates the pool; workers must not print tracebacks.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _import_engine()
    _STARTED = started


def _started() -> int:
    """A pool's first task, one per worker: each waits until every worker has started (so no worker takes two)."""
    _STARTED.wait(timeout=300)
    return os.getpid()


class LocalPool:
    """``workers`` processes ("spawn": a fresh interpreter each, nothing inherited from the driver; a script that
    calls the API must guard its entry point with ``if __name__ == "__main__":``, as for any spawn pool);
    1 = this process, no pool. A worker that dies (crash, out of memory) stops the campaign with an error instead
    of hanging it; the finished runs stay journaled."""

    def __init__(self, workers: int | None = None):
        workers = default_workers() if workers is None else workers
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise RobofdiError(f"--workers: expected an integer >= 1, got {workers!r}")
        self.workers = workers
        self.description = "this process" if workers == 1 else f"local process pool, {workers} workers"
        self._pool = None

    def __enter__(self):
        if self.workers > 1:
            context = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(self.workers, mp_context=context, initializer=_worker_init,
                                             initargs=(context.Barrier(self.workers),))
            # every worker started now (the executor would start them one by one as tasks come), so that a campaign's
            # runs do not wait for a worker's interpreter and imports
            try:
                for future in [self._pool.submit(_started) for _ in range(self.workers)]:
                    future.result()
            except BaseException as exc:
                self.__exit__(RobofdiError, None, None)
                if isinstance(exc, Exception):
                    raise RobofdiError(f"--workers: the local pool's {self.workers} workers did not all start "
                                       f"({type(exc).__name__}: {exc})") from exc
                raise
        return self

    def __exit__(self, exc_type, exc, tb):
        pool, self._pool = self._pool, None
        if pool is not None:
            if exc_type is not None:
                # runs in flight are lost (finished ones are journaled): stop the workers now, not after their run
                for process in list(getattr(pool, "_processes", {}).values()):
                    process.terminate()
            pool.shutdown(wait=True, cancel_futures=True)
        return False

    def map_unordered(self, fn: Callable, args_list: Iterable[tuple]) -> Iterator:
        if self._pool is None:
            for args in args_list:
                yield fn(*args)
            return
        futures = [self._pool.submit(fn, *args) for args in args_list]
        try:
            for future in as_completed(futures):
                try:
                    yield future.result()
                except BrokenProcessPool:
                    raise RobofdiError("a worker process of the local pool died (crash or out of memory); the finished "
                                       "runs are kept, --resume continues") from None
        finally:
            for f in futures:
                f.cancel()


class DaskCluster:
    """A running Dask distributed scheduler at ``address`` (tcp://host:port), connected now: an unreachable
    scheduler is an error before any run starts. Needs the optional extra ``cluster``.

    Inside ``with``, the workers' statistical profiler (the dashboard's profile page) is paused and it is started
    again at its end (:data:`PROFILER_CALLBACKS`; ``pause_profiler=False`` leaves it running)."""

    def __init__(self, address: str, timeout: float = 10.0, pause_profiler: bool = True):
        try:
            from dask.distributed import Client
        except ImportError:
            raise RobofdiError(f"--scheduler needs dask.distributed, which is not installed: {INSTALL_CLUSTER}") from None
        if not isinstance(address, str) or not address.strip():
            raise RobofdiError(f"--scheduler: expected an address like tcp://HOST:8786, got {address!r}")
        self.client = _connect(Client, address, timeout)
        self.workers = len(self.client.scheduler_info().get("workers", {}))
        if self.workers == 0:
            self.client.close()
            raise RobofdiError(f"--scheduler: the Dask scheduler at {address!r} has no workers; start some with "
                               f"`dask worker {address}`")
        self.description = f"Dask cluster at {address}, {self.workers} workers"
        self.client.run(_import_engine)
        self.pause_profiler = pause_profiler
        self._paused = {}
        self._futures = []

    def __enter__(self):
        if self.pause_profiler:
            try:
                self._paused = self.client.run(_pause_profiler)
            except Exception:     # a worker without Dask's profiler callbacks: the campaign runs all the same
                self._paused = {}
        return self

    def __exit__(self, exc_type, exc, tb):
        if self._futures and exc_type is not None:
            self.client.cancel(self._futures)
        self._futures = []
        try:
            for address, names in self._paused.items():
                if names:
                    self.client.run(_resume_profiler, names, workers=[address])
        except Exception:         # a worker gone meanwhile has no profiler to start again
            pass
        self._paused = {}
        self.client.close()
        return False

    def map_unordered(self, fn: Callable, args_list: Iterable[tuple]) -> Iterator:
        from dask.distributed import as_completed

        args_list = list(args_list)
        if not args_list:
            return
        # the arguments every task shares (spec, calibrations) travel once, not once per task
        shared = {}
        for i, a in enumerate(args_list[0]):
            if all(len(b) > i and b[i] is a for b in args_list) and not isinstance(a, (int, str, type(None))):
                shared[i] = self.client.scatter([a], broadcast=True, hash=False)[0]   # a list: a dict would be split
        self._futures = [self.client.submit(fn, *[shared.get(i, a) for i, a in enumerate(args)], pure=False)
                         for args in args_list]
        for future in as_completed(self._futures, loop=self.client.loop):
            yield future.result()


def _connect(client_type, address: str, timeout: float):
    """A Dask client connected to ``address`` within ``timeout`` seconds whatever answers there (a scheduler, an
    HTTP server that never completes the handshake, nothing at all), or one RobofdiError. The connection is made
    in a helper thread so that the deadline holds even where dask's own timeout does not; a client that connects
    too late, or whose connection failed, is closed quietly (no ``Client.__del__`` traceback at exit)."""
    outcome: dict = {}

    def connect():
        try:
            client = client_type(address, timeout=timeout, set_as_default=False)
        except BaseException as exc:       # any failure of a foreign endpoint (MemoryError from a garbage length…)
            outcome["error"] = exc
            return
        if outcome.setdefault("client", client) is not client or outcome.get("late"):
            _close_quietly(client)

    thread = threading.Thread(target=connect, name="robofdi-dask-connect", daemon=True)
    thread.start()
    thread.join(timeout + 2.0)
    if "client" in outcome and not outcome.get("late"):
        return outcome["client"]
    outcome["late"] = True
    reason = outcome.get("error")
    detail = f" ({type(reason).__name__}: {' '.join(str(reason).split())[:200]})" if reason is not None else \
        " (no answer as a Dask scheduler)"
    raise RobofdiError(f"--scheduler: cannot reach the Dask scheduler at {address!r} within {timeout:g} s{detail}; "
                       "expected the address of a running `dask scheduler` (tcp://HOST:8786)")


def _close_quietly(client) -> None:
    try:
        client.close(timeout=1)
    except BaseException:
        pass


def backend(workers: int | None = None, scheduler: str | None = None):
    """The backend asked for: a Dask cluster when ``scheduler`` is given, else a local pool."""
    if scheduler is not None:
        if workers is not None:
            raise RobofdiError("--workers and --scheduler exclude each other (the cluster's workers run the campaign)")
        return DaskCluster(scheduler)
    return LocalPool(workers)
