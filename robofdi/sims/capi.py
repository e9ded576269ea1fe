"""MuJoCo's C API for compiled kernels: ``mj_step`` called from inside a kernel, without a Python call.

:data:`MJ_STEP` is the address of ``mj_step`` in the ``libmujoco`` shared library the ``mujoco`` package ships
and its bindings have loaded (found in the package's folder, taken only if already loaded where the platform can
tell, and checked against ``mujoco.mj_version()``), or 0 when it cannot be found (then the caller steps through
the Python bindings: the same C function, the same bits).
:func:`mj_step_at` ``(MJ_STEP, model._address, data._address)`` steps once: compiled, it is a direct call of
the C function (an ``llvmlite`` intrinsic, so the kernel holding it stays cacheable on disk); in the pure-Python
path (``NUMBA_DISABLE_JIT=1``, :func:`robofdi.jit.interpreted`) it goes through ``ctypes``. The model and data
must outlive the call: pass the addresses of objects the caller holds.

A MuJoCo fatal error inside ``mj_step`` (``mju_error``: a corrupt model or an exhausted memory arena, none of
which a valid model meets while stepping) cannot become a Python exception on this path; the bindings' own
``mujoco.mj_step`` raises ``mujoco.FatalError`` instead.
"""
from __future__ import annotations

import ctypes
import os
from functools import cache
from pathlib import Path

import mujoco

from robofdi.jit import numba

__all__ = ["MJ_STEP", "mj_step_at"]

_PATTERNS = ("libmujoco.so*", "libmujoco*.dylib", "mujoco*.dll")


def _mj_step_address() -> int:
    """The address of ``mj_step`` in the package's own ``libmujoco`` of the bindings' version, else 0. Where the
    platform can say so (``RTLD_NOLOAD``), only a library the bindings have already loaded is taken: the very
    instance whose data they allocate, never a second copy."""
    folder = Path(mujoco.__file__).parent
    mode = getattr(os, "RTLD_NOLOAD", 0) | getattr(os, "RTLD_LAZY", 0) or ctypes.DEFAULT_MODE
    for pattern in _PATTERNS:
        for path in sorted(folder.glob(pattern)):
            try:
                lib = ctypes.CDLL(str(path), mode=mode)
                lib.mj_version.restype = ctypes.c_int
                if lib.mj_version() != mujoco.mj_version():
                    continue
                return int(ctypes.cast(lib.mj_step, ctypes.c_void_p).value or 0)
            except (OSError, AttributeError):
                continue
    return 0


MJ_STEP: int = _mj_step_address()


@cache
def _ctypes_function(address: int):
    return ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(address)


def mj_step_at(function: int, model: int, data: int) -> None:
    """``mj_step(model, data)`` through the C function at address ``function`` (the pure-Python path: ctypes)."""
    _ctypes_function(function)(model, data)


if numba is not None:                          # the compiled path: a direct call of the C function
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic, overload

    @intrinsic
    def _call_pointer_pointer(typingctx, function, a, b):
        """void (*function)(void*, void*) called on two addresses (all three integers)."""
        if not all(isinstance(x, types.Integer) for x in (function, a, b)):
            return None

        def codegen(context, builder, signature, args):
            f, x, y = args
            void_p = ir.IntType(8).as_pointer()
            fn_type = ir.FunctionType(ir.VoidType(), [void_p, void_p])
            builder.call(builder.inttoptr(f, fn_type.as_pointer()),
                         [builder.inttoptr(x, void_p), builder.inttoptr(y, void_p)])
            return context.get_dummy_value()

        return types.void(function, a, b), codegen

    @overload(mj_step_at)
    def _mj_step_at_compiled(function, model, data):
        return lambda function, model, data: _call_pointer_pointer(function, model, data)
