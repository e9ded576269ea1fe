"""The figures' share of one `robofdi` command (issue 23: figures ≤ 20 % of a run), in this process.

CPU time (``time.process_time``: this process, all its threads) from the first line of ``robofdi.cli.main`` to its
return, with the heavy imports done before (robofdi's command line and experiments, matplotlib through
``robofdi.evaluate.figures``, meshcat through ``robofdi.viz`` when installed): imports excluded. The figures are
the CPU time spent inside the run folder's generic figure functions (``plot_residual_figures`` and
``plot_estimates`` of :mod:`robofdi.evaluate.figures`, wherever the run folder calls them from). Run it with the
calibration cached (a first run fills the cache) and on one core, e.g.::

    ROBOFDI_CACHE=/tmp/cache taskset -c 0 python benchmarks/figures_share.py -- run arm --out /tmp/runs --quiet

It prints one line: figures [s CPU], the command [s CPU], the figures' share [%], the command's exit code.
"""
from __future__ import annotations

import contextlib
import functools
import importlib
import importlib.util
import io
import sys
import time

import robofdi.cli
import robofdi.evaluate.figures as figures
import robofdi.evaluate.run_folder as run_folder
import robofdi.experiments  # noqa: F401
import robofdi.experiments.arm  # noqa: F401

if importlib.util.find_spec("meshcat") is not None:
    importlib.import_module("robofdi.viz")

spent = [0.0]
depth = [0]


def _timed(fn):
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        depth[0] += 1
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            depth[0] -= 1
            if depth[0] == 0:                    # a figure function calling another is counted once
                spent[0] += time.process_time() - t0
    return wrapper


for name in ("plot_residual_figures", "plot_estimates"):
    timed = _timed(getattr(figures, name))
    setattr(figures, name, timed)
    if hasattr(run_folder, name):                # imported by name into the run folder's module
        setattr(run_folder, name, timed)


def main(argv: list[str]) -> int:
    args = argv[argv.index("--") + 1:] if "--" in argv else argv
    with contextlib.redirect_stdout(io.StringIO()):
        t0 = time.process_time()
        code = robofdi.cli.main(args)
        total = time.process_time() - t0
    print(f"figures {spent[0]:.3f} s CPU  command {total:.3f} s CPU  share {100 * spent[0] / total:.1f} %  "
          f"exit {code}")
    return code


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
