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
from afo_mj.circuits.device_spec import TORQUE_CHANNEL, DeviceSpec, circuit_roles
from afo_mj.devices.registry import device_spec
from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.transmission import play_operator

__all__ = ["BenchReplay", "PreparedRun", "HOLDS", "DEFAULT_MAX_STEP_S", "HELD_CHANNELS",
           "CIRCUIT_OUTPUTS", "ReplayError", "circuit_geometry", "circuit_roles"]


class ReplayError(RuntimeError):
    """The model could not be replayed (a state became non-finite, or inputs are missing)."""


#: the replay's maximum sub-step unless set (:attr:`BenchReplay.max_step_s`), s; a calibration
#: of a described rig chooses its own from here (:mod:`afo_mj.calibration.numerical_check`)
DEFAULT_MAX_STEP_S = 5e-4
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


def ankle_velocity(theta_rad: np.ndarray, dt_s: float) -> np.ndarray:
    """Savitzky–Golay (1964) derivative of the imposed angle: a cubic fitted over 21 samples
    (fewer for short records), evaluated at the window centre."""
    n = len(theta_rad)
    win = min(21, n - (1 - n % 2))
    if win < 5:
        return np.gradient(theta_rad, dt_s)
    return savgol_filter(theta_rad, win, 3, deriv=1, delta=dt_s, mode="interp")


@dataclasses.dataclass(frozen=True)
class PreparedRun:
    """A replay's inputs as the circuit sees them (:meth:`BenchReplay.prepare`)."""

    command_channel: str
    hold: str                   #: how the command is held (:data:`HOLDS`)
    time_s: np.ndarray
    dt_s: float                 #: the record's sample period (median interval), s
    substeps: int               #: equal sub-steps per sample interval
    command: np.ndarray         #: the command per sample
    theta: np.ndarray           #: imposed angle per sample, rad (zeros with a load)
    theta_dot: np.ndarray       #: its velocity, rad/s
    temperature_k: np.ndarray   #: oil temperature per sample, K
    load: JointLoad | None      #: the simulated load with this run's parameters
    changes: dict               #: packed parameters to set (label → value)
    open_loop: bool             #: the command is the open-loop actuation (not a torque)
    imposed: bool               #: the command is written to the circuit's ``command`` input


class BenchReplay:
    """A device ready to replay records: a registered device by name (``preset``, with its
    ``overrides``: :func:`afo_mj.devices.registry.device_spec`), a described ``circuit`` (a
    user's rig, optionally with a simulated ``load``), or a ``spec``
    (:class:`~afo_mj.circuits.device_spec.DeviceSpec`). Everything the replay needs to know
    about the device comes from its spec: the command channels it accepts (the open-loop
    command, and a torque reference for a torque-controlled device), how an open-loop command
    takes over (a switch parameter, or imposed on the circuit's ``command`` input), the state
    it starts from, its output channels, and the roles of its parts.

    The generated circuit's packed parameter row is :attr:`base_row`, its entries named by
    :attr:`param_labels` (``component.key``,
    :attr:`afo_mj.circuits.codegen.CompiledCircuit.param_labels`); :meth:`simulate` takes
    per-run changes to it by label, which is how the calibration sets fitted parameters and
    switches effects on without rebuilding or recompiling the device.
    """

    def __init__(self, preset: str | None = None,
                 overrides: Mapping[str, object] | None = None, *,
                 circuit: Circuit | None = None, load: JointLoad | None = None,
                 signals: Mapping[str, str] | None = None,
                 hold: Mapping[str, str] | None = None, spec: DeviceSpec | None = None):
        given = [k for k, v in (("preset", preset), ("circuit", circuit), ("spec", spec))
                 if v is not None]
        if len(given) != 1:
            raise ParameterError(f"BenchReplay: {given or 'nothing'} given; allowed: one of "
                                 "preset, circuit, spec")
        if circuit is not None:
            spec = DeviceSpec.from_circuit(circuit)
        elif preset is not None:
            spec = device_spec(preset, overrides, key="source.preset")
        if load is not None and spec.params is not None:
            raise ParameterError("a simulated load is available for a described circuit "
                                 "([circuit] with [load]); the presets replay the imposed angle")
        #: the device (:class:`~afo_mj.circuits.device_spec.DeviceSpec`)
        self.spec = spec
        self.load = load
        self._signal_overrides = dict(signals or {})
        #: a description given directly (a user's rig): its parameters are declared in its
        #: own names and it holds an undeclared command linearly
        self.described = spec.params is None
        #: how an undeclared command is held over a sample interval: ``"zero_order"`` (a
        #: digital command, the presets' records) or ``"linear"`` (a sampled continuous
        #: signal, a described rig's default: interpolated between the samples)
        self.default_hold = "linear" if self.described else "zero_order"
        #: declared hold per command channel (:meth:`set_hold`); others use default_hold
        self.hold: dict[str, str] = {}
        self.set_hold(hold or {})
        self.preset = spec.name
        self.circuit = spec.circuit
        #: the preset's parameter set, or a description's cylinder geometry (what the record
        #: checks compare the angle with; :func:`circuit_geometry`)
        self.params = spec.params if not self.described else circuit_geometry(spec.circuit)
        self.cc = build(spec.circuit)
        self.initial_state = dict(spec.initial_state)
        self.base_row = self.cc.P.copy()
        #: role → component name (a described circuit answers to the presets' part names)
        self.roles = dict(spec.roles)
        self.param_labels = tuple(self.cc.param_labels) + (LOAD_LABELS if load else ())
        self._label_index = {lab: i for i, lab in enumerate(self.param_labels)}
        self.commands = spec.commands
        self.inputs = self.commands[:1] + (() if load else ("ankle_angle_rad",))
        self.ambient_temperature_k = float(spec.circuit.thermal.ambient_temperature_k)
        # 0.5 ms, not the stand's 1 ms: a 1 ms backward-Euler step through a fast valve event
        # (the flushing valve shuttling while the pump reverses the lines) lands up to 160 kPa
        # away from the same interval taken in sub-steps, and whether the stepper falls back to
        # sub-steps flips with a 0.025 % change of a parameter: the replay jumps as a function
        # of the fitted parameters and the calibration's fit stalls beside the truth (mismatch
        # record: pressure_b residual 1.26× the noise at 1 ms, 1.016× at 0.5 ms, 1.009× at
        # 0.25 ms; the old kernel's 1.01× at 1 ms)
        self.max_step_s = DEFAULT_MAX_STEP_S
        if spec.outputs is not None:
            self._columns = {name: self._signal(name) for name in spec.outputs
                             if name != "fluid_temperature_k"}
            self.outputs = tuple(spec.outputs)
        else:
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
        geo = circuit_geometry(spec.circuit)
        if geo is not None:
            self._piston_zero = 0.5 * float(geo.cylinder.stroke_m)

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
        roles = self.roles
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
        roles = self.roles
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

    def check_inputs(self, channels) -> tuple[str, ...]:
        """The record's command channel and, unless the load is simulated, the imposed angle:
        ``(command, "ankle_angle_rad")`` (the first of the device's command channels the
        record has: the open-loop command, else the torque reference)."""
        cmds = [c for c in self.commands if c in channels]
        need_angle = self.load is None
        if not cmds or (need_angle and "ankle_angle_rad" not in channels):
            ctrl = self.circuit.controller.kind
            raise ReplayError(
                f"the {self.preset!r} replay needs one of {list(self.commands)} (its {ctrl} "
                f"controller)" + (" and ankle_angle_rad (the joint angle is imposed)"
                                  if need_angle else "")
                + f"; the record has {sorted(channels)}")
        return (cmds[0], "ankle_angle_rad") if need_angle else (cmds[0],)

    def prepare(self, time_s: np.ndarray, inputs: Mapping[str, np.ndarray],
                row_changes: Mapping[str, float] | None = None, backlash_rad: float = 0.0,
                temperature_rate_k_s: float = 0.0) -> "PreparedRun":
        """What a replay of ``inputs`` drives the circuit with (:class:`PreparedRun`): the
        command channel and its samples, the imposed angle (after the backlash's play
        operator) and its Savitzky–Golay velocity, or the simulated load with the run's load
        parameters, the oil temperature per sample, the packed parameters to set (the
        open-loop switch included) and the sub-steps per sample. :meth:`simulate` integrates
        it with the circuit's stepper; :mod:`afo_mj.experiments.replay_reference` with
        Radau."""
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
        open_loop = cmd_name != TORQUE_CHANNEL
        imposed = False
        if open_loop and self.spec.open_loop_switch is not None:
            changes[self.spec.open_loop_switch] = 1.0
        elif open_loop:
            imposed = True
        return PreparedRun(cmd_name, self.hold_of(cmd_name), t, dt, sub, u, theta, theta_dot,
                           temp, load, changes, open_loop, imposed)

    def simulate(self, time_s: np.ndarray, inputs: Mapping[str, np.ndarray],
                 row_changes: Mapping[str, float] | None = None, backlash_rad: float = 0.0,
                 temperature_rate_k_s: float = 0.0) -> dict[str, np.ndarray]:
        """Replay: the model's output channels (:data:`REPLAY_OUTPUTS`) at ``time_s``.

        ``row_changes``: packed circuit parameters to set for this run (label → value);
        ``backlash_rad``: total play of the cable on the pulley; ``temperature_rate_k_s``: oil
        temperature drift when the record has no temperature input. Raises
        :class:`ReplayError` when a state becomes non-finite (never returns NaN)."""
        run = self.prepare(time_s, inputs, row_changes, backlash_rad, temperature_rate_k_s)
        t, sub, load, theta, theta_dot, u, temp = (run.time_s, run.substeps, run.load,
                                                   run.theta, run.theta_dot, run.command,
                                                   run.temperature_k)
        changes = run.changes
        cmd_name = run.command_channel
        dev = CircuitDevice(self.cc, timestep_s=run.dt_s / sub)
        for label, v in self.initial_state.items():
            dev.Y[0, self.cc.index(label)] = v
        imposed = {"command": u[:-1]} if run.imposed else None
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
            raise ReplayError(f"replay of {self.preset!r} became non-finite: {exc}; "
                              f"parameters {dict(row_changes or {})}") from None
        return self.outputs_of(log, temp, load, row_changes)

    def outputs_of(self, log: Mapping[str, np.ndarray], temperature_k: np.ndarray,
                   load: JointLoad | None, row_changes=None,
                   channels=None) -> dict[str, np.ndarray]:
        """The output channels (``channels``, default :attr:`outputs`) from a run's log of
        signals at the end of each sample interval (states, probes, ``torque_nm``,
        ``angle_rad``, ...): sample 0 is the initial state (a signal that is no state starts
        at its value over the first step); the piston position is taken from mid-stroke.
        Raises :class:`ReplayError` on a non-finite value."""
        out = {}
        for name in (self.outputs if channels is None else channels):
            if name == "fluid_temperature_k":
                out[name] = np.array(temperature_k, dtype=float)
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
            raise ReplayError(f"replay of {self.preset!r} became non-finite in "
                              f"{bad}; parameters {dict(row_changes or {})}")
        return out

    def signal_of(self, channel: str) -> str | None:
        """The circuit signal (state, probe or log column) behind output ``channel``; None
        for the oil temperature and a simulated load's angle."""
        return self._columns.get(channel)
