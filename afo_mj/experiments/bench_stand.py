"""The bench protocols on the ankle test stand (the ``stand`` rig), for any device spec.

Each run builds a fresh :class:`~afo_mj.human.test_stand.AnkleTestStand` (a wearer's foot, with
its weight, on the stand's load) and a fresh :class:`~afo_mj.circuits.device.CircuitDevice` of
the device's :class:`~afo_mj.circuits.device_spec.DeviceSpec` (a registered device or a
``[circuit]`` description), and steps them together (``stand.run_device``). What each protocol
needs of the device is declared in :data:`afo_mj.scenarios.bench_protocols.NEEDS` and checked
by :func:`run_stand`. Protocols, as reported for the HAFO prototype (Neubauer & Durfee 2016,
the seed's chapter 6) and the clinical stiffness rigs:

* :func:`torque_velocity` — full motor voltage, open loop, delivered torque against imposed
  constant plantarflexion velocities; free-foot no-load speed; locked-ankle stall torque.
* :func:`isometric_steps` — locked ankle, closed-loop torque control, plantarflexion torque
  steps of 20/30/40/50 N·m.
* :func:`frequency_response` — open-loop (motor voltage) sinusoidal sweeps: ankle velocity with
  the foot free on a weak centring spring, isometric torque with the ankle locked.
* :func:`position_step` — closed-loop ankle position control (PD with gravity compensation,
  optional integral, on the angle → torque command) with the foot carrying an added inertia.
* :func:`stiffness_sweeps` — the device emulating linear springs through its impedance mode
  while the stand's position drive sweeps the ankle (Bregman et al. 2009, *Gait Posture*
  30:144, BRUCE; Shuman & Russell Esposito 2021, EMPIRE).

:func:`run_stand` runs a selection and returns ``(summary, series)``;
:func:`afo_mj.outputs.bench_figures.plot_bench` draws the figures.

Sign conventions: ankle angle, velocity and torque are positive in dorsiflexion (the stand and
the device). Plantarflexion assistance torque is therefore negative; positive motor voltage
drives plantarflexion. Figures of merit are reported as positive magnitudes where their name
says so (``stall_torque_nm``, ``no_load_speed_deg_s``).

Formulas (each run, SI units; degrees only where a name ends in ``_deg`` / ``_deg_s``)
--------------------------------------------------------------------------------------------
* Full voltage: the command is ``full_voltage_v`` (default 1.25 × the fully charged pack
  open-circuit voltage, ``1.25 · 4.2 V · cells``), which the driver clips to
  ``duty_max · V_bus`` (:func:`~afo_mj.hydraulics.laws.driver_voltage_v`); it is reached through a
  50 ms linear ramp so the first millisecond does not slam the relief valve (a ramp does not
  change the steady values measured).
* Stall torque ``= −mean(τ)`` over the last 40 % of a locked-ankle run at full voltage.
* No-load speed ``= −mean(θ̇)`` of the free foot at full voltage over the window after it
  reached speed (from 0.15 s until it passes −0.45 rad), converted to deg/s. The foot's own
  weight (≈ 0.6 N·m near neutral) is the only load.
* Torque–velocity point: the stand imposes (``imposed`` load) a hold at +0.45 rad while the
  voltage ramps up (0.2 s, the stall state), then a raised-cosine velocity ramp (40 ms) to the
  constant velocity ``v`` held until the ankle reaches −0.45 rad (the ±32° stroke is not left);
  the point is ``mean(τ)`` over the hold after a 0.1 s settling allowance (at most 0.35 s).
  The no-load speed from the curve is its zero crossing (linear interpolation).
* Step metrics: :func:`afo_mj.metrics.response_metrics.step_metrics` (10–90 % rise, overshoot
  re final value, 2 % settling, steady-state error re target).
* Frequency response: ``u = u_0 + A sin 2πft`` [V] after a preload at ``u_0``; the output ``y``
  is the plantarflexion velocity ``−θ̇`` [rad/s] or plantarflexion torque ``−τ`` [N·m] (so
  that the low-frequency phase is ≈ 0°); gain and phase by the IEEE 1057 three-parameter fit
  (:func:`~afo_mj.metrics.response_metrics.sine_response`); gain in dB relative to the
  lowest frequency's gain; bandwidth = −3 dB frequency
  (:func:`~afo_mj.metrics.response_metrics.bandwidth_hz`).
* Position control: ``τ_cmd = K_p e + K_i ∫e dt − K_d θ̇ − τ_g(θ)``, ``e = θ_ref − θ``,
  ``τ_g`` the foot's gravity moment from the stand model (PD with gravity compensation,
  e.g. Spong, Hutchinson & Vidyasagar, *Robot Modeling and Control*, §8.4), clipped to
  ±``torque_limit_nm``, integral clamped so that ``K_i ∫e`` stays within the limit
  (anti-windup); the device's own torque loop delivers it.
* Energy balance of a run (from ``device.ledger()``): relative error
  ``|residual_j| / max(|electrical_in_j|, |mechanical_out_j|)``, the residual being
  ``in − out − losses − Δstored``; the denominator is ``electrical_in_j`` whenever the device
  motors (every run but the over-running torque–velocity points, where the stand drives the
  device and the mechanical input is the larger flow).

Time step
---------
The bench steps at 0.25 ms by default (``timestep_s``; the velocity sweep at 0.1 ms, see
:data:`VELOCITY_SWEEP_TIMESTEP_S`), to resolve the driver's electrical time constant
(L/R ≈ 0.17 ms) in the recorded responses. The energy ledger closes at any step: a device
step whose Newton correction fails (a 50 N·m step saturating the current at 1 ms) is redone
in converged sub-steps (:mod:`afo_mj.circuits.stepper`); at 1 ms
the isometric steps close to 2e-11 with the same 34 ms rise time.
``run_bench(timestep_s=...)`` sets one step for every test.
"""

from __future__ import annotations

import math
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from afo_mj.devices.hafo import HAFO_PUBLISHED
from afo_mj.circuits.device import CircuitDevice
from afo_mj.circuits.device_spec import DeviceSpec
from afo_mj.experiments.frequency_sweep import adaptive_log_sweep, resonance_peak
from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad
from afo_mj.metrics.response_metrics import bandwidth_hz, sine_response, step_metrics
from afo_mj.metrics.stiffness_metrics import sweep_stiffness
from afo_mj.scenarios.bench_protocols import (RIG_PROTOCOLS, STAND_DEFAULT_PROTOCOLS,
                                              BenchError, StiffnessSweepConfig, bench_spec,
                                              bus_voltage_v, check_protocols, motor_component,
                                              stiffness_label)

__all__ = ["PUBLISHED", "BenchError", "torque_velocity", "isometric_steps",
           "frequency_response", "position_step", "stiffness_sweeps", "run_stand",
           "energy_error", "ACCEPTANCE_TOLERANCE_REL"]

#: Published prototype figures (Neubauer & Durfee 2016; seed ch. 6): what the HAFO presets
#: are compared with (their specs carry them: :attr:`DeviceSpec.published`).
PUBLISHED = HAFO_PUBLISHED
#: The stiffness sweep's acceptance figure: emulated stiffness within 10 % of the command.
ACCEPTANCE_TOLERANCE_REL = 0.10

DEFAULT_TIMESTEP_S = 2.5e-4
DEFAULT_TV_VELOCITIES_DEG_S = tuple(-12.0 * k for k in range(11))      # 0 … −120 deg/s
#: Frequency ranges of the default sweeps (Hz): :func:`frequency_response` measures 20
#: log-spaced frequencies over the range, then 12 more inside the bracket of the gain's peak
#: (or, without an interior peak, of the −3 dB crossing):
#: :func:`afo_mj.experiments.frequency_sweep.adaptive_log_sweep`, 32 frequencies in all.
DEFAULT_TORQUE_RANGE_HZ = (0.2, 30.0)
DEFAULT_VELOCITY_RANGE_HZ = (1.0, 400.0)
#: The velocity sweep reaches the foot-on-oil resonance (≈ 150 Hz); 0.1 ms resolves it.
VELOCITY_SWEEP_TIMESTEP_S = 1e-4

_RAMP_S = 0.05          # full-voltage ramp
#: the bench's ankle excursion limit (rad), drawn on the position-step figure
STROKE_LIMIT_RAD = 0.45





# -- argument checks ------------------------------------------------------------------------------
def _check_number(name: str, value, lo: float = -math.inf, hi: float = math.inf,
                  lo_open: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise BenchError(f"{name} = {value!r} is not a number") from None
    bad_lo = v <= lo if lo_open else v < lo
    if not math.isfinite(v) or bad_lo or v > hi:
        lo_s = "" if lo == -math.inf else f"{lo:g} {'<' if lo_open else '<='} "
        hi_s = "" if hi == math.inf else f" <= {hi:g}"
        raise BenchError(f"{name} = {value!r} is out of range; allowed: {lo_s}{name}{hi_s}")
    return v


def _check_spec(spec) -> DeviceSpec:
    if not isinstance(spec, DeviceSpec):
        raise BenchError(f"spec = {type(spec).__name__}; allowed: a DeviceSpec "
                         "(afo_mj.devices.registry.device_spec(name), or "
                         "DeviceSpec.from_circuit(description))")
    return spec


def _check_seq(name: str, values, lo: float, hi: float, lo_open: bool = False) -> tuple:
    try:
        vals = tuple(values)
    except TypeError:
        raise BenchError(f"{name} = {values!r} is not a sequence of numbers") from None
    if not vals:
        raise BenchError(f"{name} is empty; allowed: at least one value")
    return tuple(_check_number(f"{name}[{i}]", v, lo, hi, lo_open) for i, v in enumerate(vals))


# -- one coupled run ------------------------------------------------------------------------------
class _Run:
    """One stand + device run: record, device log (1-D arrays, by generic signal name: the
    spec's log renames undone), ledger, energy error. ``open_loop``: ``fn`` gives the
    device's open-loop command (:meth:`DeviceSpec.circuit_for`), else a torque."""

    def __init__(self, spec: DeviceSpec, load: StandLoad, open_loop: bool, fn: Callable,
                 duration_s: float, timestep_s: float, body_mass_kg: float, height_m: float,
                 initial_angle_rad: float | None = None, label: str = "", impedance=None):
        stand = AnkleTestStand(body_mass_kg=body_mass_kg, height_m=height_m, load=load,
                               timestep_s=timestep_s, initial_angle_rad=initial_angle_rad)
        n = int(round(duration_s / timestep_s))
        if getattr(fn, "needs_stand", False):
            fn = fn(stand)
        dev = CircuitDevice(spec, open_loop=open_loop, torque_fn=fn, timestep_s=timestep_s,
                            max_steps=n, impedance=impedance)
        self.stand = stand
        self.rec = stand.run_device(dev, duration_s)
        #: the log by the spec's names (:attr:`DeviceSpec.log_names`) and by generic name
        self.named = {k: v[:, 0] for k, v in dev.log.arrays().items()}
        self.log = {g: self.named[k] for g, k in zip(_generic_fields(dev), dev.log_fields)}
        self.ledger = dev.ledger()
        self.label = label
        self.energy_error = energy_error(self.ledger)


def _generic_fields(dev: CircuitDevice) -> tuple:
    """The device log's fields by generic name, in the order of ``dev.log_fields``."""
    from afo_mj.circuits.stepper import LOG_HEADER
    cc = dev.cc
    return (LOG_HEADER + tuple(cc.state_names) + tuple(cc.probe_names) + tuple(cc.input_names)
            + tuple(f"controller.{n}" for n in cc.ctrl_names))


def energy_error(ledger: Mapping) -> float:
    """Relative energy-balance error of a run: ``|residual| / max(|E_in|, |E_mech|)`` (the
    input the circuit's sources delivered, the electrical input of a battery device)."""
    scale = max(abs(ledger["input_j"]), abs(ledger["mechanical_out_j"]))
    return abs(ledger["residual_j"]) / scale if scale > 0 else 0.0


def _full_voltage(spec: DeviceSpec, full_voltage_v: float | None) -> float:
    if full_voltage_v is None:
        return 1.25 * bus_voltage_v(spec.circuit_for(True))
    return _check_number("full_voltage_v", full_voltage_v, 0.0, 1000.0, lo_open=True)


def _motor_current(spec: DeviceSpec) -> str | None:
    """The generic log name of the motor's current state, None without a motor."""
    m = motor_component(spec.circuit)
    return None if m is None or m.kind != "motor" else f"{m.name}.current_a"


def _ramped(v: float, ramp_s: float = _RAMP_S) -> Callable:
    return lambda t, q, w: v * min(1.0, t / ramp_s)


def _ramp_hold(q0: float, v: float, t0: float, ta: float) -> ImposedTrajectory:
    """Hold at q0 until t0, raised-cosine velocity ramp to v over ta, then constant v."""
    def vel(t):
        s = t - t0
        if s <= 0:
            return 0.0
        if s < ta:
            return 0.5 * v * (1.0 - math.cos(math.pi * s / ta))
        return v

    def ang(t):
        s = t - t0
        if s <= 0:
            return q0
        if s < ta:
            return q0 + 0.5 * v * (s - ta / math.pi * math.sin(math.pi * s / ta))
        return q0 + v * (0.5 * ta + s - ta)

    def acc(t):
        s = t - t0
        return 0.5 * v * math.pi / ta * math.sin(math.pi * s / ta) if 0 < s < ta else 0.0

    return ImposedTrajectory(ang, vel, acc)


def _stand_kw(body_mass_kg: float, height_m: float, timestep_s: float) -> dict:
    return {"body_mass_kg": _check_number("body_mass_kg", body_mass_kg, 20.0, 200.0),
            "height_m": _check_number("height_m", height_m, 1.0, 2.3),
            "timestep_s": _check_number("timestep_s", timestep_s, 1e-5, 1e-3)}


# -- tests -----------------------------------------------------------------------------------------
def torque_velocity(spec: DeviceSpec,
                    velocities_deg_s: Sequence[float] = DEFAULT_TV_VELOCITIES_DEG_S, *,
                    full_voltage_v: float | None = None, body_mass_kg: float = 75.0,
                    height_m: float = 1.75, timestep_s: float = DEFAULT_TIMESTEP_S
                    ) -> tuple[dict, dict]:
    """Torque–velocity curve at full motor voltage, stall torque and no-load speed.

    ``velocities_deg_s``: imposed ankle velocities (≤ 0: plantarflexion, the direction the
    positive voltage drives; ≥ −400 deg/s). Returns ``(summary, series)``: summary keys
    ``stall_torque_nm``, ``no_load_speed_deg_s``, ``no_load_speed_from_curve_deg_s``,
    ``energy_error_max``; series ``torque_velocity`` (``velocity_deg_s``, ``torque_nm``,
    ``plantarflexion_speed_deg_s``, ``assist_torque_nm``), ``stall`` and ``no_load`` time series.
    """
    _check_spec(spec)
    kw = _stand_kw(body_mass_kg, height_m, timestep_s)
    vels = _check_seq("velocities_deg_s", velocities_deg_s, -400.0, 0.0)
    vfull = _full_voltage(spec, full_voltage_v)
    cur = _motor_current(spec)
    fn = _ramped(vfull)
    errors = {}

    # stall: locked at neutral
    stall = _Run(spec, StandLoad(kind="locked"), True, fn, 0.4, label="stall", **kw)
    n = stall.rec.time_s.size
    stall_tau = -float(np.mean(stall.rec.device_torque_nm[int(0.6 * n):]))
    errors["stall"] = stall.energy_error

    # no load: free foot started dorsiflexed, runs through neutral at full speed
    free = _Run(spec, StandLoad(kind="free"), True, fn, 0.4,
                initial_angle_rad=STROKE_LIMIT_RAD, label="no_load", **kw)
    t, q, w = free.rec.time_s, free.rec.angle_rad, free.rec.velocity_rad_s
    sel = (t >= 0.15) & (q >= -STROKE_LIMIT_RAD)
    if np.count_nonzero(sel) < 10:
        raise RuntimeError("no-load run: the foot left the stroke before reaching speed")
    no_load = -math.degrees(float(np.mean(w[sel])))
    errors["no_load"] = free.energy_error

    # imposed constant velocities
    t_pre, t_acc, settle, hold_max = 0.2, 0.04, 0.1, 0.35
    tau_pts = []
    for v_deg in vels:
        v = math.radians(v_deg)
        travel = 2 * STROKE_LIMIT_RAD - 0.5 * abs(v) * t_acc
        hold = hold_max if v == 0 else min(hold_max, travel / abs(v))
        hold = max(hold, settle + 0.05)
        traj = _ramp_hold(STROKE_LIMIT_RAD, v, t_pre, t_acc)
        run = _Run(spec, StandLoad(kind="imposed", trajectory=traj), True, fn,
                   t_pre + t_acc + hold, **kw)
        tt = run.rec.time_s
        win = tt >= t_pre + t_acc + settle
        tau_pts.append(float(np.mean(run.rec.device_torque_nm[win])))
        errors[f"torque_velocity_{abs(v_deg):g}deg_s_plantarflexion"] = run.energy_error
    v_arr = np.asarray(vels)
    tau_arr = np.asarray(tau_pts)
    # zero crossing of the assistance torque along increasing plantarflexion speed
    order = np.argsort(-v_arr)
    sp, at = -v_arr[order], -tau_arr[order]
    nl_curve = math.nan
    idx = np.flatnonzero((at[:-1] > 0) & (at[1:] <= 0))
    if idx.size:
        k = int(idx[0])
        nl_curve = float(sp[k] + at[k] / (at[k] - at[k + 1]) * (sp[k + 1] - sp[k]))
    summary = {"stall_torque_nm": stall_tau, "no_load_speed_deg_s": no_load,
               "no_load_speed_from_curve_deg_s": nl_curve,
               "full_voltage_command_v": vfull,
               "stall_current_a": (float(np.mean(stall.log[cur][int(0.6 * n):]))
                                   if cur else math.nan),
               "energy_error_max": max(errors.values()), "energy_errors": errors}
    series = {
        "torque_velocity": {"velocity_deg_s": v_arr, "torque_nm": tau_arr,
                            "plantarflexion_speed_deg_s": -v_arr, "assist_torque_nm": -tau_arr},
        "stall": {"time_s": stall.rec.time_s, "torque_nm": stall.rec.device_torque_nm,
                  "motor_current_a": stall.log[cur] if cur else np.full(n, math.nan)},
        "no_load": {"time_s": t, "velocity_deg_s": np.degrees(w), "angle_deg": np.degrees(q)},
    }
    return summary, series


def isometric_steps(spec: DeviceSpec,
                    levels_nm: Sequence[float] = (20.0, 30.0, 40.0, 50.0), *,
                    t_step_s: float = 0.05, duration_s: float = 0.5,
                    locked_angle_rad: float = 0.0, body_mass_kg: float = 75.0,
                    height_m: float = 1.75, timestep_s: float = DEFAULT_TIMESTEP_S
                    ) -> tuple[dict, dict]:
    """Isometric torque steps: locked ankle, torque mode, command 0 → −level at ``t_step_s``.

    ``levels_nm`` are plantarflexion torque magnitudes (> 0, ≤ 90 N·m). Metrics of the
    delivered torque per level (:func:`step_metrics`). Summary: ``levels`` →
    ``{"20": {...}, ...}`` plus ``energy_error_max``; series ``isometric_step_<L>nm`` with
    ``time_s``, ``command_nm``, ``torque_nm``.
    """
    _check_spec(spec)
    kw = _stand_kw(body_mass_kg, height_m, timestep_s)
    levels = _check_seq("levels_nm", levels_nm, 0.0, 90.0, lo_open=True)
    t_step_s = _check_number("t_step_s", t_step_s, 0.0, 1.0)
    duration_s = _check_number("duration_s", duration_s, t_step_s + 0.1, 10.0)
    q_lock = _check_number("locked_angle_rad", locked_angle_rad, -0.5, 0.5)
    out, series, errors = {}, {}, {}
    eps = 0.5 * kw["timestep_s"]
    for lev in levels:
        cmd = -lev
        fn = (lambda c: lambda t, q, w: c if t >= t_step_s - eps else 0.0)(cmd)
        run = _Run(spec, StandLoad(kind="locked", locked_angle_rad=q_lock), False, fn,
                   duration_s, label=f"step_{lev:g}", **kw)
        m = step_metrics(run.rec.time_s, run.rec.device_torque_nm, cmd, t_step_s)
        m["energy_error"] = run.energy_error
        m["peak_current_a"] = run.ledger.get("peak_current_a")
        out[f"{lev:g}"] = m
        errors[f"isometric_step_{lev:g}nm"] = run.energy_error
        series[f"isometric_step_{lev:g}nm"] = {
            "time_s": run.rec.time_s, "command_nm": run.log["commanded_torque_nm"],
            "torque_nm": run.rec.device_torque_nm}
    summary = {"levels": out, "energy_error_max": max(errors.values()), "energy_errors": errors}
    return summary, series


def frequency_response(spec: DeviceSpec, kind: str = "torque",
                       freqs_hz: Sequence[float] | None = None, *,
                       amplitude_v: float | None = None, bias_v: float | None = None,
                       spring_stiffness_nm_per_rad: float = 20.0,
                       added_inertia_kg_m2: float = 0.0, settle_s: float = 0.3,
                       measure_cycles: int = 1, preload_s: float = 0.3,
                       body_mass_kg: float = 75.0, height_m: float = 1.75,
                       timestep_s: float | None = None) -> tuple[dict, dict]:
    """Open-loop frequency response from motor voltage (mode ``voltage``).

    ``kind="torque"``: isometric — ankle locked at neutral; ``u = bias + A sin 2πft`` with
    defaults bias 1.5 V, A 0.75 V (stall current ``u/R`` ≤ 3.75 A, inside the 6.2 A limit, so
    the driver stays linear; the bias keeps line a pressurised so the flushing valve does not
    switch sides); output plantarflexion torque ``−τ`` [N·m].

    ``kind="velocity"``: the foot swings free on a weak centring spring
    (``spring_stiffness_nm_per_rad``, default 20 N·m/rad, relaxed at neutral: it holds the foot
    near neutral against its weight, inside the ±32° stroke, and against the pump's
    ≈ 35 N·m·s/rad torque–speed slope its corner k/b ≈ 0.1 Hz lies below the sweep) plus
    optional ``added_inertia_kg_m2``; ``u = A sin 2πft``, no bias, default A = 10 V
    (≈ ±50 deg/s, 8° at 1 Hz: large enough that the seal-friction stick at each velocity
    reversal is a small part of the cycle; at 3 V it distorts the response by ~50 %); output
    plantarflexion velocity ``−θ̇`` [rad/s].

    ``freqs_hz``: the frequencies to measure; default (None) an adaptive sweep over
    :data:`DEFAULT_TORQUE_RANGE_HZ` / :data:`DEFAULT_VELOCITY_RANGE_HZ` (20 log-spaced, then 12
    more about the gain's peak or the −3 dB crossing; 32 in all,
    :func:`afo_mj.experiments.frequency_sweep.adaptive_log_sweep`), enough to draw a resonance
    and place it (``resonance_hz``: parabola through the peak in log f).

    Each frequency: ``preload_s`` at the bias (50 ms ramp), then the sine for ``settle_s``
    (transient allowance) plus ``measure_cycles`` whole periods (at least 0.5 s); the fit uses
    the measured periods. Summary: ``bandwidth_hz`` (−3 dB re the lowest frequency, NaN plus
    ``bandwidth_note`` if not reached), ``dc_gain`` (gain at the lowest frequency, N·m/V or
    rad/s/V), ``resonance_hz`` / ``resonance_peak_db`` / ``resonance_inside_range``
    (:func:`afo_mj.experiments.frequency_sweep.resonance_peak`), ``n_frequencies``,
    ``refined`` (what the adaptive sweep refined: ``peak``, ``bandwidth``, ``top``, or
    ``none`` for given frequencies), ``energy_error_max``; series
    ``frequency_response_<kind>``: ``freq_hz``, ``gain``
    (absolute), ``gain_db`` (re the lowest frequency), ``phase_deg``, ``distortion`` (fit
    residual RMS ÷ fundamental RMS).
    """
    _check_spec(spec)
    if kind not in ("velocity", "torque"):
        raise BenchError(f"kind = {kind!r}; allowed: 'velocity', 'torque'")
    if timestep_s is None:
        timestep_s = DEFAULT_TIMESTEP_S if kind == "torque" else VELOCITY_SWEEP_TIMESTEP_S
    kw = _stand_kw(body_mass_kg, height_m, timestep_s)
    nyq = 0.5 / kw["timestep_s"]
    if freqs_hz is not None:
        freqs = _check_seq("freqs_hz", freqs_hz, 0.0, nyq / 10.0, lo_open=True)
        if len(freqs) < 2 or len(set(freqs)) != len(freqs):
            raise BenchError(f"freqs_hz = {list(freqs)!r}; allowed: at least 2 distinct "
                             "frequencies")
        freqs = tuple(sorted(freqs))
    else:
        freqs = None
        f_range = DEFAULT_TORQUE_RANGE_HZ if kind == "torque" else DEFAULT_VELOCITY_RANGE_HZ
        _check_seq("frequency range", f_range, 0.0, nyq / 10.0, lo_open=True)
    if kind == "torque":
        amp = _check_number("amplitude_v", 0.75 if amplitude_v is None else amplitude_v,
                            0.0, 20.0, lo_open=True)
        bias = _check_number("bias_v", 1.5 if bias_v is None else bias_v, -20.0, 20.0)
        load = StandLoad(kind="locked", locked_angle_rad=0.0,
                         added_inertia_kg_m2=_check_number("added_inertia_kg_m2",
                                                           added_inertia_kg_m2, 0.0, 10.0))
    else:
        amp = _check_number("amplitude_v", 10.0 if amplitude_v is None else amplitude_v,
                            0.0, 20.0, lo_open=True)
        bias = _check_number("bias_v", 0.0 if bias_v is None else bias_v, -20.0, 20.0)
        load = StandLoad(kind="spring", spring_stiffness_nm_per_rad=_check_number(
                             "spring_stiffness_nm_per_rad", spring_stiffness_nm_per_rad, 0.0,
                             1e4, lo_open=True),
                         spring_rest_angle_rad=0.0,
                         added_inertia_kg_m2=_check_number("added_inertia_kg_m2",
                                                           added_inertia_kg_m2, 0.0, 10.0))
    settle = _check_number("settle_s", settle_s, 0.0, 10.0)
    mc = int(_check_number("measure_cycles", measure_cycles, 1.0, 100.0))
    t_pre = _check_number("preload_s", preload_s, 0.0, 10.0)

    def measure(f: float) -> dict:
        period = 1.0 / f
        n_settle = settle / period
        n_meas = max(mc, math.ceil(0.5 / period))
        # two steps' margin: the record must hold the whole periods despite rounding to steps
        dur = t_pre + (n_settle + n_meas) * period + 2.0 * kw["timestep_s"]
        w = 2 * math.pi * f

        def fn(t, q, v, w=w):
            if t < t_pre:
                return bias * min(1.0, t / _RAMP_S)
            return bias + amp * math.sin(w * (t - t_pre))

        run = _Run(spec, load, True, fn, dur, label=f"{kind}_{f:g}Hz", **kw)
        t = run.rec.time_s
        sel = t >= t_pre - 0.5 * kw["timestep_s"]
        # sample k: voltage held over step k, state at its start (the delivered torque of
        # the record is the end-of-step value, so it is shifted one sample)
        u = run.log["actuated_input"][sel]
        if kind == "torque":
            tau = run.rec.device_torque_nm
            y = -np.concatenate(([0.0], tau[:-1]))[sel]
        else:
            y = -run.rec.velocity_rad_s[sel]
        r = sine_response(t[sel], u, y, f, settle_cycles=n_settle)
        return {"gain": r["gain"], "phase_deg": r["phase_deg"], "distortion": r["distortion_y"],
                "energy_error": run.energy_error}

    if freqs is None:
        f_arr, results, refined = adaptive_log_sweep(measure, *f_range)
        freqs = tuple(float(f) for f in f_arr)
    else:
        results, refined = [measure(f) for f in freqs], "none"
    gains = [r["gain"] for r in results]
    phases = [r["phase_deg"] for r in results]
    dist = [r["distortion"] for r in results]
    errors = {f"frequency_response_{kind}_{f:g}Hz": r["energy_error"]
              for f, r in zip(freqs, results)}
    g = np.asarray(gains)
    g_db = 20 * np.log10(g / g[0])
    ph = np.degrees(np.unwrap(np.radians(phases)))
    bw, note = bandwidth_hz(freqs, g_db, return_note=True)
    f_peak, peak_db, inside = resonance_peak(freqs, g)
    summary = {"kind": kind, "bandwidth_hz": bw, "bandwidth_note": note,
               "dc_gain": float(g[0]), "bias_v": bias, "amplitude_v": amp,
               "resonance_hz": f_peak if inside else math.nan,
               "resonance_peak_db": peak_db if inside else math.nan,
               "resonance_inside_range": inside, "n_frequencies": len(freqs),
               "refined": refined,
               "energy_error_max": max(errors.values()), "energy_errors": errors}
    series = {f"frequency_response_{kind}": {"freq_hz": np.asarray(freqs), "gain": g,
                                              "gain_db": g_db, "phase_deg": ph,
                                              "distortion": np.asarray(dist)}}
    return summary, series


def position_step(spec: DeviceSpec, step_rad: float = -math.radians(15.0), *,
                  kp_nm_per_rad: float = 60.0, ki_nm_per_rad_s: float = 0.0,
                  kd_nm_s_per_rad: float = 6.0, gravity_compensation: bool = True,
                  torque_limit_nm: float = 65.0,
                  added_inertia_kg_m2: float = 0.05, t_step_s: float = 0.3,
                  duration_s: float = 1.5, body_mass_kg: float = 75.0, height_m: float = 1.75,
                  timestep_s: float = DEFAULT_TIMESTEP_S) -> tuple[dict, dict]:
    """Closed-loop ankle position step (PD + gravity compensation, optional integral, on the
    ankle angle → torque command; the device runs in torque mode).

    The foot (plus ``added_inertia_kg_m2`` on the axis, default 0.05 kg·m², about a shoe and
    foot segment's worth swung at the ankle, and its own weight) starts at neutral, held there
    by the controller until ``t_step_s``, when the reference steps to ``step_rad`` (default
    −15°, plantarflexion; |step| ≤ 0.5 rad keeps the ±32° stroke). Control law in the module
    docstring; with I ≈ 0.058 kg·m² (foot 0.008 + added 0.05) the default gains (K_p
    60 N·m/rad, K_d 6 N·m·s/rad, K_i 0) put the loop's natural frequency √(K_p/I) ≈ 32 rad/s
    (5 Hz) below the torque loop's (≈ 35 ms rise) and its damping ratio
    ζ = K_d / (2√(K_p I)) ≈ 1.6 on the rigid-body model: the torque-loop lag takes part of
    that damping (K_d 3 overshoots ≈ 30 %). An integral term (K_i > 0) removes a residual
    friction offset only slowly and winds up during the step, so it is off by default; the
    gravity compensation removes the foot's weight offset.

    Summary: :func:`step_metrics` of the angle (``*_s``, ``overshoot_pct``,
    ``steady_state_error`` in rad and ``steady_state_error_deg``), ``energy_error``; series
    ``position_step`` with ``time_s``, ``angle_deg``, ``reference_deg``, ``command_nm``,
    ``torque_nm``.
    """
    _check_spec(spec)
    kw = _stand_kw(body_mass_kg, height_m, timestep_s)
    step = _check_number("step_rad", step_rad, -0.5, 0.5)
    if step == 0:
        raise BenchError("step_rad = 0; allowed: a nonzero step, -0.5 <= step_rad <= 0.5")
    kp = _check_number("kp_nm_per_rad", kp_nm_per_rad, 0.0, 1e4)
    ki = _check_number("ki_nm_per_rad_s", ki_nm_per_rad_s, 0.0, 1e5)
    kd = _check_number("kd_nm_s_per_rad", kd_nm_s_per_rad, 0.0, 1e3)
    lim = _check_number("torque_limit_nm", torque_limit_nm, 0.0, 90.0, lo_open=True)
    inertia = _check_number("added_inertia_kg_m2", added_inertia_kg_m2, 0.0, 10.0, lo_open=True)
    t_step_s = _check_number("t_step_s", t_step_s, 0.0, 5.0)
    duration_s = _check_number("duration_s", duration_s, t_step_s + 0.2, 20.0)
    h = kw["timestep_s"]
    i_lim = lim / ki if ki > 0 else 0.0

    def make_law(stand):
        gravity = stand.gravity_torque_nm if gravity_compensation else (lambda q: 0.0)
        state = {"i": 0.0}

        def law(t, q, v):
            ref = step if t >= t_step_s - 0.5 * h else 0.0
            e = ref - q
            if ki > 0:
                state["i"] = min(i_lim, max(-i_lim, state["i"] + e * h))
            tau = kp * e + ki * state["i"] - kd * v - gravity(q)
            return min(lim, max(-lim, tau))
        return law

    make_law.needs_stand = True
    run = _Run(spec, StandLoad(kind="inertia", added_inertia_kg_m2=inertia), False, make_law,
               duration_s, initial_angle_rad=0.0, label="position_step", **kw)
    t = run.rec.time_s
    m = step_metrics(t, run.rec.angle_rad, step, t_step_s)
    m["steady_state_error_deg"] = math.degrees(m["steady_state_error"])
    m["step_deg"] = math.degrees(step)
    m["energy_error"] = run.energy_error
    ref = np.where(t >= t_step_s - 0.5 * h, step, 0.0)
    series = {"position_step": {"time_s": t, "angle_deg": np.degrees(run.rec.angle_rad),
                                "reference_deg": np.degrees(ref),
                                "command_nm": run.log["commanded_torque_nm"],
                                "torque_nm": run.rec.device_torque_nm}}
    return m, series


# -- stiffness emulation ---------------------------------------------------------------------------
def stiffness_sweep(spec: DeviceSpec, stiffness_nm_per_rad: float,
                    cfg: StiffnessSweepConfig) -> tuple[dict, dict]:
    """One commanded spring on the stand (a clinical stiffness rig): the device emulates
    ``τ_cmd = −K (θ − θ0) − B θ̇`` (+ dorsiflexion; its impedance mode) while the stand's
    position drive imposes ``θ(t) = A sin(2π f t)`` for ``cycles`` periods from neutral. The
    record (angle, delivered torque) is reduced by
    :func:`afo_mj.metrics.stiffness_metrics.sweep_stiffness` (least-squares slope over whole
    cycles, the first dropped as start-up); the ledger gives pressures and energies.

    Figures (SI unless the name says otherwise): ``commanded_nm_per_rad`` /
    ``commanded_nm_per_deg``, ``emulated_nm_per_rad`` / ``emulated_nm_per_deg`` (the fitted
    slope, restoring positive), ``error_rel`` = emulated / commanded − 1, ``r_squared``,
    ``rest_angle_rad`` (the fit's zero-torque crossing), the branch stiffnesses,
    ``hysteresis_energy_j`` (loop area per cycle), ``hysteresis_fraction``, ``loss_factor``,
    ``peak_torque_nm`` and ``commanded_peak_torque_nm`` (= K A + B 2π f A, an upper bound of
    the sum), ``torque_tracking_rmse_nm``, ``peak_pressure_pa`` (the highest node, gauge),
    ``peak_chamber_pressure_pa``, ``peak_load_pressure_pa`` (largest |p_A − p_B|),
    ``peak_supply_pressure_pa`` (the rail, a valve device's; None without one),
    ``electrical_in_j`` (energy drawn), ``electrical_per_cycle_j``,
    ``mean_electrical_power_w``, ``mechanical_out_j``, ``losses_j`` (the device's named ledger,
    else by component), ``energy_balance_error_rel`` (ledger residual / throughput) and
    ``energy_error`` (:func:`energy_error`)."""
    _check_spec(spec)
    k = float(stiffness_nm_per_rad)
    traj = ImposedTrajectory.sinusoid(cfg.amplitude_rad, cfg.frequency_hz)
    run = _Run(spec, StandLoad(kind="imposed", trajectory=traj), False, None, cfg.duration_s,
               timestep_s=cfg.timestep_s, body_mass_kg=cfg.body_mass_kg, height_m=cfg.height_m,
               impedance=[(1e9, k, cfg.damping_nm_s_per_rad, cfg.rest_angle_rad, 0.0)])
    rec, log, led = run.rec, run.log, run.ledger
    theta, tau = rec.angle_rad, rec.device_torque_nm
    sw = sweep_stiffness(theta, tau, rec.velocity_rad_s)
    w = 2 * math.pi * cfg.frequency_hz
    cmd, dlv = log["commanded_torque_nm"], log["delivered_torque_nm"]
    drawn = led.get("electrical_drawn_j", led["input_drawn_j"])
    pa, pb = log.get("chamber_a"), log.get("chamber_b")
    fig = {
        "commanded_nm_per_rad": k,
        "commanded_nm_per_deg": k * math.pi / 180.0,
        "emulated_nm_per_rad": sw.stiffness_nm_per_rad,
        "emulated_nm_per_deg": sw.stiffness_nm_per_deg,
        "error_rel": sw.stiffness_nm_per_rad / k - 1.0,
        "r_squared": sw.r_squared,
        "rest_angle_rad": sw.rest_angle_rad,
        "dorsiflexing_nm_per_rad": sw.dorsiflexing_stiffness_nm_per_rad,
        "plantarflexing_nm_per_rad": sw.plantarflexing_stiffness_nm_per_rad,
        "hysteresis_energy_j": sw.hysteresis_energy_j,
        "hysteresis_fraction": sw.hysteresis_fraction,
        "loss_factor": sw.loss_factor,
        "cycles_analysed": sw.n_cycles,
        "angle_amplitude_rad": sw.angle_amplitude_rad,
        "peak_torque_nm": sw.max_torque_nm,
        "commanded_peak_torque_nm": k * cfg.amplitude_rad
        + cfg.damping_nm_s_per_rad * w * cfg.amplitude_rad,
        "torque_tracking_rmse_nm": float(np.sqrt(np.mean((cmd - dlv) ** 2))),
        "peak_pressure_pa": led["peak_pressure_pa"],
        "peak_chamber_pressure_pa": (None if pa is None or pb is None
                                     else float(max(pa.max(), pb.max()))),
        "peak_load_pressure_pa": (None if pa is None or pb is None
                                  else float(np.max(np.abs(pa - pb)))),
        "peak_supply_pressure_pa": led.get("peak_supply_pressure_pa"),
        "electrical_in_j": drawn,
        "electrical_per_cycle_j": drawn / cfg.cycles,
        "mean_electrical_power_w": drawn / cfg.duration_s,
        "mechanical_out_j": led["mechanical_out_j"],
        "losses_j": led["losses_j"],
        "energy_balance_error_rel": led["balance_error_rel"],
        "energy_error": run.energy_error,
        "newton_unconverged_steps": led["newton_unconverged_steps"],
        "battery_overload_steps": led["battery_overload_steps"],
    }
    series = {"time_s": rec.time_s, "angle_rad": theta, "torque_nm": tau,
              "commanded_torque_nm": cmd, "stiffness_nm_per_rad": k,
              "rest_angle_rad": cfg.rest_angle_rad,
              # the device log (its own time base) for stiffness_timeseries.png
              "log_time_s": log["time_s"], "log_delivered_torque_nm": dlv}
    # the pressures and valve signals a valve device logs under these names (absent from
    # other circuits: the figure leaves them out)
    for key in ("supply_pa", "pump_pa", "chamber_a_pa", "chamber_b_pa", "valve_position",
                "valve_command"):
        if key in run.named:
            series[key] = run.named[key]
    return fig, series


def stiffness_sweeps(spec: DeviceSpec, cfg: StiffnessSweepConfig,
                     tolerance_rel: float = ACCEPTANCE_TOLERANCE_REL) -> tuple[dict, dict]:
    """Every commanded spring of ``cfg`` (:func:`stiffness_sweep`); returns ``(summary,
    series)``: summary ``stiffness`` (per ``k<K>``, K in N·m/deg as :func:`stiffness_label`
    prints it), ``sweep`` (the rig settings, SI), ``acceptance`` (every emulated stiffness
    within ``tolerance_rel`` of its command) and ``energy_error_max``; series
    ``stiffness_sweeps`` → ``k<K>`` → arrays."""
    per, series = {}, {}
    for k in cfg.stiffnesses_nm_per_rad:
        lab = stiffness_label(k)
        per[lab], series[lab] = stiffness_sweep(spec, k, cfg)
    worst = max(abs(v["error_rel"]) for v in per.values())
    summary = {
        "stiffness": per,
        "sweep": {"amplitude_rad": cfg.amplitude_rad, "frequency_hz": cfg.frequency_hz,
                  "cycles": cfg.cycles, "duration_s": cfg.duration_s,
                  "damping_nm_s_per_rad": cfg.damping_nm_s_per_rad,
                  "rest_angle_rad": cfg.rest_angle_rad, "timestep_s": cfg.timestep_s,
                  "body_mass_kg": cfg.body_mass_kg, "height_m": cfg.height_m,
                  "imposed": "theta(t) = amplitude sin(2 pi f t) from neutral; first cycle "
                             "dropped as start-up"},
        "acceptance": {"tolerance_rel": tolerance_rel, "worst_error_rel": worst,
                       "passed": bool(worst <= tolerance_rel),
                       "criterion": "|emulated / commanded stiffness - 1| <= tolerance_rel "
                                    "for every commanded stiffness"},
        "energy_error_max": max(v["energy_error"] for v in per.values()),
    }
    return summary, {"stiffness_sweeps": series}


# -- the whole stand ------------------------------------------------------------------------------
def run_stand(spec: DeviceSpec, protocols: Iterable[str] = STAND_DEFAULT_PROTOCOLS,
              body_mass_kg: float = 75.0, height_m: float = 1.75, *,
              timestep_s: float | None = None,
              stiffness: StiffnessSweepConfig | None = None) -> tuple[dict, dict]:
    """Run the selected protocols on the stand; returns ``(summary, series)``. Each protocol
    the device cannot run is refused first (:func:`~afo_mj.scenarios.bench_protocols.
    check_protocols`), naming the protocol, the device and what it lacks.

    ``summary`` (keys present for the protocols run): ``stall_torque_nm``,
    ``no_load_speed_deg_s``, ``no_load_speed_from_curve_deg_s``; ``bandwidth_hz``
    (isometric-torque open-loop −3 dB bandwidth), ``velocity_bandwidth_hz``; ``rise_time_s``,
    ``overshoot_pct``, ``settling_time_s`` (the 40 N·m isometric step, if run) and
    ``isometric_steps`` (per level); ``position_step`` (metrics) with
    ``position_rise_time_s``, ``position_overshoot_pct``, ``position_steady_state_error_deg``;
    ``stiffness``, ``sweep``, ``acceptance`` (the stiffness sweeps, ``stiffness`` = the sweep's
    :class:`StiffnessSweepConfig`, required for that protocol); ``energy_error_max`` over every
    run and ``energy_errors`` per run. ``series``: ``{name: {signal: array}}`` (see each
    protocol). ``timestep_s=None`` uses each protocol's default step (module docstring).
    """
    _check_spec(spec)
    if isinstance(protocols, str):
        protocols = (protocols,)
    protocols = tuple(protocols)
    bad = [x for x in protocols if x not in RIG_PROTOCOLS["stand"]]
    if bad or not protocols:
        raise BenchError(f"protocols = {list(protocols)!r}; allowed on the stand: a non-empty "
                         "subset of " + ", ".join(repr(x) for x in RIG_PROTOCOLS["stand"]))
    check_protocols(spec, protocols, "stand")
    spec = bench_spec(spec)
    if "stiffness" in protocols and stiffness is None:
        raise BenchError("protocol 'stiffness' on the stand needs its sweep (stiffness = a "
                         "StiffnessSweepConfig from sweep_config(...))")
    kw = {"body_mass_kg": body_mass_kg, "height_m": height_m}
    _stand_kw(body_mass_kg, height_m, DEFAULT_TIMESTEP_S if timestep_s is None else timestep_s)
    if timestep_s is not None:
        kw["timestep_s"] = timestep_s
    summary: dict = {"protocols": list(protocols)}
    series: dict = {}
    errors: dict = {}
    if "torque_velocity" in protocols:
        s, ser = torque_velocity(spec, **kw)
        summary.update({k: s[k] for k in ("stall_torque_nm", "no_load_speed_deg_s",
                                          "no_load_speed_from_curve_deg_s", "stall_current_a")})
        errors.update(s["energy_errors"])
        series.update(ser)
    if "isometric_steps" in protocols:
        s, ser = isometric_steps(spec, **kw)
        summary["isometric_steps"] = s["levels"]
        m40 = s["levels"].get("40")
        if m40 is not None:
            summary.update(rise_time_s=m40["rise_time_s"], overshoot_pct=m40["overshoot_pct"],
                           settling_time_s=m40["settling_time_s"],
                           steady_state_error_nm=m40["steady_state_error"])
        errors.update(s["energy_errors"])
        series.update(ser)
    if "frequency_response" in protocols:
        for kind, key in (("torque", "bandwidth_hz"), ("velocity", "velocity_bandwidth_hz")):
            s, ser = frequency_response(spec, kind, **kw)
            summary[key] = s["bandwidth_hz"]
            summary[f"{kind}_dc_gain"] = s["dc_gain"]
            summary[f"{kind}_resonance_hz"] = s["resonance_hz"]
            summary[f"{kind}_frequency_count"] = s["n_frequencies"]
            if s["bandwidth_note"]:
                summary[f"{key.removesuffix('_hz')}_note"] = s["bandwidth_note"]
            errors.update(s["energy_errors"])
            series.update(ser)
    if "position_step" in protocols:
        m, ser = position_step(spec, **kw)
        summary["position_step"] = m
        summary.update(position_rise_time_s=m["rise_time_s"],
                       position_overshoot_pct=m["overshoot_pct"],
                       position_settling_time_s=m["settling_time_s"],
                       position_steady_state_error_deg=m["steady_state_error_deg"])
        errors["position_step"] = m["energy_error"]
        series.update(ser)
    if "stiffness" in protocols:
        s, ser = stiffness_sweeps(spec, stiffness)
        summary.update(stiffness=s["stiffness"], sweep=s["sweep"], acceptance=s["acceptance"])
        errors.update({f"stiffness_{lab}": v["energy_error"]
                       for lab, v in s["stiffness"].items()})
        series.update(ser)
    summary["energy_errors"] = errors
    summary["energy_error_max"] = max(errors.values())
    return summary, series
