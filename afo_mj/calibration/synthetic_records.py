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
  steps of ±1…4 V that hold for 0.2…0.6 s and a 2.3 Hz sine,
  faded in over the first 0.5 s: pressures 0.5…12 MPa, the
  motor current up to its limit, the pistons through velocity reversals under load.
* Valve (open loop, spool command): the ankle on ``0.04 sin(2πt)`` rad; the command is the flow
  feedforward of the valve controller plus steps of ±0.03…0.15 held 0.1…0.4 s (the spool never
  rests near centre while the ankle moves, which would lock the chambers).

The command's hold (issue 41) is what the record really has and its sidecar declares it
(``[hold]``): by default a digital command held zero-order between updates (sharp steps), or,
with ``command_hold = "linear"``, a band-limited continuous command (each step a 5 ms
raised-cosine rise) simulated at a finer internal step than the record's sampling.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Mapping

import numpy as np
from scipy.signal import bilinear, lfilter

from afo_mj.calibration.effect_library import (
    declared_parameters, effect_by_name, effects_for, lean_setting)
from afo_mj.calibration.calibration_model import declared_labels, model_outputs
from afo_mj.calibration.measured_data import write_measured
from afo_mj.devices.registry import device_spec
from afo_mj.hydraulics.params import ParameterError
from afo_mj.experiments.bench_replay import BenchReplay

__all__ = ["bench_protocol", "generate_record", "DEFAULT_NOISE", "RECORD_OUTPUTS",
           "DEFAULT_PRESET", "COMMAND_HOLDS"]

#: sensor noise σ (SI) of a good bench: 0.1 % FS pressure transducers (20 MPa), a 200 N·m
#: torque cell at 0.1 %, a current sense amplifier, a Hall speed estimate
DEFAULT_NOISE = {"pressure_a_pa": 2.0e4, "pressure_b_pa": 2.0e4, "chamber_a_pa": 2.0e4,
                 "chamber_b_pa": 2.0e4, "supply_pressure_pa": 2.0e4,
                 "pump_pressure_pa": 2.0e4, "ankle_torque_nm": 0.2, "motor_current_a": 0.03,
                 "motor_speed_rad_s": 2.0, "valve_position": 0.002,
                 "fluid_temperature_k": 0.05}
#: the outputs a synthetic bench record carries, by the device's open-loop command (a
#: pump-driven bench logs its line pressures and motor, a valve bench its chambers)
RECORD_OUTPUTS = {"motor_voltage_v": ("pressure_a_pa", "pressure_b_pa", "ankle_torque_nm",
                                      "motor_current_a", "motor_speed_rad_s"),
                  "valve_command": ("chamber_a_pa", "chamber_b_pa", "ankle_torque_nm")}
#: ``kind`` (``make-bench-record --kind``) → the preset it records by default
DEFAULT_PRESET = {"hafo": "hafo", "valve": "valve"}
#: encoder noise on the imposed angle (rad)
ANGLE_NOISE_RAD = 2e-5


#: how a synthetic record's command is produced between its samples (its sidecar's ``[hold]``)
COMMAND_HOLDS = ("zero_order", "linear")
#: internal steps per record sample of a continuous (``"linear"``) command's simulation
LINEAR_OVERSAMPLE = 4
#: rise time of a continuous command's steps (a raised-cosine transition, a driver's command
#: filter)
LINEAR_RISE_S = 0.005


def _step_schedule(n, fs_hz, rng, lo, hi, hold_lo, hold_hi):
    """``(switch_times_s, levels)``: levels of random sign and magnitude in [lo, hi], each
    held for a random duration in [hold_lo, hold_hi] s rounded down to whole samples (the
    draws of the original sample-by-sample generator, so records keep their seeds)."""
    times, levels, k = [], [], 0
    while k < n:
        hold = rng.uniform(hold_lo, hold_hi)
        m = max(1, int(hold / (1.0 / fs_hz)))
        times.append(k / fs_hz)
        levels.append(rng.choice((-1.0, 1.0)) * rng.uniform(lo, hi))
        k += m
    return np.asarray(times), np.asarray(levels)


def _steps_at(t, schedule, rise_s=0.0):
    """The step schedule at times ``t``: sharp steps (``rise_s`` = 0, a command held between
    its updates) or each step a raised-cosine transition ``½(1 − cos(π τ/rise_s))`` over
    ``rise_s`` after its switch time (C¹, band-limited: a continuous command)."""
    times, levels = schedule
    k = np.searchsorted(times, t + 1e-12, side="right") - 1
    out = levels[np.clip(k, 0, None)]
    if rise_s <= 0.0:
        return out
    d = np.diff(levels)
    for ts, dl in zip(times[1:], d):
        sel = (t >= ts) & (t < ts + rise_s)
        tau = (t[sel] - ts) / rise_s
        out[sel] -= dl * 0.5 * (1.0 + np.cos(np.pi * tau))
    return out


def _fade_in(t, t_ramp=0.5):
    s = np.clip(t / t_ramp, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _fade_in_rate(t, t_ramp=0.5):
    s = np.clip(t / t_ramp, 0.0, 1.0)
    return np.where((t > 0.0) & (t < t_ramp), 6.0 * s * (1.0 - s) / t_ramp, 0.0)


def _check_hold_options(command_hold, command_update_s, fs_hz) -> int:
    """Validate the command's hold options; return the DAC update period in samples."""
    if command_hold not in COMMAND_HOLDS:
        raise ParameterError(f"command_hold = {command_hold!r}; allowed: "
                             f"{', '.join(repr(h) for h in COMMAND_HOLDS)}")
    if command_update_s is None:
        return 1
    m = float(command_update_s) * fs_hz
    if command_hold != "zero_order":
        raise ParameterError(f"command_update_s = {command_update_s!r} with command_hold = "
                             f"{command_hold!r}; allowed: only with \"zero_order\"")
    if not (1.0 - 1e-9 <= m <= 100.0 and abs(m - round(m)) < 1e-6):
        raise ParameterError(f"command_update_s = {command_update_s!r}; allowed: a whole "
                             f"number (1 … 100) of sample intervals (1/fs = {1 / fs_hz:g} s)")
    return int(round(m))


class _Protocol:
    """The bench protocol as functions of time (so a command can be evaluated between the
    record's samples)."""

    def __init__(self, replay: BenchReplay, n: int, fs_hz: float, seed: int):
        rng = np.random.default_rng(seed)
        self.channel, self.p = replay.commands[0], replay.params
        if self.channel == "motor_voltage_v":
            self.schedule = _step_schedule(n, fs_hz, rng, 1.0, 4.0, 0.2, 0.6)
        else:
            self.schedule = _step_schedule(n, fs_hz, rng, 0.03, 0.15, 0.1, 0.4)

    def angle(self, t):
        """``(θ, θ̇)`` of the imposed ankle (analytic derivative)."""
        env, denv = _fade_in(t), _fade_in_rate(t)
        w = 2 * np.pi
        if self.channel == "motor_voltage_v":
            s = 0.12 * np.sin(w * t) + 0.03 * np.sin(3 * w * t)
            ds = 0.12 * w * np.cos(w * t) + 0.09 * w * np.cos(3 * w * t)
        else:
            s, ds = 0.04 * np.sin(w * t), 0.04 * w * np.cos(w * t)
        return env * s, denv * s + env * ds

    def command(self, t, rise_s=0.0):
        """The command at times ``t`` (motor voltage or valve command)."""
        p = self.p
        ktp = p.torque_per_pressure_m3      # joint torque per pascal of p_a − p_b (n A r)
        env = _fade_in(t)
        thd = self.angle(t)[1]
        steps = env * _steps_at(t, self.schedule, rise_s)
        if self.channel == "motor_voltage_v":
            w_ff = -ktp * thd / (p.pump.displacement_m3_rev / (2.0 * math.pi))
            return (p.motor.torque_constant_nm_a * w_ff + steps
                    + env * np.sin(2 * np.pi * 2.3 * t))
        dpe = 0.5 * (p.initial_supply_pressure_pa - p.reservoir_pressure_pa)
        u_ff = -ktp * thd / (p.servo_valve.discharge_coefficient * p.servo_full_area_m2
                             * math.sqrt(2 * dpe / p.fluid.density_kg_m3))
        return np.clip(u_ff + steps, -1.0, 1.0)

    @property
    def command_name(self) -> str:
        return self.channel


def bench_protocol(replay: BenchReplay, duration_s: float = 20.0, fs_hz: float = 1000.0,
                   seed: int = 0, command_hold: str = "zero_order",
                   command_update_s: float | None = None
                   ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``(time_s, inputs)`` of the open-loop bench protocol of the module docstring, sampled
    at ``fs_hz``: the command as a DAC holds it (``command_hold = "zero_order"``: sharp steps,
    updated every ``command_update_s``, default every sample) or a band-limited continuous
    command sampled (``"linear"``: steps with a 5 ms raised-cosine rise)."""
    if not 2.0 <= duration_s <= 600.0:
        raise ParameterError(f"duration_s = {duration_s!r}; allowed: 2 … 600 s")
    if not 200.0 <= fs_hz <= 10000.0:
        raise ParameterError(f"fs_hz = {fs_hz!r}; allowed: 200 … 10000 Hz")
    every = _check_hold_options(command_hold, command_update_s, fs_hz)
    n = int(round(duration_s * fs_hz))
    t = np.arange(n) / fs_hz
    proto = _Protocol(replay, n, fs_hz, seed)
    theta = proto.angle(t)[0]
    if command_hold == "linear":
        u = proto.command(t, LINEAR_RISE_S)
    else:
        u = proto.command(t[(np.arange(n) // every) * every])
    return t, {proto.command_name: u, "ankle_angle_rad": theta}


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
                    resonance_damping: float = 0.05, outputs=None, fmt: str | None = None,
                    command_hold: str = "zero_order", command_update_s: float | None = None):
    """Write a synthetic bench record to ``path`` (CSV or Parquet, plus its TOML sidecar) and
    return it as :class:`~afo_mj.calibration.measured_data.MeasuredData`.

    ``effects``: effect name → {parameter name → SI value} (names of
    :mod:`afo_mj.calibration.effect_library`; parameters left out take their typical value);
    ``mismatch``: declared parameter name → factor on the preset's value.

    ``command_hold``: how the command really is produced between the record's samples, written
    to the sidecar's ``[hold]`` (so the calibration replays it as produced):

    * ``"zero_order"`` (default): a digital command (a DAC or PWM duty) with sharp steps, held
      between updates every ``command_update_s`` (default: every sample; a whole number of
      sample intervals). The model integrates it at the replay's sub-steps with the command
      held, exactly what the record's samples show;
    * ``"linear"``: a band-limited continuous command (steps with a 5 ms raised-cosine rise),
      simulated at :data:`LINEAR_OVERSAMPLE` internal steps per record sample (each holding the
      command at its midpoint, second order in the step) and sampled at ``fs_hz``."""
    if kind not in DEFAULT_PRESET:
        raise ParameterError(f"kind = {kind!r}; allowed: {', '.join(DEFAULT_PRESET)}")
    want = device_spec(DEFAULT_PRESET[kind]).open_loop_channel
    preset = preset or DEFAULT_PRESET[kind]
    replay = BenchReplay(preset)
    if replay.described or replay.commands[0] != want:
        raise ParameterError(f"preset = {preset!r} (command {replay.commands[0]}) for kind = "
                             f"{kind!r}; allowed: a preset whose open-loop command is {want} "
                             "(a preset's lean model is what the synthetic record varies)")
    command = replay.commands[0]
    outputs = tuple(outputs or RECORD_OUTPUTS[command])
    t, inputs = bench_protocol(replay, duration_s, fs_hz, seed, command_hold, command_update_s)
    available = set(replay.param_labels)
    setting = lean_setting(available)
    declared = {d.name: d for d in declared_parameters(command)}
    for name, f in mismatch.items():
        if name not in declared:
            raise ParameterError(f"mismatch key {name!r}; allowed: {', '.join(declared)}")
        d = declared[name]
        if not d.lo_factor <= f <= d.hi_factor:
            raise ParameterError(f"mismatch.{name} = {f!r}; allowed: {d.lo_factor} … "
                                 f"{d.hi_factor}")
        for lab in declared_labels(replay, d):
            setting.row[lab] = replay.value(lab) * float(f)
    library = effects_for(outputs, {c: 1e9 for c in outputs}, available)
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
    if command_hold == "linear":
        # the continuous command between the samples: simulated on a finer grid, each internal
        # step holding the command at its midpoint, then sampled at the record's rate
        os_ = LINEAR_OVERSAMPLE
        t_f = np.arange((len(t) - 1) * os_ + 1) / (fs_hz * os_)
        proto = _Protocol(replay, len(t), fs_hz, seed)
        fine = {proto.command_name: proto.command(t_f + 0.5 / (fs_hz * os_), LINEAR_RISE_S),
                "ankle_angle_rad": proto.angle(t_f)[0]}
        out = {c: v[::os_] for c, v in model_outputs(replay, t_f, fine, setting,
                                                      outputs).items()}
    else:
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
            + ("; ".join(truth) if truth else "lean model, no effect") + f"; seed {seed}; "
            + (f"command held zero-order, updated every "
               f"{(command_update_s or 1.0 / fs_hz) * 1e3:g} ms" if command_hold == "zero_order"
               else "continuous command (5 ms raised-cosine steps)"))
    cmd = next(c for c in inputs if c != "ankle_angle_rad")
    return write_measured(
        Path(path), table, inputs=list(inputs), outputs=list(outputs),
        source={"preset": preset, "description": desc, "origin": "afo_mj synthetic"},
        noise={c: s for c, s in noise.items() if s > 0},
        segments={"period_s": 1.0, "phase_s": 0.0}, fmt=fmt, hold={cmd: command_hold})
