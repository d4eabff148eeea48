"""C-callable entry points of a generated circuit's coupled step, for loops in compiled code.

A compiled walk loop (:mod:`afo_mj.gait.walk_loop`) steps a worn circuit between MuJoCo
steps without returning to Python. It cannot call the circuit's numba functions by name (one
loop serves every circuit, and numba does not cache a function specialised on another
function), so it calls them by address: for a circuit built by
:func:`afo_mj.circuits.codegen.build` (module ``circuit_<digest>.py``), :func:`entry_points`
writes a small companion module ``circuit_<digest>_native.py`` beside it (once,
:func:`afo_mj.circuits.codegen.write_once`) with two ``numba.cfunc`` wrappers, compiled and
cached on disk by numba, and returns their addresses:

``begin(t, angle2*, velocity2*, stance2*, buf*, meta*)`` (``void``)
    :func:`afo_mj.circuits.stepper.device_begin` on arrays of the given pointers: walker-side
    angle, velocity and stance flag (``2`` float64 each), the device buffer (``meta[M_END]``
    float64) and its layout (``N_META + meta[M_NS]`` int64).
``end(velocity2*, buf*, meta*, log*, n_log, n_fields, n_sides, k, t)`` (``int64``)
    :func:`afo_mj.circuits.stepper.device_end`, the log a C array ``n_log × n_fields ×
    n_sides``; returns its code (0 non-finite, 1 stepped, 2 stepped and logged).

The companion is imported only when a compiled loop asks for it, so circuits used only on a
bench or in a calibration compile nothing more. The wrapped functions are the module's own
(``device_begin``/``device_end``, the one stepper), called with C-contiguous arrays.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
import threading
from pathlib import Path

from afo_mj.circuits.codegen import write_once

__all__ = ["NativeEntryPoints", "NativeCoupling", "entry_points", "companion_source"]


@dataclasses.dataclass(frozen=True)
class NativeEntryPoints:
    """Addresses of a circuit's ``begin`` and ``end`` cfuncs (see the module docstring)."""

    begin_address: int
    end_address: int


@dataclasses.dataclass(frozen=True)
class NativeCoupling:
    """What a compiled loop needs to step a worn circuit (``CircuitDevice.native_coupling``):
    the entry points, the device buffer and its layout, the device log (``steps × fields ×
    sides``, possibly with no rows) and views of the buffer's per-walker-side joint force,
    extra damping and delivered torque (length 2 each)."""

    begin_address: int
    end_address: int
    buffer: object
    meta: object
    log: object
    force2: object
    damping2: object
    delivered2: object


_TEMPLATE = '''"""C entry points of the coupled step of the generated circuit module {modname}
(written by afo_mj.circuits.native_entry; see its docstring)."""

import numba
from numba import carray, types

from {modname} import M_END, M_NS, N_META, device_begin, device_end

_F = types.CPointer(types.float64)
_I = types.CPointer(types.int64)


@numba.cfunc(types.void(types.float64, _F, _F, _F, _F, _I), cache=True, error_model="numpy")
def begin(t, angle2, velocity2, stance2, buf, meta):
    device_begin(t, carray(angle2, (2,)), carray(velocity2, (2,)), carray(stance2, (2,)),
                 carray(buf, (meta[M_END],)), carray(meta, (N_META + meta[M_NS],)))


@numba.cfunc(types.int64(_F, _F, _I, _F, types.int64, types.int64, types.int64, types.int64,
                         types.float64), cache=True, error_model="numpy")
def end(velocity2, buf, meta, log, n_log, n_fields, n_sides, k, t):
    return device_end(carray(velocity2, (2,)), carray(buf, (meta[M_END],)),
                      carray(meta, (N_META + meta[M_NS],)),
                      carray(log, (n_log, n_fields, n_sides)), k, t)
'''

_loaded: dict[str, NativeEntryPoints] = {}
_lock = threading.Lock()


def companion_source(modname: str) -> str:
    """The companion module's text for the generated module ``modname``."""
    return _TEMPLATE.format(modname=modname)


def entry_points(compiled_circuit) -> NativeEntryPoints:
    """The ``begin``/``end`` cfunc addresses of a built circuit (a
    :class:`~afo_mj.circuits.codegen.CompiledCircuit`); writes, compiles or loads its
    companion module on the first call in a process."""
    path = Path(compiled_circuit.source_path)
    digest = path.stem.removeprefix("circuit_")
    modname = compiled_circuit.module.__name__
    with _lock:
        got = _loaded.get(modname)
        if got is not None:
            return got
        native = path.with_name(f"{path.stem}_native.py")
        write_once(native, companion_source(modname))
        name = f"afo_mj_circuit_{digest}_native"
        module = sys.modules.get(name)
        if module is None:
            spec = importlib.util.spec_from_file_location(name, native)
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                sys.modules.pop(name, None)
                raise
        got = NativeEntryPoints(int(module.begin.address), int(module.end.address))
        _loaded[modname] = got
        return got
