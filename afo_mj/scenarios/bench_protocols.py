"""What a bench scenario may ask for: the protocols of each bench and their settings, checked.

The vocabulary the bench-scenario parser (:mod:`afo_mj.scenarios.bench_scenario`) validates
against and the experiments (:mod:`afo_mj.experiments.hafo_bench`,
:mod:`afo_mj.experiments.stiffness_bench`, :mod:`afo_mj.experiments.circuit_bench`) run:

* the HAFO bench's tests (:data:`BENCH_TESTS`);
* the stiffness bench's sweep (:class:`StiffnessSweepConfig`, built by :func:`sweep_config`,
  which checks each value and the device's torque limit);
* the circuit bench's protocols (:data:`PROTOCOLS`), its settings
  (:class:`CircuitBenchConfig`) and which protocols a given circuit can run
  (:func:`protocol_problem`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Sequence

__all__ = ["BENCH_TESTS", "BenchError", "StiffnessBenchError", "StiffnessSweepConfig",
           "stiffness_label", "sweep_config", "PROTOCOLS", "TORQUE_CONTROLLERS",
           "DIGITAL_CONTROLLERS", "CircuitBenchError", "CircuitBenchConfig", "motor_component",
           "protocol_problem", "check_protocols"]

_DEG = math.pi / 180.0

# -- the HAFO bench ----------------------------------------------------------------------------
#: the HAFO bench's tests, in the order they run
BENCH_TESTS = ("torque_velocity", "isometric_steps", "frequency_response", "position_step")


class BenchError(ValueError):
    """A bench argument outside what the test allows."""


# -- the stiffness bench -----------------------------------------------------------------------
class StiffnessBenchError(BenchError):
    """A stiffness-bench argument outside what the bench allows."""


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


# -- the circuit bench -------------------------------------------------------------------------
PROTOCOLS = ("torque_velocity", "isometric_steps", "frequency_response", "position_step",
             "stiffness", "flow_vs_duty", "tracking")
#: controller kinds that take a joint-torque command
TORQUE_CONTROLLERS = ("pump_torque", "servo_valve_torque", "digital_valve_torque")
#: controllers of a circuit metered by PWM on/off valves (``flow_vs_duty``)
DIGITAL_CONTROLLERS = ("digital_valve_torque",)


class CircuitBenchError(ValueError):
    """A protocol the circuit cannot run, or a bench setting out of range."""


@dataclasses.dataclass(frozen=True)
class CircuitBenchConfig:
    """Bench settings (SI). Defaults are a foot-sized load and the protocols' lengths."""

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


def protocol_problem(circuit, test: str) -> str | None:
    """Why ``circuit`` cannot run protocol ``test`` (None: it can)."""
    if test not in PROTOCOLS:
        return f"unknown protocol {test!r}; allowed: {', '.join(PROTOCOLS)}"
    ctrl = circuit.controller.kind
    motor = motor_component(circuit)
    valves = [c.name for c in circuit.components
              if c.kind in ("servo_valve", "onoff_valve")]
    if test in ("torque_velocity", "frequency_response"):
        if motor is None or motor.kind != "motor":
            return (f"{test} drives the motor voltage open loop; circuit {circuit.name!r} has "
                    "no motor as its actuated component")
        if valves:
            return (f"{test} drives the motor voltage open loop, which moves the joint only "
                    f"in a pump-controlled circuit; in circuit {circuit.name!r} the motor "
                    f"feeds the valve(s) {', '.join(valves)} (controller {ctrl!r}): run "
                    "isometric_steps, position_step, stiffness, tracking or flow_vs_duty")
        return None
    if test == "flow_vs_duty":
        if ctrl in DIGITAL_CONTROLLERS:
            return None
        act = motor.name if motor is not None else "nothing"
        kind = motor.kind if motor is not None else "-"
        return (f"flow_vs_duty needs a valve (PWM duty) as the actuated input: on/off valves "
                f"under controller {' | '.join(repr(c) for c in DIGITAL_CONTROLLERS)}; "
                f"circuit {circuit.name!r} is actuated by {act!r} ({kind}) through "
                f"controller {ctrl!r}")
    if ctrl not in TORQUE_CONTROLLERS:
        what = {"stiffness": "an impedance-capable (torque-commanded) controller"}.get(
            test, "a torque controller")
        return (f"{test} needs {what} (circuit.controller.kind = "
                f"{' | '.join(repr(c) for c in TORQUE_CONTROLLERS)}); circuit "
                f"{circuit.name!r} has controller {ctrl!r}, which passes the command through "
                "as the motor voltage")
    return None


def check_protocols(circuit, tests) -> None:
    for t in tests:
        why = protocol_problem(circuit, t)
        if why:
            raise CircuitBenchError(why)
