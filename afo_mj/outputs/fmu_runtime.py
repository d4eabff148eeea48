"""What runs inside an exported FMU (:mod:`afo_mj.outputs.fmu_export`): the FMI 2.0
co-simulation calls of the compiled shim (``afo_mj/outputs/fmu_shim.c``), answered by a
:class:`~afo_mj.circuits.device.CircuitDevice` of the exported circuit.

A communication step ``[t, t + h]`` is one sample of
:meth:`CircuitDevice.run_imposed <afo_mj.circuits.device.CircuitDevice.run_imposed>`, the
native replay's compiled loop, split into ``ceil(h / timestep_s)`` equal sub-steps of at most
the exported ``timestep_s``, with the joint angle, its velocity and the command the host set
held over the step. A host that also gives the inputs' first derivatives
(``fmi2SetRealInputDerivatives``, ``canInterpolateInputs``) has the angle and velocity ramped
linearly over the sub-steps, as the native replay interpolates between samples, and the
command held at each sub-step's midpoint value. The outputs
are the state at ``t + h`` and the joint torque, probes, battery current and bus voltage of
the step's end. Before the first step the outputs that are not states (joint torque, battery
current, bus voltage, battery power, currents that are probes) read 0.

The shim passes value references and values as addresses (``get_real``/``set_real``); every
function returns an FMI status (0 OK, 3 error) and keeps its message for
:func:`take_message`, so no Python exception crosses into the host.
"""

from __future__ import annotations

import ctypes
import functools
import json
import math
import pickle
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np

OK, WARNING, DISCARD, ERROR, FATAL = range(5)
#: the FMU's configuration and its circuit, in its resources folder
CONFIG_NAME = "afo_mj_fmu.json"
CIRCUIT_NAME = "circuit.pickle"

_INSTANCES: dict = {}
_MESSAGES: dict = {0: []}
_NEXT = [1]


class FmuRuntimeError(RuntimeError):
    """A call the FMU cannot honour (its message goes to the host's logger)."""


def _guarded(fn):
    """Run ``fn(handle, ...)``; an exception becomes an error status with its message kept
    for the instance (``handle`` 0: instantiation)."""
    @functools.wraps(fn)
    def call(handle, *args):
        try:
            return fn(handle, *args)
        except Exception as exc:  # noqa: BLE001 - nothing may cross into the C host
            text = str(exc) if isinstance(exc, FmuRuntimeError) else \
                f"{type(exc).__name__}: {exc}"
            _MESSAGES.setdefault(handle, []).append(text)
            return ERROR
    return call


def resource_folder(uri: str) -> Path:
    """The folder of an FMI ``fmuResourceLocation`` (a ``file:`` URI)."""
    u = urlparse(uri)
    if u.scheme not in ("file", ""):
        raise FmuRuntimeError(f"fmuResourceLocation = {uri!r}; allowed: a file: URI")
    return Path(unquote(u.path))


def circuit_with(circuit, changes: dict):
    """The circuit with parameters changed by their FMU names (``component.dotted.name``,
    ``controller.*``, ``fluid.*``, ``thermal.*``, ``options.*``); each changed set is
    validated again (:func:`afo_mj.hydraulics.params.replace_named`)."""
    import copy
    from afo_mj.circuits.circuit import Circuit
    from afo_mj.hydraulics.params import replace_named
    grouped: dict = {}
    for name, v in changes.items():
        head, _, rest = name.partition(".")
        grouped.setdefault(head, {})[rest] = v
    comps = []
    for c in circuit.components:
        if c.name in grouped:
            c = copy.copy(c)
            c.params = replace_named(c.params, grouped.pop(c.name))
        comps.append(c)
    ctrl = circuit.controller
    if "controller" in grouped:
        ctrl = copy.copy(ctrl)
        ctrl.params = replace_named(ctrl.params, grouped.pop("controller"))
    sets = {k: getattr(circuit, k) for k in ("fluid", "thermal", "options")}
    for k in sets:
        if k in grouped:
            sets[k] = replace_named(sets[k], grouped.pop(k))
    if grouped:
        raise FmuRuntimeError(f"parameters {sorted(grouped)} name no part of circuit "
                              f"{circuit.name!r}")
    return Circuit(circuit.name, comps, circuit.nodes, ctrl, **sets)


class _Instance:
    """One FMU instance: its variables' values by value reference and, after
    initialisation, its device."""

    def __init__(self, folder: Path, name: str, guid: str):
        import afo_mj
        cfg = json.loads((folder / CONFIG_NAME).read_text())
        if guid and guid != cfg["guid"]:
            raise FmuRuntimeError(f"fmuGUID = {guid!r}; this FMU's resources are "
                                  f"{cfg['guid']!r} (modelDescription.xml and resources "
                                  "from different exports)")
        if afo_mj.__version__ != cfg["afo_mj_version"]:
            raise FmuRuntimeError(
                f"the FMU was exported with afo_mj {cfg['afo_mj_version']}; this host's "
                f"afo_mj is {afo_mj.__version__} ({Path(afo_mj.__file__).parent}); allowed: "
                "the same version")
        with open(folder / CIRCUIT_NAME, "rb") as f:
            self.circuit = pickle.load(f)
        self.cfg = cfg
        self.name = name
        self.vars = cfg["variables"]
        self.start = np.array([float(v.get("start", 0.0)) for v in self.vars])
        self.causality = [v["causality"] for v in self.vars]
        self.reset()

    def reset(self):
        self.values = self.start.copy()
        #: first time derivatives of the three inputs over the coming step
        self.derivs = np.zeros(3)
        self.dev = None
        self.time_s = 0.0
        self.stop_s = None
        self.mode = "instantiated"
        self.broken = False

    # -- initialisation ------------------------------------------------------------------
    def exit_initialization(self):
        from afo_mj.circuits.codegen import build
        from afo_mj.circuits.device import CircuitDevice
        changes = {v["name"]: float(self.values[i]) for i, v in enumerate(self.vars)
                   if v["causality"] == "parameter" and self.values[i] != self.start[i]}
        circuit = circuit_with(self.circuit, changes) if changes else self.circuit
        cc = build(circuit)
        if not changes and cc.source_path.stem != self.cfg["kernel"]:
            raise FmuRuntimeError(
                f"this host's afo_mj generates kernel {cc.source_path.stem} for circuit "
                f"{circuit.name!r}; the FMU was exported with {self.cfg['kernel']} (the "
                "circuit code differs): export it again with this afo_mj")
        self.dev = CircuitDevice(cc, timestep_s=self.cfg["timestep_s"],
                                 initial_state=self.cfg["initial_state"])
        self._signals = {}
        for i, v in enumerate(self.vars):
            if v["causality"] == "output":
                sig = v["signal"]
                self._signals[i] = sig
                if sig in cc.state_names:
                    self.values[i] = self.dev.Y[0, cc.index(sig)]
                else:
                    self.values[i] = 0.0
        self.mode = "step"

    # -- stepping ------------------------------------------------------------------------
    def do_step(self, t: float, h: float):
        if self.dev is None:
            raise FmuRuntimeError("fmi2DoStep before fmi2ExitInitializationMode")
        if self.broken:
            raise FmuRuntimeError("fmi2DoStep after a failed step; allowed: fmi2Reset first")
        if not (h > 0 and math.isfinite(h)):
            raise FmuRuntimeError(f"communicationStepSize = {h!r}; allowed: > 0")
        if abs(t - self.time_s) > 1e-9 * max(1.0, abs(t)):
            raise FmuRuntimeError(f"currentCommunicationPoint = {t!r}; the FMU is at "
                                  f"{self.time_s!r} (allowed: the end of the last step)")
        dev = self.dev
        dt = self.cfg["timestep_s"]
        sub = max(1, math.ceil(h / dt - 1e-9))
        hs = h / sub
        if dev.S[0, 0, 0] != hs:
            # another sub-step length: the kept prediction matrix I - h J is rebuilt
            dev.S[:, 0, 0] = hs
            dev.S[:, 0, 1] = 0.0
        u0, th0, thd0 = (float(self.values[k]) for k in (0, 1, 2))
        du, dth, dthd = (float(x) for x in self.derivs)
        if du == dth == dthd == 0.0:
            # held over the step: one sample, nothing to interpolate towards
            u, th, thd, run_sub = np.array([u0]), np.array([th0]), np.array([thd0]), sub
        else:
            # first derivatives given (fmi2SetRealInputDerivatives): the angle and velocity
            # ramp linearly over the sub-steps, as the native replay interpolates samples,
            # and each sub-step holds the command at its midpoint (BenchReplay's linear hold)
            s = np.arange(sub + 1) * hs
            th, thd = th0 + dth * s, thd0 + dthd * s
            u = u0 + du * (s[:-1] + 0.5 * hs)
            run_sub = 1
        try:
            log = dev.run_imposed(u, th, thd, substeps=run_sub)
        except FloatingPointError as exc:
            self.broken = True
            raise FmuRuntimeError(f"step [{t}, {t + h}] s: {exc}") from None
        for i, sig in self._signals.items():
            if sig == "battery_power_w":
                self.values[i] = log["battery_current_a"][-1] * log["bus_voltage_v"][-1]
            else:
                self.values[i] = log[sig][-1]
        self.time_s = t + h
        # the derivatives hold for this step only (FMI 2.0: they are set before each step)
        self.derivs[:] = 0.0

    # -- values --------------------------------------------------------------------------
    def _refs(self, vr_addr: int, n: int) -> np.ndarray:
        vr = np.ctypeslib.as_array((ctypes.c_uint * n).from_address(vr_addr)).astype(np.int64)
        bad = vr[(vr < 0) | (vr >= len(self.vars))]
        if bad.size:
            raise FmuRuntimeError(f"value reference {int(bad[0])} is unknown; allowed: "
                                  f"0 … {len(self.vars) - 1}")
        return vr

    def get_real(self, vr_addr: int, n: int, val_addr: int):
        if n == 0:
            return
        vr = self._refs(vr_addr, n)
        out = np.ctypeslib.as_array((ctypes.c_double * n).from_address(val_addr))
        out[:] = self.values[vr]

    def set_input_derivatives(self, vr_addr: int, n: int, order_addr: int, val_addr: int):
        if n == 0:
            return
        vr = self._refs(vr_addr, n)
        order = np.ctypeslib.as_array((ctypes.c_int * n).from_address(order_addr))
        vals = np.ctypeslib.as_array((ctypes.c_double * n).from_address(val_addr))
        for r, o, v in zip(vr.tolist(), order.tolist(), vals.tolist()):
            name = self.vars[r]["name"]
            if self.causality[r] != "input":
                raise FmuRuntimeError(f"fmi2SetRealInputDerivatives: {name} is no input")
            if o != 1:
                raise FmuRuntimeError(f"fmi2SetRealInputDerivatives: order {o} of {name}; "
                                      "allowed: 1 (first derivatives: canInterpolateInputs)")
            if not math.isfinite(v):
                raise FmuRuntimeError(f"derivative of {name} = {v!r}; allowed: finite")
            self.derivs[r] = v

    def set_real(self, vr_addr: int, n: int, val_addr: int):
        if n == 0:
            return
        vr = self._refs(vr_addr, n)
        vals = np.ctypeslib.as_array((ctypes.c_double * n).from_address(val_addr)).copy()
        for r, v in zip(vr.tolist(), vals.tolist()):
            c = self.causality[r]
            name = self.vars[r]["name"]
            if c == "output":
                raise FmuRuntimeError(f"{name} is an output; allowed: set inputs and "
                                      "parameters")
            if c == "parameter" and self.mode == "step":
                raise FmuRuntimeError(f"{name} is a fixed parameter; allowed: set it before "
                                      "fmi2ExitInitializationMode")
            if not math.isfinite(v):
                raise FmuRuntimeError(f"{name} = {v!r}; allowed: a finite number")
            lo, hi = self.vars[r].get("min"), self.vars[r].get("max")
            if (lo is not None and v < lo) or (hi is not None and v > hi):
                raise FmuRuntimeError(f"{name} = {v!r}; allowed: {lo} … {hi}")
        self.values[vr] = vals


def _inst(handle: int) -> _Instance:
    if handle not in _INSTANCES:
        raise FmuRuntimeError(f"no FMU instance {handle}")
    return _INSTANCES[handle]


def instantiate(resource_uri: str, name: str, guid: str) -> int:
    """A new instance's handle (> 0), or 0 with the reason in ``take_message(0)``."""
    try:
        inst = _Instance(resource_folder(resource_uri), name, guid)
    except Exception as exc:  # noqa: BLE001
        text = str(exc) if isinstance(exc, FmuRuntimeError) else f"{type(exc).__name__}: {exc}"
        _MESSAGES[0].append(f"instantiating {name!r}: {text}")
        return 0
    h = _NEXT[0]
    _NEXT[0] += 1
    _INSTANCES[h] = inst
    _MESSAGES[h] = []
    return h


def take_message(handle: int) -> str:
    """The messages kept for ``handle`` since the last call (cleared)."""
    msgs = _MESSAGES.get(handle, [])
    text = "; ".join(msgs)
    msgs.clear()
    return text


def free(handle: int) -> int:
    _INSTANCES.pop(handle, None)
    _MESSAGES.pop(handle, None)
    return OK


@_guarded
def setup_experiment(handle: int, start: float, stop_defined: int, stop: float) -> int:
    inst = _inst(handle)
    inst.time_s = float(start)
    inst.stop_s = float(stop) if stop_defined else None
    return OK


@_guarded
def enter_initialization(handle: int) -> int:
    _inst(handle).mode = "initialization"
    return OK


@_guarded
def exit_initialization(handle: int) -> int:
    _inst(handle).exit_initialization()
    return OK


@_guarded
def terminate(handle: int) -> int:
    _inst(handle).mode = "terminated"
    return OK


@_guarded
def reset(handle: int) -> int:
    _inst(handle).reset()
    return OK


@_guarded
def get_real(handle: int, vr_addr: int, n: int, val_addr: int) -> int:
    _inst(handle).get_real(vr_addr, n, val_addr)
    return OK


@_guarded
def set_real(handle: int, vr_addr: int, n: int, val_addr: int) -> int:
    _inst(handle).set_real(vr_addr, n, val_addr)
    return OK


@_guarded
def set_input_derivatives(handle: int, vr_addr: int, n: int, order_addr: int,
                          val_addr: int) -> int:
    _inst(handle).set_input_derivatives(vr_addr, n, order_addr, val_addr)
    return OK


@_guarded
def do_step(handle: int, t: float, h: float) -> int:
    _inst(handle).do_step(float(t), float(h))
    return OK


@_guarded
def last_time(handle: int, addr: int) -> int:
    ctypes.c_double.from_address(addr).value = _inst(handle).time_s
    return OK
