"""The bench protocols on a simulated load (the ``load`` rig), for any device spec.

The stand rig (:mod:`afo_mj.experiments.bench_stand`) drives a device on the MuJoCo ankle
test stand; here the device's compiled circuit (:class:`afo_mj.circuits.device.CircuitDevice`
of its :class:`~afo_mj.circuits.device_spec.DeviceSpec`: a registered device with its initial
state and named ledger, or a ``[circuit]`` description) drives a simulated load: a foot
inertia ``J`` on a torsional spring ``K`` and damper ``c`` (``run_load``), the joint motion
imposed (``run_imposed``: a locked ankle, a constant velocity, a sinusoid), or, for the
closed position loop, the same inertia stepped with the device's coupled protocol.

Protocols (:data:`~afo_mj.scenarios.bench_protocols.PROTOCOLS`) and what they need of the
device (:data:`~afo_mj.scenarios.bench_protocols.NEEDS`, refused by :func:`run_load_bench`
naming the protocol, the device and what it lacks):

* ``torque_velocity`` — an open-loop motor voltage (the device's open-loop variant; a
  pump-controlled description's controller is replaced by ``open_loop``): full motor
  voltage ``1.25 × V_bus``, which the driver clips to ``duty_max V_bus``, reached
  through a 50 ms ramp. Stall torque ``= −mean(τ)`` over the last 40 % of a locked run
  (0.4 s, lengthened to 1.5 s then 4 s until that window changes by under 1 %:
  ``stall_settled``);
  no-load speed ``= −mean(θ̇)`` of the free inertia (no spring) from 0.1 s until it passes
  80 % of the plantarflexion stroke; torque–velocity points at imposed constant
  plantarflexion velocities (``mean(τ)`` after 50 ms at the velocity).
* ``isometric_steps`` — a torque controller: locked ankle, plantarflexion torque steps;
  10–90 % rise time, overshoot and steady-state error
  (:func:`~afo_mj.metrics.response_metrics.step_metrics`).
* ``frequency_response`` — a motor-driven circuit (open loop, as ``torque_velocity``):
  motor-voltage sine about 0 V, plantarflexion velocity ``−θ̇`` of the inertia on its spring
  at ``freq_points`` log-spaced frequencies, then ``freq_refine_points`` more log-spaced
  inside the bracket of the largest gain (20 + 12 by default,
  :func:`afo_mj.experiments.frequency_sweep.adaptive_log_sweep`); gain and phase by the
  three-parameter sine fit; the resonance (the inertia on the oil column) is the vertex of the
  parabola through the largest gain and its neighbours in (log f, dB) and its peak the largest
  measured gain in dB above the lowest frequency's gain.
* ``position_step`` — a torque controller: ``τ_cmd = K_p (θ_ref − θ) − K_d θ̇`` (clipped to
  ``±torque_limit_nm``) on the inertia and spring; step metrics of the angle.
* ``stiffness`` — a torque controller, which renders a spring through its command
  (``τ_cmd = −K (θ − θ_rest)``; the rest angle at the sweep's dorsiflexion end so that the
  command is plantarflexion only, as a single-acting actuator can deliver): imposed sinusoid,
  emulated stiffness = −slope of the least-squares line of delivered torque on angle.
  Refused for ``open_loop``.
* ``flow_vs_duty`` — a circuit metered by on/off valves under PWM (controller
  ``digital_valve_torque``; seed ch. 5). The controller's ``valve_command_on`` switch is set
  (the command is the metering fraction ``u``, open loop; the supply at its set speed). Per duty
  ``u`` in ``duties``: the pump spun up with the ankle locked at 80 % of the dorsiflexion stroke and
  the valves at rest (``u = 0``), then the inertia ``flow_inertia_kg_m2`` (an adult foot about the
  ankle, 0.01 kg m²) released (no spring: a spring's torque would pull the line below the tank)
  against a damper ``flow_damping_nm_s_rad`` and a constant dorsiflexion torque
  ``k_τ p_bias`` (``flow_bias_pressure_pa``: the actuator's line held above the tank, so the
  open switching valve, not the actuator, takes the pump's flow) at ``u``; the flow delivered into
  the actuator ``Q = −k_τ θ̇`` (``k_τ`` its torque per pascal = displacement per radian) and the
  pump's geometric flow ``d ω`` averaged over whole PWM periods from the second period until
  the ankle passes 80 % of the plantarflexion stroke. Figures: ``Q`` and ``Q/(d ω)`` per
  duty and the straight line ``Q/(d ω) = a u + b`` fitted by least squares. Seed ch. 5: on a
  load of constant pressure the delivered fraction is the duty less what passes while the
  valve travels, ``u − (1 − 2x*) T_sw f`` (``x*`` the opening at which the pump's pressure
  falls to the load's), so within ``± T_sw f`` of ``u``; the load's inertia carries flow
  through the open phase too (measured on the digital preset: 0.375 at ``u = 0.4`` with
  0.01 kg m², 0.338 with 0.001 kg m²). The PWM period must be a whole number of steps.
* ``tracking`` — a torque controller: a Zhang et al. (2017) profile (peak
  ``tracking_peak_torque_nm``) commanded on a load moved through ``θ = A sin 2πft`` (one
  profile per cycle); RMSE of delivered − commanded torque over all cycles but the first, and
  the energy over those cycles per cycle: the run's ledger less that of a second run of the
  first cycle alone (the same device from the same state under the same inputs: its first
  cycle is the first cycle of the whole run), giving ``electrical_j_per_cycle`` (drawn from
  the source), ``electrical_net_j_per_cycle``, ``mechanical_j_per_cycle`` (net work on the
  ankle), ``losses_j_per_cycle`` and ``stored_change_j_per_cycle`` (the device's named
  ledger, else by component), ``hydraulic_j_per_cycle`` (a named ledger's pump output),
  ``efficiency_mechanical`` = mechanical / drawn, ``efficiency_hydraulic`` = hydraulic / drawn.

Every run's energy ledger is reported (``ledger.<run>``: ``balance_error_rel``); the
summary's ``energy.balance_error_rel`` is the worst and ``energy.ledger_closed`` says whether
all are within 1e-9.

Sign conventions as the circuits': angle, velocity and torque positive in dorsiflexion;
plantarflexion torque negative; positive motor voltage drives plantarflexion.
"""

from __future__ import annotations

import math

import numpy as np

from afo_mj.circuits.device_spec import DeviceSpec
from afo_mj.experiments.frequency_sweep import adaptive_log_sweep, resonance_peak
from afo_mj.metrics.response_metrics import sine_response, step_metrics
from afo_mj.scenarios.bench_protocols import (LOAD_DEFAULT_PROTOCOLS, RIG_PROTOCOLS,
                                              BenchError, LoadBenchConfig, ProtocolError,
                                              bench_spec, bus_voltage_v, check_protocols,
                                              joint_actuator, stroke_limits_rad)

__all__ = ["run_load_bench", "LEDGER_TOLERANCE"]

LEDGER_TOLERANCE = 1e-9
_RAMP_S = 0.05


def _no_command(t, q, w):
    """The coupled-step command of a device whose replay loops take theirs per sample."""
    return 0.0


# -- runs ---------------------------------------------------------------------------------------
class _Bench:
    def __init__(self, spec: DeviceSpec, cfg: LoadBenchConfig):
        self.spec, self.cfg = bench_spec(spec), cfg
        self.circuit = spec.circuit
        self.ledgers: dict = {}

    def _dev(self, open_loop=False, **kw):
        from afo_mj.circuits.device import CircuitDevice
        if open_loop:
            kw.setdefault("torque_fn", _no_command)
        return CircuitDevice(self.spec, timestep_s=self.cfg.timestep_s, open_loop=open_loop,
                             **kw)

    def _close(self, dev, label):
        led = dev.ledger()
        self.ledgers[label] = {"balance_error_rel": led["balance_error_rel"],
                               "input_j": led["input_j"],
                               "mechanical_out_j": led["mechanical_out_j"],
                               "peak_pressure_pa": led["peak_pressure_pa"],
                               "newton_unconverged_steps": led["newton_unconverged_steps"],
                               "battery_overload_steps": led["battery_overload_steps"]}
        return led

    def load(self, open_loop, cmd, label, stiffness=None, damping=None, theta0=0.0):
        c = self.cfg
        dev = self._dev(open_loop)
        log = dev.run_load(cmd, c.load_inertia_kg_m2,
                           c.load_stiffness_nm_rad if stiffness is None else stiffness,
                           c.load_damping_nm_s_rad if damping is None else damping,
                           theta0_rad=theta0)
        self._close(dev, label)
        return log

    def imposed(self, open_loop, cmd, angle, velocity, label):
        dev = self._dev(open_loop)
        log = dev.run_imposed(cmd, angle, velocity)
        return log, self._close(dev, label)

    def t(self, duration_s):
        n = int(round(duration_s / self.cfg.timestep_s))
        return np.arange(n) * self.cfg.timestep_s


def _ramp(t, v):
    return v * np.minimum(1.0, t / _RAMP_S)


def torque_velocity(b: _Bench) -> tuple[dict, list]:
    vfull = 1.25 * bus_voltage_v(b.spec.circuit_for(True))
    lo, hi = stroke_limits_rad(b.circuit)
    # a compliant circuit (an accumulator on the line) takes longer to reach its stall
    # pressure: the run is lengthened until the last 40 % changes by under 1 %
    for stall_s in (0.4, 1.5, 4.0):
        t = b.t(stall_s)
        z = np.zeros_like(t)
        stall_log, _ = b.imposed(True, _ramp(t, vfull), z, z,
                                 f"torque_velocity.stall_{stall_s:g}s")
        tail = stall_log["torque_nm"][int(0.6 * t.size):]
        stall = -float(np.mean(tail))
        settled = abs(tail[-1] - tail[0]) <= 0.01 * max(abs(stall), 1e-9)
        if settled:
            break
    t = b.t(0.6)
    free = b.load(True, _ramp(t, vfull), "torque_velocity.free", stiffness=0.0, damping=0.0)
    th, w = free["angle_rad"], free["velocity_rad_s"]
    win = (t >= 0.1) & (np.minimum.accumulate(th) > 0.8 * lo)
    if np.count_nonzero(win) < 10:
        win = t >= 0.7 * t[-1]
    no_load = -float(np.mean(w[win]))
    speeds, torques = [], []
    for k in range(b.cfg.tv_points):
        v = -no_load * k / max(b.cfg.tv_points - 1, 1)
        th0 = 0.8 * hi
        t_hold = 0.15
        span = 0.8 * (hi - lo)
        dur = t_hold + 0.04 + (span / abs(v) if v != 0 else 0.2)
        tt = b.t(min(dur, 1.5))
        s = np.clip(tt - t_hold, 0.0, None)
        ta = 0.04
        vel = np.where(s < ta, 0.5 * v * (1 - np.cos(np.pi * s / ta)), v)
        ang = th0 + np.concatenate(([0.0], np.cumsum(vel[:-1]) * b.cfg.timestep_s))
        log, _ = b.imposed(True, _ramp(tt, vfull), ang, vel, f"torque_velocity.v{k}")
        sel = (s > ta + 0.05) & (ang > lo * 0.8)
        if not np.any(sel):
            sel = s > ta
        speeds.append(-math.degrees(v))
        torques.append(-float(np.mean(log["torque_nm"][sel])))
    summary = {"stall_torque_nm": stall, "stall_settled": bool(settled),
               "stall_run_s": stall_s, "no_load_speed_rad_s": no_load,
               "no_load_speed_deg_s": math.degrees(no_load), "full_voltage_v": vfull,
               "curve_speed_deg_s": speeds, "curve_torque_nm": torques}
    series = [{"x": np.array(speeds), "y": {"plantarflexion torque": np.array(torques)},
               "xlabel": "plantarflexion velocity [deg/s]", "ylabel": "torque [N·m]",
               "markers": True},
              {"x": t, "y": {"free angle [rad]": th, "free velocity [rad/s]": w},
               "xlabel": "time [s]", "ylabel": "free inertia"}]
    return summary, series


def isometric_steps(b: _Bench) -> tuple[dict, list]:
    t = b.t(b.cfg.step_duration_s)
    z = np.zeros_like(t)
    t_step = 0.05
    out, ys = {}, {}
    for tau in b.cfg.step_torques_nm:
        cmd = np.where(t >= t_step, -tau, 0.0)
        log, _ = b.imposed(False, cmd, z, z, f"isometric_steps.{tau:g}nm")
        m = step_metrics(log["time_s"], -log["torque_nm"], tau, t_step + b.cfg.timestep_s)
        out[f"{tau:g}nm"] = {k: m[k] for k in ("rise_time_s", "overshoot_pct",
                                               "settling_time_s", "steady_state_error",
                                               "final")}
        ys[f"{tau:g} N·m"] = -log["torque_nm"]
    head = out[f"{b.cfg.step_torques_nm[-1]:g}nm"]
    summary = {"steps": out, "rise_time_s": head["rise_time_s"],
               "overshoot_pct": head["overshoot_pct"],
               "steady_state_error_nm": head["steady_state_error"],
               "headline_step_nm": b.cfg.step_torques_nm[-1]}
    return summary, [{"x": t + b.cfg.timestep_s, "y": ys, "xlabel": "time [s]",
                      "ylabel": "plantarflexion torque [N·m]"}]


def frequency_response(b: _Bench) -> tuple[dict, list]:
    c = b.cfg

    def measure(f: float) -> dict:
        dur = max(8.0 / f, 0.25)
        t = b.t(dur)
        u = c.voltage_amplitude_v * np.sin(2 * np.pi * f * t)
        log = b.load(True, u, f"frequency_response.{f:.4g}hz")
        return sine_response(log["time_s"], u, -log["velocity_rad_s"], f, settle_cycles=3.0)

    freqs, results, refined = adaptive_log_sweep(measure, c.freq_min_hz, c.freq_max_hz,
                                                 n_coarse=c.freq_points,
                                                 n_refine=c.freq_refine_points)
    gains = np.array([r["gain"] for r in results])
    phases = [r["phase_deg"] for r in results]
    db = 20 * np.log10(gains / gains[0])
    # the peak: a parabola through the largest gain and its neighbours in (log f, dB)
    f_peak, _db_peak, inside = resonance_peak(freqs, gains)
    k = int(np.argmax(gains))
    summary = {"frequencies_hz": freqs.tolist(), "gain_rad_s_per_v": gains.tolist(),
               "gain_db": db.tolist(), "phase_deg": phases,
               "resonance_hz": float(f_peak), "resonance_peak_db": float(db[k]),
               "resonance_at_range_end": not inside, "n_frequencies": int(freqs.size),
               "refined": refined,
               "output": "plantarflexion velocity per motor volt (open loop)"}
    return summary, [{"x": freqs, "y": {"gain [dB]": db}, "xlabel": "frequency [Hz]",
                      "ylabel": "−θ̇ / V gain [dB re lowest]", "log_x": True,
                      "markers": True},
                     {"x": freqs, "y": {"phase [deg]": np.array(phases)},
                      "xlabel": "frequency [Hz]", "ylabel": "phase [deg]", "log_x": True,
                      "markers": True}]


def position_step(b: _Bench) -> tuple[dict, list]:
    """The closed position loop on the inertia, stepped with the coupled protocol (implicit
    in the device's damping, as MuJoCo integrates it)."""
    c = b.cfg
    h = c.timestep_s
    ref = c.position_step_rad
    t_step = 0.05

    def law(t, q, v):
        r = ref if t >= t_step else 0.0
        return float(np.clip(c.position_kp_nm_rad * (r - q) - c.position_kd_nm_s_rad * v,
                             -c.torque_limit_nm, c.torque_limit_nm))

    n = int(round(c.position_duration_s / h))
    dev = b._dev(torque_fn=law, max_steps=n)
    th = np.zeros(2)
    w = np.zeros(2)
    stance = np.zeros(2, dtype=bool)
    J, K, cd = c.load_inertia_kg_m2, c.load_stiffness_nm_rad, c.load_damping_nm_s_rad
    angle = np.zeros(n)
    for i in range(n):
        force, damping = dev.begin_step(i * h, th, w, stance)
        # semi-implicit Euler with the device's damping and the load's taken implicitly
        acc_free = (force[0] - K * th[0]) / J
        wn = (w[0] + h * acc_free) / (1.0 + h * (damping[0] + cd) / J)
        dev.end_step(np.array([wn, 0.0]))
        w[0] = wn
        th[0] += h * wn
        angle[i] = th[0]
    b._close(dev, "position_step")
    time = (np.arange(n) + 1) * h
    m = step_metrics(time, -angle, -ref, t_step)
    L = dev.log.arrays()
    summary = {"step_rad": ref, "rise_time_s": m["rise_time_s"],
               "overshoot_pct": m["overshoot_pct"], "settling_time_s": m["settling_time_s"],
               "steady_state_error_rad": -m["steady_state_error"],
               "gains": {"kp_nm_rad": c.position_kp_nm_rad,
                         "kd_nm_s_rad": c.position_kd_nm_s_rad}}
    return summary, [{"x": time, "y": {"angle [rad]": angle,
                                       "reference [rad]": np.where(time >= t_step, ref, 0.0)},
                      "xlabel": "time [s]", "ylabel": "ankle angle [rad]"},
                     {"x": L["time_s"][:, 0], "y": {
                         "commanded": L["commanded_torque_nm"][:, 0],
                         "delivered": L["delivered_torque_nm"][:, 0]},
                      "xlabel": "time [s]", "ylabel": "torque [N·m]"}]


def stiffness(b: _Bench) -> tuple[dict, list]:
    c = b.cfg
    f, amp = c.stiffness_frequency_hz, c.stiffness_amplitude_rad
    t = b.t(3.0 / f)
    ang = amp * np.sin(2 * np.pi * f * t)
    vel = amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    rest = -amp
    out, ys = {}, {}
    keep = t >= 1.0 / f
    for k in c.stiffnesses_nm_rad:
        cmd = -k * (ang - rest)
        log, _ = b.imposed(False, cmd, ang, vel, f"stiffness.k{k:g}")
        slope = float(np.polyfit(ang[keep], log["torque_nm"][keep], 1)[0])
        out[f"k{k:g}"] = {"commanded_nm_rad": k, "emulated_nm_rad": -slope,
                          "error_rel": (-slope - k) / k,
                          "peak_torque_nm": float(np.max(np.abs(log["torque_nm"])))}
        ys[f"K = {k:g} N·m/rad"] = log["torque_nm"][keep]
    worst = max(abs(v["error_rel"]) for v in out.values())
    return ({"stiffness": out, "worst_error_rel": worst, "amplitude_rad": amp,
             "frequency_hz": f, "rest_angle_rad": rest},
            [{"x": ang[keep], "y": ys, "xlabel": "ankle angle [rad]",
              "ylabel": "delivered torque [N·m]"}])


def tracking(b: _Bench) -> tuple[dict, list]:
    from afo_mj.control import assistance as asst
    c = b.cfg
    f, amp = c.tracking_frequency_hz, c.tracking_amplitude_rad
    t = b.t(c.tracking_cycles / f)
    ang = amp * np.sin(2 * np.pi * f * t)
    vel = amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    prof = asst.zhang_profile(c.tracking_peak_torque_nm, 52.9, 26.2, 9.8)
    phase = (t * f) % 1.0
    cmd = np.interp(phase, np.linspace(0.0, 1.0, len(prof)), prof)
    log, led = b.imposed(False, cmd, ang, vel, "tracking")
    keep = t >= 1.0 / f
    err = log["torque_nm"][keep] - cmd[keep]
    # the first cycle alone, on a fresh device: its ledger is the whole run's at 1 / f
    # (module docstring), so the difference is the ledger of the measured cycles
    n1 = int(np.count_nonzero(~keep))
    dev1 = b._dev()
    dev1.run_imposed(cmd[:n1], ang[:n1], vel[:n1])
    led0 = dev1.ledger()
    ncm = c.tracking_cycles - 1

    def per(key):
        return None if key not in led else float(led[key] - led0[key]) / ncm

    drawn = per("electrical_drawn_j") if "electrical_drawn_j" in led else per("input_drawn_j")
    mech, hyd = per("mechanical_out_j"), per("hydraulic_j")
    return ({"rmse_nm": float(np.sqrt(np.mean(err ** 2))),
             "peak_commanded_nm": float(np.max(np.abs(cmd))),
             "peak_delivered_nm": float(np.max(np.abs(log["torque_nm"][keep]))),
             "amplitude_rad": amp, "frequency_hz": f, "cycles_measured": ncm,
             "electrical_j_per_cycle": drawn,
             "electrical_net_j_per_cycle": per("input_j"),
             "mechanical_j_per_cycle": mech, "hydraulic_j_per_cycle": hyd,
             "losses_j_per_cycle": {k: float(v - led0["losses_j"][k]) / ncm
                                    for k, v in led["losses_j"].items()},
             "stored_change_j_per_cycle": {k: float(v - led0["stored_change_j"][k]) / ncm
                                           for k, v in led["stored_change_j"].items()},
             "efficiency_mechanical": mech / drawn if drawn > 0 else math.nan,
             "efficiency_hydraulic": (hyd / drawn if hyd is not None and drawn > 0
                                      else math.nan)},
            [{"x": t[keep], "y": {"commanded": cmd[keep], "delivered": log["torque_nm"][keep]},
              "xlabel": "time [s]", "ylabel": "torque [N·m] (+ dorsiflexion)"},
             {"x": t[keep], "y": {"imposed angle": ang[keep]}, "xlabel": "time [s]",
              "ylabel": "ankle angle [rad]"}])


def flow_vs_duty(b: _Bench) -> tuple[dict, list]:
    c = b.cfg
    cc = b._dev().cc
    ctrl = cc.circuit.controller
    # the controller's valve_command_on switch: the command is the metering fraction itself
    open_slot = cc.param_labels.index("controller.valve_command_on")
    f = ctrl.params.pwm_frequency_hz
    h = c.timestep_s
    spp = 1.0 / (f * h)
    if abs(spp - round(spp)) > 1e-6:
        raise ProtocolError(f"bench.timestep_s = {h!r} does not divide the PWM period "
                                f"{1.0 / f!r} s; allowed: a step with period / step an "
                                "integer")
    spp = int(round(spp))
    act = joint_actuator(cc.circuit)
    k_tau = act.torque_per_pa()
    lo, hi = stroke_limits_rad(cc.circuit)
    theta0 = 0.8 * hi
    # the pump's displacement per radian as the kernel reads it, and its shaft's state
    pump = ctrl.refs["pump"]
    d = float(cc.P[cc.param_labels.index(f"{pump}.d")])
    shaft = [n for n in cc.state_names if n == "shaft" or n.endswith(".shaft")]
    spin = b.t(0.15)
    # a constant dorsiflexion torque holds the actuator's line at the bias pressure, so that
    # the open switching valve, not the actuator, takes the pump's flow
    bias = np.full(int(round(c.flow_max_duration_s / h)), c.flow_bias_pressure_pa * k_tau)
    rows = {k: [] for k in ("duty", "delivered_flow_m3_s", "pump_flow_m3_s",
                            "flow_fraction", "periods")}
    traces = {}
    for u in c.duties:
        dev = b._dev()
        dev.P[:, open_slot] = 1.0
        dev.run_imposed(np.zeros_like(spin), np.full(spin.size, theta0), np.zeros_like(spin))
        n = int(round(c.flow_max_duration_s / h))
        log = dev.run_load(np.full(n, float(u)), c.flow_inertia_kg_m2, 0.0,
                           c.flow_damping_nm_s_rad, theta0_rad=theta0,
                           external_torque_nm=bias)
        b._close(dev, f"flow_vs_duty.u{u:g}")
        th, w = log["angle_rad"], log["velocity_rad_s"]
        past = np.flatnonzero(th < 0.8 * lo)
        end = past[0] if past.size else th.size
        periods = (end - spp) // spp
        if periods < 1:
            raise ProtocolError(
                f"flow_vs_duty: at duty {u:g} the ankle crosses 80 % of the stroke within "
                f"{(end * h):.3g} s, less than two PWM periods ({2.0 / f:.3g} s); allowed: a "
                "load that slows it (bench.load_damping_nm_s_rad, load_stiffness_nm_rad)")
        sel = slice(spp, spp + periods * spp)
        q = -k_tau * float(np.mean(w[sel]))
        qp = d * float(np.mean(log[shaft[0]][sel])) if shaft else float("nan")
        rows["duty"].append(float(u))
        rows["delivered_flow_m3_s"].append(q)
        rows["pump_flow_m3_s"].append(qp)
        rows["flow_fraction"].append(q / qp if qp > 0 else float("nan"))
        rows["periods"].append(int(periods))
        traces[f"u = {u:g}"] = th[:end]
    x = np.array(rows["duty"])
    y = np.array(rows["flow_fraction"])
    ok = np.isfinite(y)
    if np.count_nonzero(ok) >= 2:
        a, b0 = np.polyfit(x[ok], y[ok], 1)
        fit = a * x[ok] + b0
        ss = float(np.sum((y[ok] - np.mean(y[ok])) ** 2))
        r2 = 1.0 - float(np.sum((y[ok] - fit) ** 2)) / ss if ss > 0 else 1.0
    else:
        a = b0 = r2 = float("nan")
    summary = dict(rows, pwm_frequency_hz=f, fit_slope=float(a), fit_offset=float(b0),
                   fit_r2=float(r2), torque_per_pa_m3_rad=k_tau,
                   start_angle_rad=theta0)
    q_ml = np.array(rows["delivered_flow_m3_s"]) * 6e7
    return summary, [{"x": x, "y": {"delivered flow [L/min]": q_ml / 1000.0},
                      "xlabel": "PWM duty (metering fraction)", "ylabel": "flow [L/min]",
                      "markers": True},
                     {"x": x, "y": {"Q / (d ω)": y}, "xlabel": "PWM duty (metering fraction)",
                      "ylabel": "delivered / pump flow", "markers": True}]


_RUNNERS = {"torque_velocity": torque_velocity, "isometric_steps": isometric_steps,
            "frequency_response": frequency_response, "position_step": position_step,
            "stiffness": stiffness, "tracking": tracking, "flow_vs_duty": flow_vs_duty}


def run_load_bench(spec: DeviceSpec, protocols=LOAD_DEFAULT_PROTOCOLS,
                   cfg: LoadBenchConfig = LoadBenchConfig()) -> tuple[dict, dict]:
    """Run ``protocols`` on device ``spec`` against the simulated load; returns ``(summary,
    series)``: summary ``{protocol: figures, "ledger": {run: …}, "energy": {...}}``, series
    ``{protocol: [panels]}`` (:func:`afo_mj.outputs.circuit_figures.plot_circuit_bench`).
    A protocol the device cannot run is refused first (:class:`ProtocolError` naming the
    protocol, the device and what it lacks)."""
    if not isinstance(spec, DeviceSpec):
        raise BenchError(f"spec = {type(spec).__name__}; allowed: a DeviceSpec")
    if isinstance(protocols, str):
        protocols = (protocols,)
    protocols = tuple(protocols)
    if not protocols:
        raise BenchError("protocols = []; allowed: a non-empty subset of "
                         + ", ".join(RIG_PROTOCOLS["load"]))
    check_protocols(spec, protocols, "load")
    b = _Bench(spec, cfg)
    summary, series = {}, {}
    for test in protocols:
        summary[test], series[test] = _RUNNERS[test](b)
    worst = max((abs(v["balance_error_rel"]) for v in b.ledgers.values()), default=0.0)
    summary["ledger"] = b.ledgers
    summary["energy"] = {"balance_error_rel": worst,
                         "ledger_closed": bool(worst <= LEDGER_TOLERANCE),
                         "tolerance": LEDGER_TOLERANCE,
                         "newton_unconverged_steps": sum(
                             v["newton_unconverged_steps"] for v in b.ledgers.values()),
                         "battery_overload_steps": sum(
                             v["battery_overload_steps"] for v in b.ledgers.values()),
                         "note": "largest |ledger residual| / energy throughput over every "
                                 "bench run (ledger.<run>.balance_error_rel)"}
    return summary, series
