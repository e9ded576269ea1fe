"""Compiled kernels: the per-sample arithmetic of the diagnosers and decisions, compiled by numba where it pays.

A kernel is a plain Python function over float arrays and numbers, written element by element in the order of
operations of the NumPy expression it replaces (fastmath off, no fused multiply-add, ``math.sin``/``cos``/``exp``
are the C library's, as NumPy's are for float64 on x86-64 without AVX-512): the compiled kernel and its Python
function give the same bits on any machine, and the NumPy code before them too where NumPy's ``exp`` is the C
library's (on AVX-512 CPUs NumPy has its own ``exp``, which differs in the last bit for some arguments). What a
kernel may not hold: matrix products and solves (NumPy's BLAS and LAPACK stay outside, called on the same arrays
as before), ``tanh`` (NumPy's own SIMD implementation) and reductions whose summation order NumPy chooses
(``einsum``, ``sum`` over more than a few entries). One exception, measured: the consistency scheme's sample
(:mod:`robofdi.observers.consistency`, ``_operating_point`` and the payload evidence) sums its small products and
takes ``math.exp`` in the kernel, so its residual differs from the NumPy form it replaced at rounding level
(≤ 1e-15, docs/performance.md); the compiled kernel and its Python function still agree bit for bit. A second
one: the arm plant's control period (:mod:`robofdi.sims.kernels`, with ``mj_step`` called through MuJoCo's C API)
sums its ripple terms in its own order and takes ``math.tanh``, so the arm's simulated state moved at rounding
level from the NumPy/BLAS form it replaced (a state difference of ≈ 1e-13 after 3 000 ticks; docs/performance.md);
the plant no longer depends on the BLAS build or on NumPy's SIMD ``tanh``.

:func:`kernel` compiles with ``numba.njit(cache=True, nogil=True)``: the machine code is cached on disk next to
the source (``__pycache__``; numba's ``NUMBA_CACHE_DIR`` moves it), so a process pays the compilation once per
source change, later ones load it in milliseconds. The pure-Python path: ``NUMBA_DISABLE_JIT=1`` (numba's own
switch) runs every kernel of the process as its Python function; :func:`interpreted` does the same for a block
of code (tests compare the two paths on one real run). Without numba installed, kernels are their Python
functions.
"""
from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator

__all__ = ["COMPILED", "kernel", "interpreted"]

try:                                           # pragma: no cover - which branch runs depends on the install
    import numba

    COMPILED = not numba.config.DISABLE_JIT
except ImportError:                            # pragma: no cover
    numba = None
    COMPILED = False

try:        # np.einsum's own C function, without its Python wrapper: what np.einsum calls (optimize=False, its
    # default), so the same result bits; per-sample reductions that stay NumPy's use it
    from numpy._core.multiarray import c_einsum as einsum
except ImportError:                            # pragma: no cover - a NumPy without the private module
    from numpy import einsum  # noqa: F401 - used by the observers (not in __all__: NumPy's docstring)

_KERNELS: list[tuple[str, str, Callable, Callable]] = []     # (module, name, compiled, python function)


def kernel(fn: Callable) -> Callable:
    """``fn`` compiled (numba, disk-cached, fastmath off) when numba is there and enabled, else ``fn`` itself.
    Call a kernel through its module's global name (``_kernel(...)`` in the module that defines it), so that
    :func:`interpreted` reaches every call."""
    compiled = numba.njit(cache=True, nogil=True)(fn) if numba is not None else fn
    _KERNELS.append((fn.__module__, fn.__name__, compiled, fn))
    return compiled


@contextlib.contextmanager
def interpreted() -> Iterator[None]:
    """Inside the block every kernel runs as its Python function (the pure-Python path), then compiled again."""
    swapped = []
    for module, name, compiled, python in _KERNELS:
        namespace = vars(sys.modules[module])
        if namespace.get(name) is compiled:
            namespace[name] = python
            swapped.append((namespace, name, compiled))
    try:
        yield
    finally:
        for namespace, name, compiled in swapped:
            namespace[name] = compiled
