"""The bench's vocabulary: its protocols, what each needs of a device, the rigs, the settings.

One set of bench protocols runs on any device that drives a joint: a registered device
(:mod:`afo_mj.devices.registry`) or a user's ``[circuit]`` description, both seen as a
:class:`~afo_mj.circuits.device_spec.DeviceSpec`. Each protocol (:data:`PROTOCOLS`) declares
what it needs of the device (:data:`NEEDS`): a torque controller (a torque reference drives
it), an open-loop motor voltage that moves the joint (a pump-controlled circuit), a PWM valve
duty (an on/off-valve circuit). :func:`device_capabilities` reads those from the spec (never
from a preset's name) and :func:`protocol_problem` refuses a protocol the device cannot run,
naming the protocol, the device and what it lacks.

A protocol runs on one of two rigs (:data:`RIGS`), the load the joint drives:

* ``stand`` — the MuJoCo ankle test stand (:class:`afo_mj.human.test_stand.AnkleTestStand`): a
  wearer's foot with its weight, locked, free, on a spring or moved by a position drive; the
  device steps with it through the coupled protocol. Settings: ``timestep_s``,
  ``body_mass_kg``, ``height_m`` and the stiffness sweep (:class:`StiffnessSweepConfig`).
* ``load`` — a simulated load inside the compiled circuit: an inertia on a torsional spring
  and damper, or the joint motion imposed (:meth:`afo_mj.circuits.device.CircuitDevice.run_load`,
  ``run_imposed``). Settings: :class:`LoadBenchConfig`.

:data:`RIG_PROTOCOLS` says which protocols each rig has. The experiments are
:mod:`afo_mj.experiments.bench_stand` and :mod:`afo_mj.experiments.bench_load`, dispatched by
:func:`afo_mj.experiments.bench_run.run_bench`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

__all__ = ["PROTOCOLS", "RIGS", "RIG_PROTOCOLS", "NEEDS", "NEED_TEXT", "STAND_DEFAULT_PROTOCOLS",
           "LOAD_DEFAULT_PROTOCOLS", "BenchError", "ProtocolError", "StiffnessBenchError",
           "StiffnessSweepConfig", "stiffness_label", "sweep_config", "LoadBenchConfig",
           "TORQUE_CONTROLLERS", "DIGITAL_CONTROLLERS", "motor_component", "joint_actuator",
           "stroke_limits_rad", "bus_voltage_v", "bench_spec",
           "device_capabilities", "protocol_problem", "check_protocols"]

_DEG = math.pi / 180.0

#: every bench protocol, in the order a bench runs them
PROTOCOLS = ("torque_velocity", "isometric_steps", "frequency_response", "position_step",
             "stiffness", "tracking", "flow_vs_duty")
#: the loads a protocol can drive (module docstring)
RIGS = ("stand", "load")
#: the protocols each rig has
RIG_PROTOCOLS = {"stand": ("torque_velocity", "isometric_steps", "frequency_response",
                           "position_step", "stiffness"),
                 "load": PROTOCOLS}
#: the protocols a bench runs when its scenario names none: the stand's published tests,
#: the load's open-loop pair
STAND_DEFAULT_PROTOCOLS = ("torque_velocity", "isometric_steps", "frequency_response",
                           "position_step")
LOAD_DEFAULT_PROTOCOLS = ("torque_velocity", "frequency_response")
#: what each protocol needs of the device (keys of :data:`NEED_TEXT`); every protocol also
#: needs an actuator on the joint (``joint``)
NEEDS = {"torque_velocity": ("motor_voltage",), "isometric_steps": ("torque",),
         "frequency_response": ("motor_voltage",), "position_step": ("torque",),
         "stiffness": ("torque",), "tracking": ("torque",), "flow_vs_duty": ("valve_duty",)}
NEED_TEXT = {
    "joint": "an actuator on the joint",
    "torque": "a torque controller (a torque reference drives it)",
    "motor_voltage": "an open-loop motor-voltage command that moves the joint (a "
                     "pump-controlled circuit)",
    "valve_duty": "a PWM duty command of on/off metering valves (controller "
                  "digital_valve_torque with its valve_command_on switch)"}
#: controller kinds that take a joint-torque command
TORQUE_CONTROLLERS = ("pump_torque", "servo_valve_torque", "digital_valve_torque")
#: controllers of a circuit metered by PWM on/off valves (``flow_vs_duty``)
DIGITAL_CONTROLLERS = ("digital_valve_torque",)


class BenchError(ValueError):
    """A bench argument outside what the protocol allows."""


class ProtocolError(BenchError):
    """A protocol the device cannot run, or a bench setting it cannot honour."""


class StiffnessBenchError(BenchError):
    """A stiffness-sweep argument outside what the sweep allows."""


@dataclasses.dataclass(frozen=True)
class StiffnessSweepConfig:
    """The sweep (SI). Build it with :func:`sweep_config`, which checks every value."""

    stiffnesses_nm_per_rad: tuple[float, ...]
    amplitude_rad: float = 12.0 * _DEG
    frequency_hz: float = 0.25
    cycles: int = 3
    damping_nm_s_per_rad: float = 0.0
    rest_angle_rad: float = 0.0
    timestep_s: float = 5e-4
    body_mass_kg: float = 25.8
    height_m: float = 1.28

    @property
    def duration_s(self) -> float:
        return self.cycles / self.frequency_hz


def stiffness_label(stiffness_nm_per_rad: float) -> str:
    """``k<K>`` with K in N·m/deg as ``:g`` prints it (``k1``, ``k2.5``, ``k4.6``): the key of
    one stiffness in the summary (the same names as the walking sweep's ``assist_k<K>``)."""
    return f"k{round(stiffness_nm_per_rad * _DEG, 9):g}"


def _num(name: str, value, lo: float, hi: float, lo_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise StiffnessBenchError(f"{name} = {value!r} is not a number; allowed: a number in "
                                  f"{'(' if lo_open else '['}{lo:g}, {hi:g}]")
    v = float(value)
    if not math.isfinite(v) or (v <= lo if lo_open else v < lo) or v > hi:
        raise StiffnessBenchError(f"{name} = {value!r} is out of range; allowed: "
                                  f"{'(' if lo_open else '['}{lo:g}, {hi:g}]")
    return v


def sweep_config(stiffnesses_nm_per_rad: Sequence[float], amplitude_rad: float = 12.0 * _DEG,
                 frequency_hz: float = 0.25, cycles: int = 3,
                 damping_nm_s_per_rad: float = 0.0, rest_angle_rad: float = 0.0,
                 timestep_s: float = 5e-4, body_mass_kg: float = 25.8, height_m: float = 1.28,
                 max_torque_nm: float | None = None) -> StiffnessSweepConfig:
    """A checked :class:`StiffnessSweepConfig` (SI; each bad value raises
    :class:`StiffnessBenchError` naming the argument, the value and the allowed range). With
    ``max_torque_nm`` (the device's torque limit) the stiffest spring's torque at the sweep's
    end, ``K (A + |θ0|) + B ω A``, must stay within it: beyond it the device saturates and
    the sweep measures the saturation, not the spring."""
    try:
        ks = tuple(stiffnesses_nm_per_rad)
    except TypeError:
        raise StiffnessBenchError(f"stiffnesses_nm_per_rad = {stiffnesses_nm_per_rad!r}"
                                  " is not a list; allowed: a non-empty list of distinct "
                                  "positive stiffnesses") from None
    if not ks:
        raise StiffnessBenchError("stiffnesses_nm_per_rad = []; allowed: a non-empty "
                                  "list of distinct positive stiffnesses")
    ks = tuple(_num(f"stiffnesses_nm_per_rad[{i}]", k, 0.0, 20.0 / _DEG, lo_open=True)
               for i, k in enumerate(ks))
    labels = [stiffness_label(k) for k in ks]
    if len(set(labels)) != len(labels):
        raise StiffnessBenchError(f"stiffnesses_nm_per_rad = {list(stiffnesses_nm_per_rad)!r}"
                                  " repeats a stiffness; allowed: distinct values")
    amp = _num("amplitude_rad", amplitude_rad, 0.0, 30.0 * _DEG, lo_open=True)
    f = _num("frequency_hz", frequency_hz, 0.01, 5.0)
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not 2 <= cycles <= 20:
        raise StiffnessBenchError(f"cycles = {cycles!r}; allowed: an integer in 2 … 20 "
                                  "(the first cycle is dropped as start-up)")
    b = _num("damping_nm_s_per_rad", damping_nm_s_per_rad, 0.0, 5.0 / _DEG)
    rest = _num("rest_angle_rad", rest_angle_rad, -20.0 * _DEG, 20.0 * _DEG)
    dt = _num("timestep_s", timestep_s, 1e-5, 2e-3)
    if f * dt > 1.0 / 200.0:
        raise StiffnessBenchError(f"timestep_s = {timestep_s!r} with "
                                  f"frequency_hz = {frequency_hz!r} gives fewer than 200 "
                                  "steps per cycle; allowed: timestep_s <= 1 / (200 f)")
    mass = _num("body_mass_kg", body_mass_kg, 10.0, 200.0)
    height = _num("height_m", height_m, 0.8, 2.2)
    if max_torque_nm is not None:
        peak = max(ks) * (amp + abs(rest)) + b * 2 * math.pi * f * amp
        if peak > max_torque_nm:
            raise StiffnessBenchError(
                f"amplitude_rad = {amplitude_rad!r} asks the stiffest spring for "
                f"{peak:.1f} N*m at the sweep's end, above the device's max_torque_nm = "
                f"{max_torque_nm:g}; allowed: max stiffness x (amplitude + |rest angle|) + "
                f"damping x 2 pi f amplitude <= {max_torque_nm:g} N*m")
    return StiffnessSweepConfig(ks, amp, f, int(cycles), b, rest, dt, mass, height)


# -- the simulated-load rig --------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class LoadBenchConfig:
    """The simulated-load rig's settings (SI): the load and the protocols' lengths.
    Defaults are a foot-sized load; a scenario's ``[bench]`` keys are checked against
    :data:`afo_mj.scenarios.bench_scenario.LOAD_BENCH` before they get here."""

    timestep_s: float = 1e-4
    load_inertia_kg_m2: float = 0.05
    load_stiffness_nm_rad: float = 20.0
    load_damping_nm_s_rad: float = 0.2
    step_torques_nm: tuple = (10.0, 20.0, 30.0, 40.0)
    step_duration_s: float = 0.4
    freq_min_hz: float = 2.0
    freq_max_hz: float = 300.0
    freq_points: int = 20
    #: frequencies added about the gain's peak after the ``freq_points`` log-spaced ones
    #: (:func:`afo_mj.experiments.frequency_sweep.adaptive_log_sweep`): 32 in all by default
    freq_refine_points: int = 12
    voltage_amplitude_v: float = 3.0
    tv_points: int = 6
    position_step_rad: float = -0.2
    position_kp_nm_rad: float = 60.0
    position_kd_nm_s_rad: float = 2.0
    torque_limit_nm: float = 60.0
    position_duration_s: float = 1.0
    stiffnesses_nm_rad: tuple = (20.0, 50.0, 100.0)
    stiffness_amplitude_rad: float = 0.15
    stiffness_frequency_hz: float = 0.5
    tracking_peak_torque_nm: float = 30.0
    tracking_amplitude_rad: float = 0.2
    tracking_frequency_hz: float = 1.0
    tracking_cycles: int = 4
    duties: tuple = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
    flow_bias_pressure_pa: float = 0.5e6
    flow_damping_nm_s_rad: float = 2.0
    flow_inertia_kg_m2: float = 0.01
    flow_max_duration_s: float = 2.0


def motor_component(circuit):
    """The circuit's actuated component (the motor, or a PWM valve), None if it has none."""
    for c in circuit.components:
        if getattr(c, "actuated", False):
            return c
    return None


def joint_actuator(circuit):
    """The component on the joint node (the cylinders that turn pressure into joint torque),
    None if the circuit drives no joint."""
    for c in circuit.components:
        if "joint" in c.ports:
            return c
    return None


def stroke_limits_rad(circuit) -> tuple[float, float]:
    """Joint angles at the joint actuator's end stops ``(plantarflexion, dorsiflexion)``
    (pulley cylinders: half the stroke over the pulley radius; a spring-return cylinder on a
    lever: ``x = x0 − r θ`` in ``[0, stroke]``); ±0.5 rad for another actuator."""
    a = joint_actuator(circuit)
    if a is None:
        raise ProtocolError(f"circuit {circuit.name!r} drives no joint")
    p = a.params
    if a.kind == "pulley_cylinders":
        half = 0.5 * p.cylinder.stroke_m / p.pulley_radius_m
        return -half, half
    if a.kind == "spring_return_cylinder":
        r = p.moment_arm_m
        return (p.neutral_position_m - p.cylinder.stroke_m) / r, p.neutral_position_m / r
    return -0.5, 0.5


def bus_voltage_v(circuit) -> float:
    """Bus voltage at full charge: the battery's ``4.2 V × cells``, or the bench supply."""
    for c in circuit.components:
        if c.kind == "battery":
            return 4.2 * c.params.battery.cells_series
    return circuit.options.supply_voltage_v


def device_capabilities(spec) -> dict[str, str | None]:
    """What device ``spec`` (a :class:`~afo_mj.circuits.device_spec.DeviceSpec`) offers a
    bench: need (:data:`NEED_TEXT`) → None when it has it, else why not (one clause)."""
    circuit = spec.circuit
    ctrl = circuit.controller.kind
    caps: dict[str, str | None] = {}
    caps["joint"] = (None if joint_actuator(circuit) is not None
                     else f"no component of circuit {circuit.name!r} is on the joint node")
    caps["torque"] = (None if spec.torque_controlled and ctrl in TORQUE_CONTROLLERS else
                      f"its controller {ctrl!r} takes no torque reference (it passes the "
                      "command through as the motor voltage)")
    motor = motor_component(circuit)
    valves = [c.name for c in circuit.components if c.kind in ("servo_valve", "onoff_valve")]
    if spec.open_loop_channel == "motor_voltage_v":
        caps["motor_voltage"] = None
    elif motor is None or motor.kind != "motor":
        caps["motor_voltage"] = "no motor is its actuated component"
    elif valves:
        caps["motor_voltage"] = (f"its motor feeds the valve(s) {', '.join(valves)} "
                                 f"(controller {ctrl!r}): the motor voltage sets the supply, "
                                 "not the joint")
    else:
        caps["motor_voltage"] = None      # pump-controlled: the bench drives it open loop
    caps["valve_duty"] = (None if ctrl in DIGITAL_CONTROLLERS else
                          f"its controller {ctrl!r} meters no on/off valves by PWM "
                          + (f"(its valve command, {spec.open_loop_channel}, moves a "
                             "proportional valve)" if spec.open_loop_channel == "valve_command"
                             else "(it has no valve command)"))
    return caps


def bench_spec(spec):
    """``spec`` with an open-loop motor-voltage variant where the bench can drive one and the
    spec has none: a pump-controlled description under a torque controller gets the same
    components under ``open_loop`` (the motor voltage is then the command; what
    :func:`device_capabilities` offers as ``motor_voltage``)."""
    if spec.open_loop_channel is not None or device_capabilities(spec)["motor_voltage"]:
        return spec
    from afo_mj.circuits.controllers import OpenLoop
    from afo_mj.scenarios.circuit_scenario import with_controller
    return dataclasses.replace(spec, open_loop_circuit=with_controller(spec.circuit, OpenLoop()),
                               open_loop_channel="motor_voltage_v")


def protocol_problem(spec, protocol: str, rig: str = "load") -> str | None:
    """Why device ``spec`` cannot run ``protocol`` on ``rig`` (None: it can): the protocol,
    the device and what it lacks, named."""
    if protocol not in PROTOCOLS:
        return f"unknown bench protocol {protocol!r}; allowed: {', '.join(PROTOCOLS)}"
    if rig not in RIGS:
        return f"bench.rig = {rig!r}; allowed: {', '.join(RIGS)}"
    if protocol not in RIG_PROTOCOLS[rig]:
        other = [r for r in RIGS if protocol in RIG_PROTOCOLS[r]]
        return (f"bench protocol {protocol!r} has no {rig} rig; allowed on the {rig} rig: "
                f"{', '.join(RIG_PROTOCOLS[rig])} ({protocol} runs with bench.rig = "
                + " | ".join(repr(r) for r in other) + ")")
    caps = device_capabilities(spec)
    for need in ("joint",) + NEEDS[protocol]:
        why = caps[need]
        if why:
            can = [p for p in RIG_PROTOCOLS[rig]
                   if all(caps[n] is None for n in ("joint",) + NEEDS[p])]
            return (f"bench protocol {protocol!r} cannot run on device {spec.name!r}: it needs "
                    f"{NEED_TEXT[need]}; device {spec.name!r} lacks it: {why}. Allowed for "
                    f"this device on the {rig} rig: {', '.join(can) or 'none'}")
    return None


def check_protocols(spec, protocols: Sequence[str], rig: str = "load") -> None:
    """Raise :class:`ProtocolError` for the first protocol ``spec`` cannot run on ``rig``."""
    for p in protocols:
        why = protocol_problem(spec, p, rig)
        if why:
            raise ProtocolError(why)
