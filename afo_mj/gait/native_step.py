"""MuJoCo's C step called from compiled code, with no Python in between.

The ``mujoco`` wheel ships the engine as a shared library (``libmujoco.so.X.Y.Z`` on Linux,
``libmujoco.X.Y.Z.dylib`` on macOS, ``mujoco.dll`` on Windows) next to its Python bindings.
:func:`native_step` opens that same file with :mod:`ctypes` (the dynamic loader hands back the
copy the bindings already loaded, so the model and data structs are the bindings' own) and
returns the address of ``mj_step`` and the raw ``mjModel*`` / ``mjData*`` of a bound model and
data (``MjModel._address``, ``MjData._address``). :func:`call_mj_step` is a numba intrinsic
that calls a ``void f(const mjModel*, mjData*)`` at a given address: the address is an
argument, not a constant baked into the compiled code, so the functions that use it can be
cached by numba (a ctypes function object used inside ``@njit`` cannot be).

``mjData.time`` is a scalar field of the struct, not an array the bindings expose as a view:
:func:`time_view` finds its offset once per process (the field holds a sentinel value written
through the bindings, found by scanning the struct; two sentinels must agree) and returns a
one-element float64 array over it, which compiled code reads after each step.

What the bindings' ``mujoco.mj_step`` adds around the C call is a guard that turns MuJoCo's
fatal errors (``mju_error``, e.g. an arena overflow) into Python exceptions; a direct call
has no such guard, so a fatal error ends the process. The walker (a few contacts, a fixed
arena) never comes near one; its warnings (e.g. an unstable acceleration, which makes MuJoCo
reset the data) behave the same on both paths.

Used by :mod:`afo_mj.gait.walk_loop`; ``benchmarks/gait_step.py`` measures what it saves.
"""

from __future__ import annotations

import ctypes
import dataclasses
import glob
import os

import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

__all__ = ["NativeStep", "NativeStepUnavailable", "native_step", "time_view", "call_mj_step"]

#: file names of the engine library inside the mujoco package, per platform
_LIBRARY_PATTERNS = ("libmujoco.so.*", "libmujoco.so", "libmujoco.*.dylib", "libmujoco.dylib",
                     "mujoco.dll")
#: how far into the mjData struct the time field is looked for (bytes)
_SCAN_LIMIT_BYTES = 1 << 22


class NativeStepUnavailable(RuntimeError):
    """The mujoco wheel's engine library or one of its symbols could not be found."""


@dataclasses.dataclass(frozen=True)
class NativeStep:
    """Addresses for :func:`call_mj_step`: ``mj_step`` and the library it came from."""

    mj_step_address: int
    library_path: str


_cache: dict[str, object] = {}


def _library_path() -> str:
    import mujoco
    here = os.path.dirname(mujoco.__file__)
    for pattern in _LIBRARY_PATTERNS:
        found = sorted(glob.glob(os.path.join(here, pattern)))
        if found:
            return found[0]
    raise NativeStepUnavailable(
        f"no MuJoCo engine library in {here} (looked for {', '.join(_LIBRARY_PATTERNS)}); "
        f"the compiled walk loop needs the library the mujoco wheel ships")


def native_step() -> NativeStep:
    """The address of the engine's ``mj_step`` (once per process)."""
    got = _cache.get("step")
    if got is None:
        path = _library_path()
        try:
            lib = ctypes.CDLL(path)
            fn = lib.mj_step
        except (OSError, AttributeError) as exc:
            raise NativeStepUnavailable(f"cannot load mj_step from {path}: {exc}") from None
        _cache["lib"] = lib                          # keep the handle open
        got = NativeStep(int(ctypes.cast(fn, ctypes.c_void_p).value), path)
        _cache["step"] = got
    return got


def _time_offset(data) -> int:
    """Byte offset of ``time`` in ``mjData`` (found once per process)."""
    off = _cache.get("time_offset")
    if isinstance(off, int):
        return off
    saved = data.time
    base = data._address
    found = None
    try:
        for sentinel in (7.389056098930650e5, -2.718281828459045e-7):
            data.time = sentinel
            target = np.float64(sentinel).tobytes()
            hit = None
            chunk = 4096
            for start in range(0, _SCAN_LIMIT_BYTES, chunk):
                raw = ctypes.string_at(base + start, chunk)
                k = raw.find(target)
                while k >= 0 and (start + k) % 8:
                    k = raw.find(target, k + 1)
                if k >= 0:
                    hit = start + k
                    break
            if hit is None or (found is not None and hit != found):
                raise NativeStepUnavailable("cannot locate mjData.time in the struct")
            found = hit
    finally:
        data.time = saved
    _cache["time_offset"] = found
    return found


def time_view(data) -> np.ndarray:
    """A one-element float64 array over ``data``'s ``time`` field (live: it reads what
    ``mj_step`` writes). ``data`` must outlive the array."""
    off = _time_offset(data)
    ptr = ctypes.cast(data._address + off, ctypes.POINTER(ctypes.c_double))
    view = np.ctypeslib.as_array(ptr, shape=(1,))
    if view[0] != data.time:
        raise NativeStepUnavailable("mjData.time view does not read the bindings' time")
    return view


@intrinsic
def call_mj_step(typingctx, fn_address, model_address, data_address):
    """Call ``void f(const mjModel*, mjData*)`` at ``fn_address`` (integers: addresses)."""
    for a in (fn_address, model_address, data_address):
        if not isinstance(a, types.Integer):
            return None
    sig = types.void(fn_address, model_address, data_address)

    def codegen(context, builder, signature, args):
        fn, m, d = args
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [vp, vp])
        fptr = builder.inttoptr(fn, fnty.as_pointer())
        builder.call(fptr, [builder.inttoptr(m, vp), builder.inttoptr(d, vp)])
        return context.get_dummy_value()

    return sig, codegen
