"""Bench tests of the valve-controlled and digital-valve orthoses on the ankle test stand.

Two tests (seed ch. 4–5), each on a fresh :class:`~afo_mj.human.test_stand.AnkleTestStand` and
:class:`~afo_mj.devices.valve_afo.ValveAfoDevice` per run (``stand.run_device``):

* :func:`digital_flow_vs_duty` — the digital (PWM on/off) circuit open loop
  (``mode="valve_command"``): a constant duty ``D`` (the fraction of each PWM period the
  switching valve is shut, so the pump's flow goes to the load) drives the free foot against
  a load; the mean flow into chamber A over whole PWM periods against ``D``, next to the ideal
  ``D · Q_pump``, with the switching valve's throttling loss and the valves' actuator energy.
* :func:`tracking_efficiency` — one closed-loop torque task for several presets (default the
  proportional servo valve ``valve`` and the ``digital`` valve): tracking error, electrical
  energy per cycle, named losses per cycle and the efficiencies, so the digital valve is
  compared with the proportional one on the same task.

Sign conventions as the stand and device: angle, velocity and torque positive in
dorsiflexion; plantarflexion assistance is negative torque. Chamber A drives plantarflexion:
its volume grows by ``A_e r`` per radian of plantarflexion.

Flow vs duty: load and measurement
----------------------------------
The foot starts at rest dorsiflexed (``start_angle_rad``, default +0.45 rad inside the
±0.56 rad cylinder stroke) and plantarflexes against

* a nearly constant opposing torque: a weak torsional spring relaxed at +π rad (past the
  stroke) of stiffness ``k = p_bias r A_e / π``, so that the load pressure at neutral is
  ``p_bias`` (``bias_pressure_pa``, default 0.5 MPa) and varies by ±14 % over ±0.45 rad; the
  foot's own weight (≈ 0.3–0.6 N·m plantarflexing, ≈ 0.05–0.09 MPa) lowers it a little;
* plus viscous joint damping ``c`` (``damping_nm_s_per_rad``, default 2 N·m·s/rad: at the
  full pump flow ≈ 9.7 N·m, 1.5 MPa), which damps the oil-spring/foot oscillation that each
  PWM pulse excites.

Why this load: the measured flow must be what the pump delivers through the switching valve.
A purely viscous load lets the foot coast during the valve's open phase and suck chamber A
below the tank (the make-up valve then feeds it from the tank: with ``c`` = 1–3 N·m·s/rad and
no bias, chamber A fell 0.1–0.6 MPa below the tank every period), and a load pressure close to zero
lets the pump flow on into the load while the switching valve is open (the open valve itself
drops ``Δp_open = (Q_p/(C_d A √(2/ρ)))²`` ≈ 0.3 MPa at 1.9 L/min). With the defaults chamber
A stays within 5 kPa of the tank pressure or above it through every period (reported:
``chamber_a_min_above_tank_pa``; the make-up flow, also reported, is zero), the mean load
pressure is 0.4–2 MPa ("small": a fifth of the 11 MPa rail of the servo presets) and the
result changes by < 0.01 of ``Q_p`` between 1 ms and 0.1 ms steps (for ``D`` ≥ 0.2).

Measured per duty after ``settle_periods`` PWM periods, over ``n`` whole periods (as many as
the stroke allows down to ``end_angle_rad``, at most ``max_periods``), with ``T_w = n / f``:

* delivered flow ``Q = A_e r (θ(t_0) − θ(t_1)) / T_w`` (chamber A's volume change; the oil
  compression over whole periods of a periodic state averages out);
* pump flow ``Q_p`` = the ledger's pumped volume over ``T_w`` (``d ω − slip``);
* ideal flow ``D Q_p``; fraction ``Q / Q_p``; ratio ``Q / (D Q_p)``;
* check-valve flow (pump → rail, the flow the switching valve passes to the load) and make-up
  flow from the tank into port A, integrated from the device state after every step with the
  kernel's valve laws (diagnostics: the make-up flow should be ≈ 0);
* switching-valve throttling loss (mean W and J per period), the valves' actuator (coil)
  energy (mean W and J per period), electrical power drawn, mechanical power to the load,
  mean load pressure ``p_A − p_B`` and the lowest chamber-A pressure above the tank.

Why the flow falls short of ``D Q_p`` (what sets the tolerance): the valve travels at its
limited rate, ``T_sw`` (2 ms) each way, ``T_sw f`` = 0.1 of a 50 Hz period, so it is fully shut
for only ``D − T_sw f`` of each period and travelling for ``2 T_sw f``. While it travels the
pump's flow splits between the valve and the load: the load gets flow only while the valve's
opening is below ``x* = √(Δp_open / p_on)``, ``p_on`` the pump pressure above the tank while
it delivers (the load plus the drops across the check valve, the digital circuit's open P→A
edge — ≈ 0.8 MPa at the pump flow — and the hose, plus the pressure peak of each pulse:
3.3–4.2 MPa with the default load). Closing, the load starts to get flow at ``x*``, opening it
stops at ``x*``: per period the load gets ``(D − T_sw f) + 2 x* T_sw f`` of the pump flow, i.e.

    Q / Q_p ≈ D − (1 − 2 x*) T_sw f        (``predicted_fraction``; our arithmetic)

an offset independent of ``D`` (≈ −0.045 here), within ``±T_sw f`` whatever the load. On top
of it, late in the open phase the decaying load pressure can fall below ``Δp_open`` and the
pump then feeds the load through the open valve (+0 … 0.03). Compressing the pump node's
0.3 cm³ costs < 0.1 %. A duty at or below ``T_sw f`` never shuts the valve.

Tracking task and efficiency
----------------------------
``task="gait"`` (default): the Zhang et al. (2017) profile (``peak_torque_nm`` 40 N·m at
52.9 % of the stride, 26.2 % rise, 9.8 % fall) commanded against time with a stride of
``stride_s`` = 1.1 s, the ankle imposed on Winter's normal-cadence ankle angle replayed at the
same stride (:func:`afo_mj.gait.reference.load_normative`): push-off plantarflexion under the
peak torque, so the device does net positive work. ``task="sine"``: the ankle imposed on
``θ = A sin 2πft`` and the command ``τ = −(T/2)(1 − cos 2πft)`` (0 → −T), which peaks while the
ankle plantarflexes fastest: net positive work ``π A T/2`` per cycle (15.7 J at A = 0.25 rad,
T = 40 N·m).

Over the cycles after the first ``skip_cycles`` (start-up):

* tracking RMSE ``√mean((τ − τ_cmd)²)`` of the delivered (end-of-step) torque and its peak
  error, also as % of the peak command;
* per cycle: electrical energy drawn from the battery, net mechanical work of the device on
  the ankle, its positive part, pump hydraulic output ``∫ Δp_pump Q_pump``, each named loss,
  the change of the stores;
* ``efficiency_mechanical`` = net mechanical work / electrical energy drawn;
  ``efficiency_hydraulic`` = pump hydraulic output / electrical energy drawn.
"""

from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

import numpy as np

from afo_mj.control.assistance import table_lookup, zhang_profile
from afo_mj.devices.valve_afo import VALVE_PRESETS, ValveAfoDevice, ValveAnkleParams
from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad

__all__ = ["BenchError", "digital_flow_vs_duty", "tracking_efficiency", "flow_table",
           "tracking_table", "TRACKING_TASKS"]

#: Tasks accepted by :func:`tracking_efficiency`.
TRACKING_TASKS = ("gait", "sine")
#: Zhang et al. (2017) profile timing (% of stride): peak, rise, fall.
ZHANG_TIMING_PCT = (52.9, 26.2, 9.8)


class BenchError(ValueError):
    """A bench argument outside what the test allows."""


# -- argument checks ------------------------------------------------------------------------
def _num(name: str, value, lo: float = -math.inf, hi: float = math.inf,
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


def _params(params, circuit: str | None = None) -> ValveAnkleParams:
    if isinstance(params, str):
        if params not in VALVE_PRESETS:
            raise BenchError(f"preset = {params!r}; allowed: {', '.join(VALVE_PRESETS)}")
        params = VALVE_PRESETS[params]
    if not isinstance(params, ValveAnkleParams):
        raise BenchError(f"params = {type(params).__name__}; allowed: a ValveAnkleParams "
                         "(afo_mj.devices.valve_afo.VALVE_PRESETS[...] or valve_params(...)) "
                         "or a preset name")
    if circuit is not None and params.circuit != circuit:
        raise BenchError(f"params.circuit = {params.circuit!r}; allowed: {circuit!r}")
    return params


def _stand_kw(body_mass_kg, height_m, timestep_s) -> dict:
    return {"body_mass_kg": _num("body_mass_kg", body_mass_kg, 20.0, 200.0),
            "height_m": _num("height_m", height_m, 1.0, 2.3),
            "timestep_s": _num("timestep_s", timestep_s, 1e-5, 1e-3)}


def _energy_error(led: Mapping) -> float:
    return abs(float(led["balance_error_rel"]))


# -- flow vs duty -----------------------------------------------------------------------------
def digital_flow_vs_duty(params=VALVE_PRESETS["digital"],
                         duties: Sequence[float] = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0),
                         *, bias_pressure_pa: float = 0.5e6, damping_nm_s_per_rad: float = 2.0,
                         start_angle_rad: float = 0.45, end_angle_rad: float = -0.45,
                         settle_periods: int = 2, max_periods: int = 10,
                         body_mass_kg: float = 75.0, height_m: float = 1.75,
                         timestep_s: float = 2.5e-4) -> dict:
    """Mean flow into chamber A against PWM duty, open loop (module docstring).

    ``params``: a digital-circuit :class:`ValveAnkleParams` (or preset name). ``duties``: the
    fraction of each PWM period the switching valve is shut, each in (0, 1]. The step
    ``timestep_s`` must divide the PWM period (default 0.25 ms: 8 steps per 2 ms valve
    travel). Returns a dict of arrays (one entry per duty): ``duty``,
    ``delivered_flow_m3_s``, ``pump_flow_m3_s``, ``ideal_flow_m3_s`` (``D Q_p``),
    ``flow_fraction`` (``Q/Q_p``), ``ratio_to_ideal``, ``check_valve_flow_m3_s``,
    ``makeup_flow_m3_s``, ``switching_valve_loss_w``, ``switching_valve_loss_j_per_period``,
    ``valve_actuator_power_w``, ``valve_actuator_j_per_period``, ``electrical_power_w``,
    ``electrical_j_per_period``, ``mechanical_power_w``, ``load_pressure_mean_pa``,
    ``chamber_a_min_above_tank_pa``, ``pump_pressure_on_pa`` (mean pump pressure above the
    tank while the switching valve is shut), ``opening_x_star``, ``predicted_fraction``
    (``D − (1 − 2x*) T_sw f``), ``periods``, ``energy_error``; and scalars
    ``energy_error_max``, ``pwm_frequency_hz``, ``switching_time_s``,
    ``nominal_pump_flow_m3_s``, ``load`` (dict of the load's numbers) and
    ``open_valve_dp_pa`` (``Δp_open`` at the nominal pump flow).
    """
    p = _params(params, "digital")
    kw = _stand_kw(body_mass_kg, height_m, timestep_s)
    h = kw["timestep_s"]
    try:
        ds = tuple(float(d) for d in duties)
    except (TypeError, ValueError):
        raise BenchError(f"duties = {duties!r} is not a sequence of numbers") from None
    if not ds:
        raise BenchError("duties is empty; allowed: at least one duty in (0, 1]")
    ds = tuple(_num(f"duties[{i}]", d, 0.0, 1.0, lo_open=True) for i, d in enumerate(ds))
    p_bias = _num("bias_pressure_pa", bias_pressure_pa, 0.0, 10e6)
    c = _num("damping_nm_s_per_rad", damping_nm_s_per_rad, 0.0, 100.0)
    q0 = _num("start_angle_rad", start_angle_rad, -0.5, 0.5)
    q1 = _num("end_angle_rad", end_angle_rad, -0.5, q0 - 0.1)
    n_settle = int(_num("settle_periods", settle_periods, 0, 100))
    n_max = int(_num("max_periods", max_periods, 1, 1000))
    f = p.pwm_frequency_hz
    period = 1.0 / f
    spp = period / h
    if abs(spp - round(spp)) > 1e-6:
        raise BenchError(f"timestep_s = {h!r} does not divide the PWM period {period!r} s; "
                         "allowed: period / timestep_s an integer")
    spp = int(round(spp))
    r, ae = p.pulley_radius_m, p.effective_area_m2
    q_nom = p.nominal_pump_flow_m3_s
    k_spring = p_bias * r * ae / math.pi
    keys = ("delivered_flow_m3_s", "pump_flow_m3_s", "ideal_flow_m3_s", "flow_fraction",
            "ratio_to_ideal", "check_valve_flow_m3_s", "makeup_flow_m3_s",
            "switching_valve_loss_w", "switching_valve_loss_j_per_period",
            "valve_actuator_power_w", "valve_actuator_j_per_period", "electrical_power_w",
            "electrical_j_per_period", "mechanical_power_w", "load_pressure_mean_pa",
            "chamber_a_min_above_tank_pa", "pump_pressure_on_pa", "opening_x_star",
            "predicted_fraction", "periods", "energy_error")
    out = {k: [] for k in keys}
    sw_name = "switching_valve"
    sw = p.switching_valve
    k_or = sw.discharge_coefficient * sw.max_area_m2 * math.sqrt(2.0 / p.fluid.density_kg_m3)
    tsw_f = sw.switching_time_s * f
    for d in ds:
        stand = AnkleTestStand(
            body_mass_kg=kw["body_mass_kg"], height_m=kw["height_m"], timestep_s=h,
            load=StandLoad(kind="spring", spring_stiffness_nm_per_rad=k_spring,
                           spring_rest_angle_rad=math.pi, joint_damping_nm_s_per_rad=c),
            initial_angle_rad=q0)
        # travel per period at the ideal flow, with a margin for the settling
        per_period = d * q_nom * period / (r * ae)
        n_total = n_settle + n_max
        dev = ValveAfoDevice(p, mode="valve_command", torque_fn=(lambda u: lambda t, q, w: u)(d),
                             timestep_s=h, max_steps=n_total * spp + 2)
        if n_settle:
            stand.run_device(dev, n_settle * period)
        led0 = dev.ledger()
        k0 = dev.steps
        room = stand.angle_rad - q1
        n = max(1, min(n_max, int(room / (1.15 * per_period)))) if room > 0 else 1
        r2 = stand.run_device(dev, n * period)
        led1 = dev.ledger()
        tw = n * period
        dq = float(r2.angle_rad[0] - stand.angle_rad)
        q_del = ae * r * dq / tw
        q_p = (led1["pump_volume_m3"] - led0["pump_volume_m3"]) / tw
        log = {key: v[k0:dev.steps, 0] for key, v in dev.log.arrays().items()}
        q_cv, q_ma = log["check.flow_m3_s"], log["makeup_a.flow_m3_s"]
        pca, pcb = log["chamber_a_pa"], log["chamber_b_pa"]

        def de(key, sub=None):
            if sub is None:
                return float(led1[key] - led0[key])
            return float(led1[key][sub] - led0[key][sub])

        out["delivered_flow_m3_s"].append(q_del)
        out["pump_flow_m3_s"].append(q_p)
        out["ideal_flow_m3_s"].append(d * q_p)
        out["flow_fraction"].append(q_del / q_p)
        out["ratio_to_ideal"].append(q_del / (d * q_p))
        out["check_valve_flow_m3_s"].append(float(np.mean(q_cv)))
        out["makeup_flow_m3_s"].append(float(np.mean(q_ma)))
        out["switching_valve_loss_w"].append(de("losses_j", sw_name) / tw)
        out["switching_valve_loss_j_per_period"].append(de("losses_j", sw_name) / n)
        out["valve_actuator_power_w"].append(de("losses_j", "valve_actuators") / tw)
        out["valve_actuator_j_per_period"].append(de("losses_j", "valve_actuators") / n)
        out["electrical_power_w"].append(de("electrical_drawn_j") / tw)
        out["electrical_j_per_period"].append(de("electrical_drawn_j") / n)
        out["mechanical_power_w"].append(de("mechanical_out_j") / tw)
        out["load_pressure_mean_pa"].append(float(np.mean(pca - pcb)))
        out["chamber_a_min_above_tank_pa"].append(float(np.min(pca)) - p.reservoir_pressure_pa)
        # pump pressure above the tank while the switching valve is shut, and the predicted
        # fraction D − (1 − 2 x*) T_sw f (module docstring)
        shut = log["unloading_valve_position"] <= 0.01
        p_on = (float(np.mean(log["pump_pa"][shut])) - p.reservoir_pressure_pa
                if np.any(shut) else math.nan)
        dp_open = (q_p / k_or) ** 2
        x_star = min(1.0, math.sqrt(dp_open / p_on)) if p_on > 0 else 1.0
        out["pump_pressure_on_pa"].append(p_on)
        out["opening_x_star"].append(x_star)
        if d >= 1.0:
            pred = 1.0
        elif np.any(shut):
            pred = d - (1.0 - 2.0 * x_star) * tsw_f
        else:
            pred = math.nan            # D <= T_sw f: the valve never shuts
        out["predicted_fraction"].append(pred)
        out["periods"].append(n)
        out["energy_error"].append(_energy_error(led1))
    res = {k: np.asarray(v, dtype=float) for k, v in out.items()}
    res["periods"] = res["periods"].astype(int)
    res["duty"] = np.asarray(ds)
    res["energy_error_max"] = float(np.max(res["energy_error"]))
    res["pwm_frequency_hz"] = f
    res["switching_time_s"] = p.switching_valve.switching_time_s
    res["nominal_pump_flow_m3_s"] = q_nom
    res["open_valve_dp_pa"] = (q_nom / k_or) ** 2
    res["load"] = {"spring_stiffness_nm_per_rad": k_spring, "spring_rest_angle_rad": math.pi,
                   "bias_pressure_pa": p_bias, "damping_nm_s_per_rad": c,
                   "start_angle_rad": q0, "end_angle_rad": q1}
    return res


# -- tracking and efficiency ------------------------------------------------------------------
def _gait_task(stride_s: float, peak_nm: float) -> tuple[ImposedTrajectory, Callable]:
    from afo_mj.gait.reference import load_normative

    gait = load_normative("winter", "normal")

    def phase(t):
        return (t / stride_s) % 1.0

    traj = ImposedTrajectory(
        lambda t: float(gait.channel("ankle_angle_rad", phase(t))),
        lambda t: float(gait.velocities_rad_s(phase(t), stride_s)[2]),
        lambda t: float(gait.accelerations_rad_s2(phase(t), stride_s)[2]))
    table = zhang_profile(peak_nm, *ZHANG_TIMING_PCT)

    def cmd(t, q, w):
        return float(table_lookup(table, phase(t)))

    return traj, cmd


def _sine_task(freq_hz: float, amp_rad: float, peak_nm: float) -> tuple[ImposedTrajectory,
                                                                         Callable]:
    w = 2 * math.pi * freq_hz
    traj = ImposedTrajectory.sinusoid(amp_rad, freq_hz)

    def cmd(t, q, v):
        return -0.5 * peak_nm * (1.0 - math.cos(w * t))

    return traj, cmd


def tracking_efficiency(preset_names: Sequence = ("valve", "digital"), *, task: str = "gait",
                        peak_torque_nm: float = 40.0, stride_s: float = 1.1,
                        frequency_hz: float = 1.0, amplitude_rad: float = 0.25,
                        cycles: int = 4, skip_cycles: int = 1, body_mass_kg: float = 75.0,
                        height_m: float = 1.75, timestep_s: float = 1e-3) -> dict:
    """The same closed-loop torque task for each preset (module docstring).

    ``preset_names``: preset names of :data:`VALVE_PRESETS` (or ``(label, params)`` pairs).
    Returns ``{label: result}``, each result with ``tracking_rmse_nm``,
    ``tracking_rmse_pct_peak``, ``peak_error_nm``, ``peak_torque_delivered_nm``,
    ``electrical_j_per_cycle`` (drawn), ``electrical_net_j_per_cycle``,
    ``mechanical_j_per_cycle`` (net, device on ankle), ``positive_mechanical_j_per_cycle``,
    ``hydraulic_j_per_cycle`` (pump output), ``efficiency_mechanical``,
    ``efficiency_hydraulic``, ``losses_j_per_cycle`` (named), ``stored_change_j_per_cycle``,
    ``energy_error``, ``peak_pressure_pa``, ``cycle_s``, ``cycles_measured``, ``task``.
    """
    if task not in TRACKING_TASKS:
        raise BenchError(f"task = {task!r}; allowed: {', '.join(TRACKING_TASKS)}")
    kw = _stand_kw(body_mass_kg, height_m, timestep_s)
    h = kw["timestep_s"]
    peak = _num("peak_torque_nm", peak_torque_nm, 0.0, 90.0, lo_open=True)
    n_cyc = int(_num("cycles", cycles, 2, 50))
    n_skip = int(_num("skip_cycles", skip_cycles, 0, n_cyc - 1))
    if task == "gait":
        period = _num("stride_s", stride_s, 0.5, 3.0)
    else:
        period = 1.0 / _num("frequency_hz", frequency_hz, 0.1, 5.0)
        amp = _num("amplitude_rad", amplitude_rad, 0.0, 0.5, lo_open=True)
    entries = []
    for item in preset_names:
        if isinstance(item, str):
            entries.append((item, _params(item)))
        else:
            try:
                label, prm = item
            except (TypeError, ValueError):
                raise BenchError(f"preset_names item {item!r}; allowed: a preset name or a "
                                 "(label, ValveAnkleParams) pair") from None
            entries.append((str(label), _params(prm)))
    if not entries:
        raise BenchError("preset_names is empty; allowed: at least one preset")
    results = {}
    for label, prm in entries:
        traj, cmd = (_gait_task(period, peak) if task == "gait"
                     else _sine_task(1.0 / period, amp, peak))
        stand = AnkleTestStand(body_mass_kg=kw["body_mass_kg"], height_m=kw["height_m"],
                               timestep_s=h, load=StandLoad(kind="imposed", trajectory=traj))
        steps_total = int(round(n_cyc * period / h))
        dev = ValveAfoDevice(prm, torque_fn=cmd, timestep_s=h, max_steps=steps_total + 2)
        led0 = None
        k0 = 0
        if n_skip:
            stand.run_device(dev, n_skip * period)
        led0 = dev.ledger()
        k0 = dev.steps
        stand.run_device(dev, (n_cyc - n_skip) * period)
        led1 = dev.ledger()
        k1 = dev.steps
        ncm = n_cyc - n_skip
        log = dev.log.arrays()
        tau = log["delivered_torque_nm"][k0:k1, 0]
        tcmd = log["commanded_torque_nm"][k0:k1, 0]
        pmech = log["mechanical_power_w"][k0:k1, 0]
        err = tau - tcmd
        rmse = float(np.sqrt(np.mean(err * err)))
        e_drawn = float(led1["electrical_drawn_j"] - led0["electrical_drawn_j"]) / ncm
        e_net = float(led1["electrical_in_j"] - led0["electrical_in_j"]) / ncm
        e_mech = float(led1["mechanical_out_j"] - led0["mechanical_out_j"]) / ncm
        e_hyd = float(led1["hydraulic_j"] - led0["hydraulic_j"]) / ncm
        losses = {k: float(led1["losses_j"][k] - led0["losses_j"][k]) / ncm
                  for k in led1["losses_j"]}
        stores = {k: float(led1["stored_change_j"][k] - led0["stored_change_j"][k]) / ncm
                  for k in led1["stored_change_j"]}
        results[label] = {
            "task": task, "circuit": prm.circuit, "supply_mode": prm.supply_mode,
            "cycle_s": period, "cycles_measured": ncm,
            "tracking_rmse_nm": rmse, "tracking_rmse_pct_peak": 100.0 * rmse / peak,
            "peak_error_nm": float(np.max(np.abs(err))),
            "peak_torque_delivered_nm": float(-np.min(tau)),
            "electrical_j_per_cycle": e_drawn, "electrical_net_j_per_cycle": e_net,
            "mechanical_j_per_cycle": e_mech,
            "positive_mechanical_j_per_cycle": float(np.sum(np.maximum(pmech, 0.0)) * h) / ncm,
            "hydraulic_j_per_cycle": e_hyd,
            "efficiency_mechanical": e_mech / e_drawn if e_drawn > 0 else math.nan,
            "efficiency_hydraulic": e_hyd / e_drawn if e_drawn > 0 else math.nan,
            "losses_j_per_cycle": losses, "stored_change_j_per_cycle": stores,
            "energy_error": _energy_error(led1),
            "peak_pressure_pa": float(led1["peak_pressure_pa"]),
        }
    return results


# -- text tables --------------------------------------------------------------------------------
def flow_table(res: Mapping) -> str:
    """A markdown table of :func:`digital_flow_vs_duty`'s result (flows in L/min)."""
    lpm = 6e4
    rows = ["| duty | Q cyl [L/min] | Q pump [L/min] | D·Q pump [L/min] | Q/Q pump "
            "| predicted Q/Q pump | Q/(D·Q pump) | check-valve Q [L/min] | make-up Q [L/min] "
            "| switching loss [W] | [J/period] | coils [W] | electrical [W] | mech. [W] "
            "| p_A−p_B mean [MPa] | min p_A−p_t [MPa] | p_on [MPa] | periods |",
            "|" + "---|" * 18]
    for i, d in enumerate(res["duty"]):
        rows.append(
            f"| {d:.2f} | {res['delivered_flow_m3_s'][i] * lpm:.3f} "
            f"| {res['pump_flow_m3_s'][i] * lpm:.3f} | {res['ideal_flow_m3_s'][i] * lpm:.3f} "
            f"| {res['flow_fraction'][i]:.3f} | {res['predicted_fraction'][i]:.3f} "
            f"| {res['ratio_to_ideal'][i]:.3f} "
            f"| {res['check_valve_flow_m3_s'][i] * lpm:.3f} "
            f"| {res['makeup_flow_m3_s'][i] * lpm:.4f} "
            f"| {res['switching_valve_loss_w'][i]:.2f} "
            f"| {res['switching_valve_loss_j_per_period'][i]:.3f} "
            f"| {res['valve_actuator_power_w'][i]:.2f} | {res['electrical_power_w'][i]:.1f} "
            f"| {res['mechanical_power_w'][i]:.2f} "
            f"| {res['load_pressure_mean_pa'][i] / 1e6:.3f} "
            f"| {res['chamber_a_min_above_tank_pa'][i] / 1e6:.3f} "
            f"| {res['pump_pressure_on_pa'][i] / 1e6:.2f} | {res['periods'][i]} |")
    return "\n".join(rows)


def tracking_table(results: Mapping) -> str:
    """A markdown table of :func:`tracking_efficiency`'s results, then the named losses."""
    labels = list(results)
    head = ("| preset | RMSE [N·m] | RMSE [% peak] | peak error [N·m] | peak torque [N·m] "
            "| electrical/cycle [J] | mech. net/cycle [J] | mech. +/cycle [J] "
            "| hydraulic/cycle [J] | η mech | η hyd |")
    rows = [head, "|" + "---|" * 11]
    for k in labels:
        r = results[k]
        rows.append(
            f"| {k} | {r['tracking_rmse_nm']:.2f} | {r['tracking_rmse_pct_peak']:.1f} "
            f"| {r['peak_error_nm']:.1f} | {r['peak_torque_delivered_nm']:.1f} "
            f"| {r['electrical_j_per_cycle']:.1f} | {r['mechanical_j_per_cycle']:.2f} "
            f"| {r['positive_mechanical_j_per_cycle']:.2f} | {r['hydraulic_j_per_cycle']:.1f} "
            f"| {r['efficiency_mechanical']:.3f} | {r['efficiency_hydraulic']:.3f} |")
    rows.append("")
    rows.append("| loss [J/cycle] | " + " | ".join(labels) + " |")
    rows.append("|---|" + "---|" * len(labels))
    names = []
    for k in labels:
        for n in results[k]["losses_j_per_cycle"]:
            if n not in names:
                names.append(n)
    for n in names:
        vals = [results[k]["losses_j_per_cycle"].get(n) for k in labels]
        rows.append(f"| {n} | " + " | ".join("—" if v is None else f"{v:.2f}" for v in vals)
                    + " |")
    for n in results[labels[0]]["stored_change_j_per_cycle"]:
        vals = [results[k]["stored_change_j_per_cycle"].get(n, math.nan) for k in labels]
        rows.append(f"| Δstore {n} | " + " | ".join(f"{v:.2f}" for v in vals) + " |")
    return "\n".join(rows)
