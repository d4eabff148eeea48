"""Replay a measured bench record through a device model: measured inputs in, model outputs out.

On the ankle test stand the ankle angle is imposed (a motor or a position-controlled load
drives it), so the orthosis's hydraulics see the ankle only through the cylinders' kinematics
``x = r θ``, ``ẋ = r θ̇``. The replay therefore needs no multibody step: it drives the
device's generated circuit (:func:`afo_mj.devices.hafo.hafo_circuit` for the pump-controlled
HAFO, :func:`afo_mj.devices.valve_afo.valve_circuit` for the valve circuits) with the measured
inputs, sample by sample, in the circuits' one compiled replay loop
(:meth:`afo_mj.circuits.device.CircuitDevice.run_imposed`: the coupled step with the joint
motion imposed; linearly implicit prediction, Newton-corrected backward Euler, adaptive
sub-steps). The circuit is compiled once per topology; a replay only writes the packed
parameter row, so a calibration, which replays a record hundreds of times, never recompiles
(``benchmarks/calibrate.py``). ``tests/test_bench_replay.py`` checks the replay against the
device stepped on the MuJoCo test stand with the same imposed angle.

Inputs (channel names of :data:`afo_mj.calibration.measured_data.CHANNELS`):

* ``ankle_angle_rad`` (required): imposed angle. The velocity is its Savitzky–Golay derivative
  (cubic, 21-sample window: encoder noise is not differentiated into the flow ``A_e r θ̇``).
* ``motor_voltage_v`` (HAFO, open loop: the driver's voltage command), or ``valve_command``
  (valve circuits, open loop: the spool command ``u ∈ [−1, 1]``, or the digital valve's duty);
  or, for either, ``commanded_torque_nm``: the torque reference of the device's own low-level
  torque controller, which then runs in the replay on the model's pressures (closed loop: a
  device tracking a profile on the bench, or in a walk whose measured ankle kinematics are
  replayed as the imposed angle).
* ``fluid_temperature_k`` (optional): the oil temperature, which sets the viscosity
  (Walther, ASTM D341). Without it the temperature is prescribed as ``T_0 + ṫ (t − t_0)``
  (``temperature_rate_k_s``, 0 by default: isothermal at the preset's ambient temperature).

The step is the record's sample period, split into equal sub-steps of at most 0.5 ms
(:attr:`BenchReplay.max_step_s`). The imposed angle, its velocity and the oil temperature are
interpolated linearly over the sub-steps (measured continuous quantities). The command is held
as declared per channel (:attr:`BenchReplay.hold`, :data:`HOLDS`): ``"zero_order"`` (a digital
command that steps at the sample instants and is held between them, as a DAC or a PWM driver
updated at the record's rate produces it) or ``"linear"`` (a sampled continuous signal, e.g. an
analog voltage: each sub-step holds the linear interpolation at its midpoint). Undeclared, a
preset holds its command zero-order (the presets' records are digital commands) and a
described circuit linearly (:attr:`BenchReplay.default_hold`); the calibration checks the
choice against the data (:mod:`afo_mj.calibration.sampling`). Output sample ``k`` is
the state at ``t_k``; sample 0 is the device's initial state (every pressure node at the
reservoir pressure; the valve circuits' supply at its initial pressure).

Transmission effects that act on the kinematics before the hydraulics see them (backlash) are
applied here with :func:`afo_mj.hydraulics.transmission.play_operator`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping

import numpy as np
from scipy.signal import savgol_filter

from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.codegen import build
from afo_mj.circuits.device import CircuitDevice, JointLoad
from afo_mj.devices.hafo import PRESETS as HAFO_PRESETS, hafo_circuit, hafo_params
from afo_mj.devices.valve_afo import (
    VALVE_PRESETS, valve_circuit, valve_initial_state, valve_params)
from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.transmission import play_operator

__all__ = ["BenchReplay", "HOLDS", "HELD_CHANNELS", "REPLAY_OUTPUTS", "REPLAY_INPUTS",
           "ReplayError", "kind_of_preset"]


class ReplayError(RuntimeError):
    """The model could not be replayed (a state became non-finite, or inputs are missing)."""


#: output channels each kind of replay produces
REPLAY_OUTPUTS = {
    "hafo": ("pressure_a_pa", "pressure_b_pa", "chamber_a_pa", "chamber_b_pa",
             "ankle_torque_nm", "motor_current_a", "motor_speed_rad_s", "fluid_temperature_k",
             "battery_current_a", "bus_voltage_v"),
    "valve": ("pump_pressure_pa", "supply_pressure_pa", "pressure_a_pa", "pressure_b_pa",
              "chamber_a_pa", "chamber_b_pa", "valve_position", "ankle_torque_nm",
              "motor_current_a", "motor_speed_rad_s", "fluid_temperature_k"),
}
#: the open-loop command input of each kind (besides the imposed ankle angle)
REPLAY_INPUTS = {"hafo": ("motor_voltage_v", "ankle_angle_rad"),
                 "valve": ("valve_command", "ankle_angle_rad")}
#: the command channels each kind accepts, in order of preference: the open-loop command, or
#: the torque reference of the device's own low-level torque controller (closed loop)
REPLAY_COMMANDS = {"hafo": ("motor_voltage_v", "commanded_torque_nm"),
                   "valve": ("valve_command", "commanded_torque_nm")}
#: how an input channel is held over a sample interval (see the module docstring)
HOLDS = ("zero_order", "linear")
#: the channels whose hold the replay applies: the command channels (the imposed angle, its
#: velocity and the oil temperature are always interpolated linearly)
HELD_CHANNELS = ("motor_voltage_v", "valve_command", "commanded_torque_nm")
#: the circuit signal behind each output channel (a state label, a probe, or a replay-log
#: column); a tuple lists alternatives, the first the circuit has is read
_SIGNALS = {
    "pressure_a_pa": ("line_a", "port_a"), "pressure_b_pa": ("line_b", "port_b"),
    "chamber_a_pa": "chamber_a", "chamber_b_pa": "chamber_b",
    "pump_pressure_pa": "pump_out", "supply_pressure_pa": "rail",
    "valve_position": ("servo.spool", "switching.position"),
    "ankle_torque_nm": "torque_nm", "motor_current_a": "motor.current_a",
    "motor_speed_rad_s": "shaft", "battery_current_a": "battery_current_a",
    "bus_voltage_v": "bus_voltage_v", "piston_position_m": "cylinders.piston_position_m",
}


#: the output channels a described circuit may produce (those whose signal it has), besides
#: the oil temperature and, with a simulated load, the ankle angle
CIRCUIT_OUTPUTS = ("pressure_a_pa", "pressure_b_pa", "chamber_a_pa", "chamber_b_pa",
                   "ankle_torque_nm", "motor_current_a", "motor_speed_rad_s",
                   "piston_position_m", "battery_current_a", "bus_voltage_v")
#: the simulated load's parameters as pseudo-labels of the packed row (a fit sets them like
#: any circuit parameter)
LOAD_LABELS = ("load.inertia_kg_m2", "load.stiffness_nm_rad", "load.damping_nm_s_rad")


def circuit_geometry(circuit: Circuit):
    """The parameters of the circuit's piston-cable ``pulley_cylinders`` (stroke, pulley
    radius: what the record checks compare the angle with), or None."""
    for c in circuit.components:
        prm = getattr(c, "params", None)
        cyl = getattr(prm, "cylinder", None)
        if cyl is not None and hasattr(prm, "pulley_radius_m"):
            return prm
    return None


#: component kinds that play the presets' roles (label prefixes of the calibration's
#: parameters and effects)
_ROLE_KINDS = {"cylinders": ("pulley_cylinders",), "pump": ("pump", "variable_pump"),
               "motor": ("motor",), "hose_a": ("hose",), "hose_b": ("hose",),
               "charge": ("reservoir",), "check_a": ("check_valve",),
               "check_b": ("check_valve",), "servo": ("servo_valve",)}


def circuit_roles(circuit: Circuit) -> dict[str, str]:
    """Role → component name of a described circuit: the first ``pulley_cylinders`` plays
    ``cylinders``, the first and second hoses ``hose_a`` and ``hose_b``, and so on (a
    component whose name already is the role's keeps it)."""
    names = {c.name: c.kind for c in circuit.components}
    used: set = set()
    roles: dict[str, str] = {}
    for role, kinds in _ROLE_KINDS.items():
        if names.get(role) in kinds:
            roles[role] = role
            used.add(role)
    for role, kinds in _ROLE_KINDS.items():
        if role in roles:
            continue
        for c in circuit.components:
            if c.kind in kinds and c.name not in used:
                roles[role] = c.name
                used.add(c.name)
                break
    return roles


def kind_of_preset(preset: str, key: str = "source.preset") -> str:
    """``"hafo"`` for a pump-controlled preset, ``"valve"`` for a valve circuit's; ``key``
    names where the preset came from in the error (a record's ``source.preset``, a command's
    ``--scenario`` option, ...)."""
    if preset in HAFO_PRESETS:
        return "hafo"
    if preset in VALVE_PRESETS:
        return "valve"
    from afo_mj.scenarios.walk_scenario import did_you_mean
    names = list(HAFO_PRESETS) + list(VALVE_PRESETS)
    raise ParameterError(f"{key} = {preset!r} is not a device preset{did_you_mean(preset, names)}"
                         f"; allowed: {', '.join(names)}")


def ankle_velocity(theta_rad: np.ndarray, dt_s: float) -> np.ndarray:
    """Savitzky–Golay (1964) derivative of the imposed angle: a cubic fitted over 21 samples
    (fewer for short records), evaluated at the window centre."""
    n = len(theta_rad)
    win = min(21, n - (1 - n % 2))
    if win < 5:
        return np.gradient(theta_rad, dt_s)
    return savgol_filter(theta_rad, win, 3, deriv=1, delta=dt_s, mode="interp")


class BenchReplay:
    """A device preset (with dotted-name ``overrides``) ready to replay records.

    ``kind`` is ``"hafo"`` or ``"valve"`` (default: from the preset). The generated circuit's
    packed parameter row is :attr:`base_row`, its entries named by :attr:`param_labels`
    (``component.key``, :attr:`afo_mj.circuits.codegen.CompiledCircuit.param_labels`);
    :meth:`simulate` takes per-run changes to it by label, which is how the calibration sets
    fitted parameters and switches effects on without rebuilding or recompiling the device.
    The HAFO is built with its torque controller: a measured motor voltage is imposed on the
    motor's input (open loop), a torque reference runs the controller (closed loop). The valve
    circuits read a measured valve command through their controller's
    ``controller.valve_command_on`` switch.
    """

    def __init__(self, preset: str | None = None,
                 overrides: Mapping[str, object] | None = None, kind: str | None = None, *,
                 circuit: Circuit | None = None, load: JointLoad | None = None,
                 signals: Mapping[str, str] | None = None,
                 hold: Mapping[str, str] | None = None):
        self.load = load
        self._signal_overrides = dict(signals or {})
        #: how an undeclared command is held over a sample interval: ``"zero_order"`` (a
        #: digital command, the presets' records) or ``"linear"`` (a sampled continuous
        #: signal, a described rig's default: interpolated between the samples)
        self.default_hold = "linear" if circuit is not None else "zero_order"
        #: declared hold per command channel (:meth:`set_hold`); others use default_hold
        self.hold: dict[str, str] = {}
        self.set_hold(hold or {})
        if circuit is not None:
            self._init_circuit(circuit, load)
            return
        if load is not None:
            raise ParameterError("a simulated load is available for a described circuit "
                                 "([circuit] with [load]); the presets replay the imposed angle")
        self.preset = preset
        self.kind = kind or kind_of_preset(preset)
        if self.kind == "hafo":
            params = hafo_params(dict(overrides or {}), preset)
            circuit = hafo_circuit(params, mode="torque")
            self.initial_state = {}
        elif self.kind == "valve":
            params = valve_params(dict(overrides or {}), preset)
            circuit = valve_circuit(params)
            self.initial_state = valve_initial_state(params)
        else:
            raise ParameterError(f"kind = {self.kind!r}; allowed: hafo, valve")
        self.params = params
        self.cc = build(circuit)
        self.base_row = self.cc.P.copy()
        self.param_labels = self.cc.param_labels
        self._label_index = {lab: i for i, lab in enumerate(self.param_labels)}
        self.outputs = REPLAY_OUTPUTS[self.kind]
        self.inputs = REPLAY_INPUTS[self.kind]
        self.ambient_temperature_k = float(params.ambient_temperature_k)
        # 0.5 ms, not the stand's 1 ms: a 1 ms backward-Euler step through a fast valve event
        # (the flushing valve shuttling while the pump reverses the lines) lands up to 160 kPa
        # away from the same interval taken in sub-steps, and whether the stepper falls back to
        # sub-steps flips with a 0.025 % change of a parameter: the replay jumps as a function
        # of the fitted parameters and the calibration's fit stalls beside the truth (mismatch
        # record: pressure_b residual 1.26× the noise at 1 ms, 1.016× at 0.5 ms, 1.009× at
        # 0.25 ms; the old kernel's 1.01× at 1 ms)
        self.max_step_s = 5e-4
        self._columns = {name: self._signal(name) for name in self.outputs
                         if name != "fluid_temperature_k"}

    def set_hold(self, hold: Mapping[str, str], key: str = "hold") -> None:
        """Declare how command channels are held (channel → one of :data:`HOLDS`); ``key``
        names where the declaration came from in the error. Channels not named keep what
        they had. Only :data:`HELD_CHANNELS` are held by the replay; ``"linear"`` for the
        imposed angle or the oil temperature is accepted (it is what the replay does),
        ``"zero_order"`` for them is refused."""
        for ch, h in hold.items():
            if h not in HOLDS:
                raise ParameterError(f"{key}.{ch} = {h!r}; allowed: {', '.join(HOLDS)}")
            if ch in ("ankle_angle_rad", "fluid_temperature_k"):
                if h != "linear":
                    raise ParameterError(
                        f"{key}.{ch} = {h!r}: the replay interpolates the imposed angle and "
                        f"the oil temperature linearly (measured continuous quantities); "
                        f"allowed: linear (zero_order applies to the command channels "
                        f"{', '.join(HELD_CHANNELS)})")
                continue
            if ch not in HELD_CHANNELS:
                ok = HELD_CHANNELS + ("ankle_angle_rad", "fluid_temperature_k")
                raise ParameterError(f"{key}.{ch}: not a replayed input channel; allowed: "
                                     f"{', '.join(ok)}")
            self.hold[ch] = h

    def hold_of(self, channel: str) -> str:
        """How ``channel`` is held: its declaration, else :attr:`default_hold`."""
        return self.hold.get(channel, self.default_hold)

    def _init_circuit(self, circuit: Circuit, load: JointLoad | None) -> None:
        """A described circuit (the user's rig): outputs are the channels its signals
        produce; with ``load`` the joint is simulated and the angle is an output."""
        self.kind = "circuit"
        self.preset = circuit.name
        self.circuit = circuit
        self.params = circuit_geometry(circuit)
        self.cc = build(circuit)
        self.initial_state = {}
        self.base_row = self.cc.P.copy()
        self.roles = circuit_roles(circuit)
        self.param_labels = tuple(self.cc.param_labels) + (LOAD_LABELS if load else ())
        self._label_index = {lab: i for i, lab in enumerate(self.param_labels)}
        self.open_loop = circuit.controller.kind == "open_loop"
        self.inputs = ("motor_voltage_v",) if self.open_loop else ("commanded_torque_nm",)
        self.ambient_temperature_k = float(circuit.thermal.ambient_temperature_k)
        self.max_step_s = 5e-4
        cols = {}
        for name in CIRCUIT_OUTPUTS:
            try:
                cols[name] = self._signal(name)
            except ReplayError:
                continue
        self._columns = cols
        self.outputs = tuple(cols) + ("fluid_temperature_k",) + (
            ("ankle_angle_rad",) if load else ())
        self._piston_zero = 0.0
        cyl = self.params
        if cyl is not None:
            self._piston_zero = 0.5 * float(cyl.cylinder.stroke_m)

    def _signal(self, channel: str) -> str:
        names = set(self.cc.state_names) | set(self.cc.probe_names) | {
            "torque_nm", "battery_current_a", "bus_voltage_v"}
        if channel in self._signal_overrides:
            sig = self._signal_overrides[channel]
            if sig not in names:
                raise ParameterError(
                    f"sensors.{channel}.signal = {sig!r} is not a state or probe of the "
                    f"circuit {self.cc.circuit.name!r}; allowed: {', '.join(sorted(names))}")
            return sig
        if channel not in _SIGNALS:
            raise ReplayError(f"no default signal for {channel}")
        alts = _SIGNALS[channel]
        roles = getattr(self, "roles", {})
        for a in (alts if isinstance(alts, tuple) else (alts,)):
            comp, _, key = a.partition(".")
            if key and comp in roles:
                a = f"{roles[comp]}.{key}"
            if a in names:
                return a
        raise ReplayError(f"circuit {self.cc.circuit.name!r} has no signal for {channel} "
                          f"(looked for {alts!r})")

    def resolve(self, label: str) -> str:
        """The circuit's own label of ``label``: a described circuit answers to the presets'
        component names by role (``cylinders.seal_fc`` is its ``pulley_cylinders``
        component's, ``hose_a.wall_inv`` its first hose's; :func:`circuit_roles`)."""
        roles = getattr(self, "roles", None)
        if roles and label not in self._label_index and "." in label:
            comp, key = label.split(".", 1)
            if comp in roles:
                return f"{roles[comp]}.{key}"
        return label

    def index(self, label: str) -> int:
        """Position of the packed parameter ``label`` in :attr:`base_row`."""
        label = self.resolve(label)
        try:
            return self._label_index[label]
        except KeyError:
            raise ParameterError(f"circuit parameter {label!r} is not in the "
                                 f"{self.cc.circuit.name!r} circuit; allowed: "
                                 f"{', '.join(self.param_labels)}") from None

    def has(self, label: str) -> bool:
        """Whether the circuit packs parameter ``label``."""
        return self.resolve(label) in self._label_index

    def value(self, label: str) -> float:
        """The preset's value of the packed parameter ``label`` (a described circuit's
        simulated load: ``load.inertia_kg_m2``, ``load.stiffness_nm_rad``,
        ``load.damping_nm_s_rad``)."""
        label = self.resolve(label)
        if label in LOAD_LABELS and self.load is not None:
            return float(getattr(self.load, label.split(".", 1)[1]))
        return float(self.base_row[self.index(label)])

    def check_inputs(self, channels) -> tuple[str, str]:
        """The record's command channel and the imposed angle: ``(command, "ankle_angle_rad")``
        (the open-loop command when the record has it, else ``commanded_torque_nm``)."""
        if self.kind == "circuit":
            cmd = self.inputs[0]
            if cmd not in channels or (self.load is None and "ankle_angle_rad" not in channels):
                need = [cmd] + ([] if self.load else ["ankle_angle_rad"])
                raise ReplayError(f"the {self.preset!r} circuit replay needs {need} (its "
                                  f"{self.circuit.controller.kind} controller"
                                  + ("" if self.load else "; the joint angle is imposed")
                                  + f"); the record has {sorted(channels)}")
            return (cmd,) if self.load else (cmd, "ankle_angle_rad")
        cmds = [c for c in REPLAY_COMMANDS[self.kind] if c in channels]
        if not cmds or "ankle_angle_rad" not in channels:
            raise ReplayError(f"the {self.kind} bench replay needs ankle_angle_rad and one of "
                              f"{list(REPLAY_COMMANDS[self.kind])}; the record has "
                              f"{sorted(channels)}")
        return cmds[0], "ankle_angle_rad"

    def simulate(self, time_s: np.ndarray, inputs: Mapping[str, np.ndarray],
                 row_changes: Mapping[str, float] | None = None, backlash_rad: float = 0.0,
                 temperature_rate_k_s: float = 0.0) -> dict[str, np.ndarray]:
        """Replay: the model's output channels (:data:`REPLAY_OUTPUTS`) at ``time_s``.

        ``row_changes``: packed circuit parameters to set for this run (label → value);
        ``backlash_rad``: total play of the cable on the pulley; ``temperature_rate_k_s``: oil
        temperature drift when the record has no temperature input. Raises
        :class:`ReplayError` when a state becomes non-finite (never returns NaN)."""
        cmd_name = self.check_inputs(inputs)[0]
        t = np.asarray(time_s, dtype=float)
        dt = float(np.median(np.diff(t)))
        sub = max(1, int(math.ceil(dt / self.max_step_s - 1e-9)))
        changes = dict(row_changes or {})
        load = None
        if self.load is not None:
            lv = {lab.split(".", 1)[1]: float(changes.pop(lab)) for lab in LOAD_LABELS
                  if lab in changes}
            load = dataclasses.replace(self.load, **lv) if lv else self.load
            theta = np.zeros(len(t))
            if backlash_rad > 0.0:
                raise ReplayError("backlash on a simulated load is not modelled (the play "
                                  "operator needs the imposed angle)")
        else:
            theta = np.ascontiguousarray(inputs["ankle_angle_rad"], dtype=float)
            if backlash_rad > 0.0:
                theta = play_operator(theta, backlash_rad)
        theta_dot = ankle_velocity(theta, dt)
        u = np.ascontiguousarray(inputs[cmd_name], dtype=float)
        if "fluid_temperature_k" in inputs:
            temp = np.ascontiguousarray(inputs["fluid_temperature_k"], dtype=float)
        else:
            temp = self.ambient_temperature_k + temperature_rate_k_s * (t - t[0])
        dev = CircuitDevice(self.cc, timestep_s=dt / sub)
        for label, v in self.initial_state.items():
            dev.Y[0, self.cc.index(label)] = v
        open_loop = cmd_name != "commanded_torque_nm"
        imposed = None
        if open_loop and self.kind == "valve":
            changes["controller.valve_command_on"] = 1.0
        elif open_loop:
            imposed = {"command": u[:-1]}
        for label, v in changes.items():
            dev.P[0, self.index(label)] = v
        cmd, run_sub, take = u[:-1], sub, slice(None)
        if self.hold_of(cmd_name) == "linear" and sub > 1:
            # a sampled continuous command (an analog voltage): each sub-step holds the
            # linear interpolation at its midpoint, so the replay has no half-sample lag
            n = len(t)
            k = np.arange(n, dtype=float)
            fine = np.arange((n - 1) * sub + 1) / sub
            mid = (np.arange((n - 1) * sub) + 0.5) / sub
            cmd = np.interp(mid, k, u)
            imposed = None if imposed is None else {"command": cmd}
            theta = np.interp(fine, k, theta)
            theta_dot = np.interp(fine, k, theta_dot)
            temp_run = np.interp(fine, k, temp)
            run_sub, take = 1, slice(sub - 1, None, sub)
        else:
            temp_run = temp
        try:
            log = dev.run_imposed(cmd, theta, theta_dot, inputs=imposed,
                                  temperature_k=temp_run, substeps=run_sub, load=load)
            log = {key: v[take] for key, v in log.items()}
        except FloatingPointError as exc:
            raise ReplayError(f"{self.kind} replay ({self.preset}) became non-finite: {exc}; "
                              f"parameters {dict(row_changes or {})}") from None
        out = {}
        for name in self.outputs:
            if name == "fluid_temperature_k":
                out[name] = temp.copy()
                continue
            if name == "ankle_angle_rad" and load is not None:
                out[name] = np.concatenate(([load.initial_angle_rad], log["angle_rad"]))
                continue
            sig = self._columns[name]
            # sample 0 is the initial state; a signal that is no state starts at its value
            # over the first step
            first = (self.initial_state.get(sig, float(self.cc.y0[self.cc.index(sig)]))
                     if sig in self.cc.state_names else float(log[sig][0]))
            out[name] = np.concatenate(([first], log[sig]))
            if name == "piston_position_m":
                out[name] = out[name] - self._piston_zero
        bad = [k for k, v in out.items() if not np.all(np.isfinite(v))]
        if bad:
            raise ReplayError(f"{self.kind} replay ({self.preset}) became non-finite in "
                              f"{bad}; parameters {dict(row_changes or {})}")
        return out
