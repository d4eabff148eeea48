"""Synthetic bench records with known, undeclared effects: the test data of the calibration.

:func:`generate_record` runs a bench protocol (:func:`bench_protocol`) through the lean model
(:func:`afo_mj.calibration.effect_library.lean_setting`) with

* chosen effects of the library switched on at chosen values (what the calibration must find),
* optional mismatch of the declared parameters (factors on the preset's values: what the fit
  must absorb without inventing an effect),
* optional effects outside the library (``torque_sensor_resonance_hz``: the torque channel seen
  through a lightly damped second-order mount, a resonance no library effect can produce),

then adds white Gaussian sensor noise (σ per channel, :data:`DEFAULT_NOISE`) and writes the
measured-data format (:func:`afo_mj.calibration.measured_data.write_measured`), with the truth in
the sidecar's ``source.description``. ``afo-mj make-bench-record`` is the command.

Protocols (``period_s`` = 1 s cycles, so the calibration holds out whole cycles):

* HAFO (open loop, motor voltage): the ankle is imposed on ``0.12 sin(2πt) + 0.03 sin(6πt)`` rad;
  the voltage is a flow feedforward (the pump follows the ankle, ``v = K d⁻¹ A_e r θ̇``) plus
  steps of ±1…4 V that hold for 0.2…0.6 s (each spread over 5 ms) and a 2.3 Hz sine,
  faded in over the first 0.5 s: pressures 0.5…12 MPa, the
  motor current up to its limit, the pistons through velocity reversals under load.
* Valve (open loop, spool command): the ankle on ``0.04 sin(2πt)`` rad; the command is the flow
  feedforward of the valve controller plus steps of ±0.03…0.15 held 0.1…0.4 s (the spool never
  rests near centre while the ankle moves, which would lock the chambers).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import numpy as np
from scipy.signal import bilinear, lfilter

from afo_mj.calibration.effect_library import (
    declared_parameters, effect_by_name, effects_for, lean_setting)
from afo_mj.calibration.calibrate import declared_labels, model_outputs
from afo_mj.calibration.measured_data import write_measured
from afo_mj.hydraulics.params import ParameterError
from afo_mj.experiments.bench_replay import BenchReplay

__all__ = ["bench_protocol", "generate_record", "DEFAULT_NOISE", "RECORD_OUTPUTS",
           "DEFAULT_PRESET"]

#: sensor noise σ (SI) of a good bench: 0.1 % FS pressure transducers (20 MPa), a 200 N·m
#: torque cell at 0.1 %, a current sense amplifier, a Hall speed estimate
DEFAULT_NOISE = {"pressure_a_pa": 2.0e4, "pressure_b_pa": 2.0e4, "chamber_a_pa": 2.0e4,
                 "chamber_b_pa": 2.0e4, "supply_pressure_pa": 2.0e4,
                 "pump_pressure_pa": 2.0e4, "ankle_torque_nm": 0.2, "motor_current_a": 0.03,
                 "motor_speed_rad_s": 2.0, "valve_position": 0.002,
                 "fluid_temperature_k": 0.05}
#: the outputs each kind of synthetic bench record carries
RECORD_OUTPUTS = {"hafo": ("pressure_a_pa", "pressure_b_pa", "ankle_torque_nm",
                           "motor_current_a", "motor_speed_rad_s"),
                  "valve": ("chamber_a_pa", "chamber_b_pa", "ankle_torque_nm")}
DEFAULT_PRESET = {"hafo": "hafo", "valve": "valve"}
#: encoder noise on the imposed angle (rad)
ANGLE_NOISE_RAD = 2e-5


def _steps(t, rng, lo, hi, hold_lo, hold_hi):
    """Piecewise-constant levels of random sign and magnitude in [lo, hi], held for random
    durations in [hold_lo, hold_hi] s."""
    out = np.zeros_like(t)
    k = 0
    while k < len(t):
        hold = rng.uniform(hold_lo, hold_hi)
        n = max(1, int(hold / (t[1] - t[0])))
        out[k:k + n] = rng.choice((-1.0, 1.0)) * rng.uniform(lo, hi)
        k += n
    return out


def _slew(x, fs_hz, rise_s=0.005):
    """A command through a rate limit: each step of ``x`` spread over ``rise_s`` (a driver's
    command filter; a record's ideal steps would be the one thing no real bench produces)."""
    n = max(1, int(round(rise_s * fs_hz)))
    kernel = np.ones(n) / n
    return np.convolve(np.concatenate([np.full(n - 1, x[0]), x]), kernel, mode="valid")


def _fade_in(t, t_ramp=0.5):
    s = np.clip(t / t_ramp, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def bench_protocol(replay: BenchReplay, duration_s: float = 20.0, fs_hz: float = 1000.0,
                   seed: int = 0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``(time_s, inputs)`` of the open-loop bench protocol of the module docstring."""
    if not 2.0 <= duration_s <= 600.0:
        raise ParameterError(f"duration_s = {duration_s!r}; allowed: 2 … 600 s")
    if not 200.0 <= fs_hz <= 10000.0:
        raise ParameterError(f"fs_hz = {fs_hz!r}; allowed: 200 … 10000 Hz")
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration_s * fs_hz))) / fs_hz
    p = replay.params
    ktp = p.torque_per_pressure_m3      # joint torque per pascal of p_a − p_b (n A r)
    if replay.kind == "hafo":
        env = _fade_in(t)
        theta = env * (0.12 * np.sin(2 * np.pi * t) + 0.03 * np.sin(6 * np.pi * t))
        thd = np.gradient(theta, t)
        w_ff = -ktp * thd / (p.pump.displacement_m3_rev / (2.0 * math.pi))
        volt = (p.motor.torque_constant_nm_a * w_ff
                + env * _slew(_steps(t, rng, 1.0, 4.0, 0.2, 0.6), fs_hz)
                + env * np.sin(2 * np.pi * 2.3 * t))
        return t, {"motor_voltage_v": volt, "ankle_angle_rad": theta}
    env = _fade_in(t)
    theta = env * 0.04 * np.sin(2 * np.pi * t)
    thd = np.gradient(theta, t)
    dpe = 0.5 * (p.initial_supply_pressure_pa - p.reservoir_pressure_pa)
    u_ff = -ktp * thd / (p.servo_valve.discharge_coefficient * p.servo_full_area_m2
                         * math.sqrt(2 * dpe / p.fluid.density_kg_m3))
    u = np.clip(u_ff + env * _slew(_steps(t, rng, 0.03, 0.15, 0.1, 0.4), fs_hz), -1.0, 1.0)
    return t, {"valve_command": u, "ankle_angle_rad": theta}


def _resonance(t, y, f_hz, zeta):
    """``y`` through ``ω²/(s² + 2ζωs + ω²)`` (unit DC gain), discretised by the bilinear
    (Tustin) transform at the record's rate."""
    w = 2 * np.pi * f_hz
    b, a = bilinear([w * w], [1.0, 2 * zeta * w, w * w], fs=1.0 / (t[1] - t[0]))
    # start at rest on the first value (no artificial step at t = 0)
    y0 = y[0]
    return lfilter(b, a, y - y0) + y0


def generate_record(path, kind: str = "hafo", effects: Mapping[str, Mapping[str, float]] = {},
                    mismatch: Mapping[str, float] = {}, noise_scale: float = 1.0,
                    duration_s: float = 20.0, fs_hz: float = 1000.0, seed: int = 0,
                    preset: str | None = None, torque_sensor_resonance_hz: float = 0.0,
                    resonance_damping: float = 0.05, outputs=None, fmt: str | None = None):
    """Write a synthetic bench record to ``path`` (CSV or Parquet, plus its TOML sidecar) and
    return it as :class:`~afo_mj.calibration.measured_data.MeasuredData`.

    ``effects``: effect name → {parameter name → SI value} (names of
    :mod:`afo_mj.calibration.effect_library`; parameters left out take their typical value);
    ``mismatch``: declared parameter name → factor on the preset's value."""
    preset = preset or DEFAULT_PRESET.get(kind)
    replay = BenchReplay(preset)
    if replay.kind != kind:
        raise ParameterError(f"preset = {preset!r} is a {replay.kind} preset; kind = {kind!r}")
    outputs = tuple(outputs or RECORD_OUTPUTS[kind])
    t, inputs = bench_protocol(replay, duration_s, fs_hz, seed)
    available = set(replay.param_labels)
    setting = lean_setting(kind, available)
    declared = {d.name: d for d in declared_parameters(kind)}
    for name, f in mismatch.items():
        if name not in declared:
            raise ParameterError(f"mismatch key {name!r}; allowed: {', '.join(declared)}")
        d = declared[name]
        if not d.lo_factor <= f <= d.hi_factor:
            raise ParameterError(f"mismatch.{name} = {f!r}; allowed: {d.lo_factor} … "
                                 f"{d.hi_factor}")
        for lab in declared_labels(replay, d):
            setting.row[lab] = replay.value(lab) * float(f)
    library = effects_for(kind, outputs, {c: 1e9 for c in outputs}, available)
    context = {}
    truth = []
    for name, values in effects.items():
        e = effect_by_name(library, name)
        names = [p.name for p in e.parameters]
        bad = [k for k in values if k not in names]
        if bad:
            raise ParameterError(f"effects.{name}: unknown parameter(s) {bad}; allowed: "
                                 f"{names}")
        vals = []
        for p in e.parameters:
            v = float(values.get(p.name, p.typical))
            if not p.lo <= v <= p.hi:
                raise ParameterError(f"effects.{name}.{p.name} = {v!r}; allowed: {p.lo} … "
                                     f"{p.hi} {p.unit}")
            vals.append(v)
        e.apply(setting, vals, context)
        truth.append(f"{name}(" + ", ".join(f"{n}={v:g}" for n, v in zip(names, vals)) + ")")
    out = model_outputs(replay, t, inputs, setting, outputs)
    if torque_sensor_resonance_hz > 0.0 and "ankle_torque_nm" in out:
        out["ankle_torque_nm"] = _resonance(t, out["ankle_torque_nm"],
                                            torque_sensor_resonance_hz, resonance_damping)
        truth.append(f"torque_sensor_resonance(f={torque_sensor_resonance_hz:g} Hz, "
                     f"zeta={resonance_damping:g}) [outside the library]")
    if mismatch:
        truth.append("mismatch(" + ", ".join(f"{k}×{v:g}" for k, v in mismatch.items()) + ")")
    rng = np.random.default_rng(seed + 1000)
    noise = {c: DEFAULT_NOISE[c] * noise_scale for c in outputs}
    table = {"time_s": t}
    for c, v in inputs.items():
        table[c] = v + (rng.normal(0.0, ANGLE_NOISE_RAD, len(t)) * noise_scale
                        if c == "ankle_angle_rad" else 0.0)
    for c in outputs:
        table[c] = out[c] + rng.normal(0.0, noise[c], len(t)) if noise[c] > 0 else out[c]
    desc = ("synthetic bench record (afo_mj.calibration.synthetic_records), truth: "
            + ("; ".join(truth) if truth else "lean model, no effect") + f"; seed {seed}")
    return write_measured(
        Path(path), table, inputs=list(inputs), outputs=list(outputs),
        source={"preset": preset, "description": desc, "origin": "afo_mj synthetic"},
        noise={c: s for c, s in noise.items() if s > 0},
        segments={"period_s": 1.0, "phase_s": 0.0}, fmt=fmt)
