"""The best design as the simulator's device, and what it should do there.

:func:`design_overrides` and :func:`design_params` write a pump-controlled design as dotted
overrides of the ``hafo`` preset (validated :class:`~afo_mj.devices.hafo.PumpAnkleParams`);
:func:`mass_check` compares its masses with the simulator's mass budget; :func:`predict_bench`
solves the steady stall and no-load points of the written parameters from the generated
circuit's own packed parameters and laws; :func:`walk_work_check` asks, quasi-statically,
whether the written walk is assisted or braked.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from afo_mj.design.design_evaluation import _base
from afo_mj.design.design_models import (CHEMISTRIES, DesignAssumptions, chain_steady,
                                           motor_scaling, pump_inertia_kg_m2)
from afo_mj.design.design_requirements import Requirements
from afo_mj.hydraulics import laws
from afo_mj.hydraulics.fluid import Fluid


#: Samples of the written walk's stride in :func:`walk_work_check`.
WALK_CHECK_SAMPLES = 1000


def design_overrides(row: dict, req: Requirements, a: DesignAssumptions | None = None) -> dict:
    """Dotted overrides of the ``hafo`` preset that make it the design ``row`` (the
    ``[device.params]`` table of the written scenarios)."""
    a = a or DesignAssumptions()
    base = _base()
    ms = motor_scaling(row["motor_rated_power_w"], a)
    r_w = row["resistance_ohm"]
    disp = row["pump_displacement_m3_rev"]
    scale = a.pump_reference_displacement_m3_rev / disp
    chem = CHEMISTRIES[req.battery_chemistry]
    cap = row["battery_capacity_ah"]
    ov = {
        "fluid": row["oil"], "fluid.air_fraction": a.air_fraction,
        "cylinder.bore_m": row["cylinder_bore_m"],
        "cylinder.rod_diameter_m": row["cable_diameter_m"],
        "cylinder.stroke_m": row["cylinder_stroke_m"],
        "cylinder.piston_seal.cross_section_m": row["piston_seal_cross_section_m"],
        "pulley_radius_m": row["pulley_radius_m"],
        "hose.bore_m": row["hose_bore_m"], "hose.length_m": req.conduit_length_m,
        "pump.displacement_m3_rev": disp,
        "pump.rotor_inertia_kg_m2": float(pump_inertia_kg_m2(
            disp, base.pump.rotor_inertia_kg_m2, a)),
        "pump_mass_kg": row["mass_kg"]["pump"],
        "motor.torque_constant_nm_a": row["torque_constant_nm_a"],
        "motor.resistance_ohm": r_w,
        "motor.inductance_h": max(a.motor_electrical_time_constant_s * r_w, 1e-7),
        "motor.rotor_inertia_kg_m2": float(ms["rotor_inertia_kg_m2"]),
        "motor.coulomb_torque_nm": float(ms["coulomb_torque_nm"]),
        "motor.viscous_coefficient_nm_s_rad": float(ms["viscous_coefficient_nm_s_rad"]),
        "motor.max_speed_rad_s": a.motor_max_speed_rad_s,
        "motor.mass_kg": row["mass_kg"]["motor"],
        # the driver law's clamp (laws.driver_voltage_v) is exact away from its rounded
        # corners, so the design's limit is written as it is
        "driver.current_limit_a": row["current_limit_a"],
        "battery.name": f"{req.cells_series}S {cap:.2f} Ah Li-ion {chem.name}",
        "battery.capacity_ah": cap, "battery.cells_series": float(req.cells_series),
        "battery.internal_resistance_ohm": row["battery_resistance_ohm"],
        "battery.max_current_a": chem.max_c_rate_per_h * cap,
        "battery.mass_kg": row["mass_kg"]["battery"],
        "relief.cracking_dp_pa": row["relief_cracking_pa"],
        "relief.override_dp_pa": a.relief_override_pa,
        "reservoir_pressure_pa": a.reservoir_pressure_pa,
        "heat_capacity_j_k": row["heat_capacity_j_k"],
        "thermal_resistance_k_w": row["oil_thermal_resistance_k_w"],
        "ambient_temperature_k": req.ambient_temperature_k,
        # the pressure loop's gain is pump flow per pressure error: keep d·k_p (as hafo_gait)
        "control.pressure_gain_rad_s_per_pa":
            base.control.pressure_gain_rad_s_per_pa * scale,
        "control.pressure_integral_gain_rad_per_pa":
            base.control.pressure_integral_gain_rad_per_pa * scale,
    }
    return {k: (round(v, 12) if isinstance(v, float) else v) for k, v in ov.items()}


def design_params(row: dict, req: Requirements, a: DesignAssumptions | None = None):
    """``(overrides, PumpAnkleParams)``: the design as the simulator's parameters, validated
    by :func:`afo_mj.devices.hafo.hafo_params`."""
    from afo_mj.devices.hafo import hafo_params
    ov = design_overrides(row, req, a)
    return ov, hafo_params(ov, "hafo")


def mass_check(row: dict, params) -> dict:
    """The design's predicted masses against :func:`afo_mj.devices.hafo.mass_budget` of the
    written parameters (what the walker carries), item by item."""
    from afo_mj.devices.hafo import HafoDevice, mass_budget
    budget = {it.name: it.mass_kg for it in mass_budget(params)}
    dev = HafoDevice(params)
    items = {k: {"design_kg": row["mass_kg"].get(k, 0.0), "budget_kg": budget.get(k, 0.0),
                 "difference_kg": row["mass_kg"].get(k, 0.0) - budget.get(k, 0.0)}
             for k in dict.fromkeys(list(row["mass_kg"]) + list(budget))}
    tot, ank = dev.mass_total_kg, dev.mass_at_ankle_kg
    return {"design_total_kg": row["total_kg"], "budget_total_kg": tot,
            "total_rel_difference": (row["total_kg"] - tot) / tot,
            "design_ankle_kg": row["ankle_kg"], "budget_ankle_kg": ank,
            "ankle_rel_difference": (row["ankle_kg"] - ank) / ank, "items": items}


def predict_bench(params, *, soc: float | None = None, temperature_k: float | None = None,
                  full_voltage_v: float | None = None) -> dict:
    """Steady-state stall torque and no-load speed of ``params`` as the torque–velocity bench
    (:func:`afo_mj.experiments.hafo_bench.torque_velocity`) measures them, from the simulator's
    own parameters and laws (:mod:`afo_mj.hydraulics.laws`).

    * full voltage command ``1.25 × 4.2 V × cells`` through the driver's clamps (current limit
      ``K ω ± R I_max``, duty ``± d V_bus``, both with the 0.05 V rounded corners of
      :func:`~afo_mj.hydraulics.laws.driver_voltage_v`);
      battery at the preset's initial charge (Rint: ``V_bus = V_oc − R_b I_b``); oil at ambient
      (the bench starts cold and runs for a fraction of a second);
    * **stall** (ankle locked): ``K i = T_motor(ω) `` with the pump turning only to feed its
      slip, the piston leakage and the relief seat leakage; the torque is ``r A_e Δp_c``;
    * **no load** (foot free): the speed at which the applied voltage equals
      ``R i + K ω`` with ``i`` the current that turns the pump against the seal friction and
      the line loss. The foot's weight (≈ 0.6 N·m about the ankle, helping plantarflexion) is
      left out: it moves the pump pressure by < 0.1 MPa and the speed by < 1 %.

    Every component equation is a law of :mod:`afo_mj.hydraulics.laws`; the open-circuit
    voltage is the battery parameters' own table
    (:meth:`afo_mj.hydraulics.battery.BatteryParams.open_circuit_voltage_v`).
    """
    from scipy.optimize import brentq

    from afo_mj.circuits.codegen import generate
    from afo_mj.devices.hafo import hafo_circuit
    # the parameters as the device's generated circuit reads them (effect switches applied)
    _, emitted, _ = generate(hafo_circuit(params))
    P = dict(zip(emitted.P_labels, emitted.P))
    soc = params.initial_soc if soc is None else soc
    temp = params.ambient_temperature_k if temperature_k is None else temperature_k
    mu = float(Fluid(params.fluid).dynamic_viscosity_pa_s(temp))
    v_oc = float(params.battery.open_circuit_voltage_v(soc))
    v_cmd = 1.25 * 4.2 * params.battery.cells_series if full_voltage_v is None else full_voltage_v
    n, r = P["cylinders.count"], P["cylinders.pulley_radius"]
    ae = n * P["cylinders.area"]
    d, cs, cf, cv, t0, wcp = (P["pump.d"], P["pump.slip"], P["pump.coulomb"],
                              P["pump.viscous"], P["pump.drag"], P["pump.smoothing_speed"])
    R, K, ilim = P["motor.R"], P["motor.K"], P["motor.current_limit"]
    hose, rho = params.hose, P["fluid.density"]
    seal = (P["cylinders.seal_fc"], P["cylinders.seal_stribeck"], P["cylinders.seal_v_st"],
            P["cylinders.seal_v_c"], P["cylinders.seal_fv"])

    def motor_t(w, dpp):
        """Motor shaft torque: pump ``d Δp + T_f`` plus the motor's friction (the laws)."""
        tm = laws.motor_friction_torque_nm(w, P["motor.coulomb_nm"], P["motor.viscous"],
                                           P["motor.smoothing_speed"])
        tp = d * dpp + laws.pump_friction_torque_nm(w, dpp, d, cf, cv, t0, wcp, mu)
        return float(tm + tp)

    def applied(w, cur):
        """Voltage the driver applies at motor speed ``w`` drawing ``cur`` (fixed point on
        the bus voltage; :func:`~afo_mj.hydraulics.laws.driver_voltage_v`,
        :func:`~afo_mj.hydraulics.laws.battery_current_a`)."""
        volt = v_cmd
        vbus = v_oc
        for _ in range(30):
            volt = float(laws.driver_voltage_v(v_cmd, K * w, R, ilim, P["motor.limit_on"],
                                               P["motor.max_duty"], vbus))
            pbus = volt * cur + P["motor.r_on"] * cur * cur + P["motor.quiescent_w"]
            rb = P["battery.resistance_ohm"]
            ib = float(laws.battery_current_a(pbus, v_oc, rb))
            vbus_new = max(v_oc - rb * ib, 0.0)
            if abs(vbus_new - vbus) < 1e-12:
                break
            vbus = vbus_new
        return volt

    # -- stall: unknown chamber difference Δp_c ------------------------------------------------
    def stall_state(dpc):
        q_lk = float(laws.laminar_gap_flow_m3_s(dpc, P["cylinders.leak_g"], mu))
        dpp = dpc + 2.0 * float(laws.hose_pressure_loss_pa(q_lk, hose.length_m, hose.bore_m, mu,
                                                           rho, 0.0, 0.0))
        q_rel = 0.0
        if dpp > 0.0:   # the relief from the high to the low side, seated otherwise
            area = laws.relief_valve_area_m2(dpp, P["relief_ab.cracking"], P["relief_ab.override"],
                                             P["relief_ab.max_area"], P["relief_ab.leak_area"])
            q_rel = float(laws.orifice_flow_m3_s(dpp, area, P["relief_ab.cd"], rho,
                                                 P["relief_ab.p_cr"]))
        w = float(laws.pump_speed_for_flow_rad_s(q_lk + q_rel, dpp, d, cs,
                                                 P["pump.extra_leak"], mu))
        return w, dpp

    def stall_residual(dpc):
        w, dpp = stall_state(dpc)
        tm = motor_t(w, dpp)
        cur = tm / K
        return applied(w, cur) - (R * cur + K * w)

    hi = 4.0 * P["relief_ab.cracking"]
    dpc = brentq(stall_residual, 0.0, hi, xtol=1.0, rtol=1e-12)
    w_s, dpp_s = stall_state(dpc)
    stall = r * ae * dpc

    # -- no load: unknown plantarflexion speed ω_a --------------------------------------------
    def free_state(wa):
        ch = chain_steady(0.0, -wa, r=r, ae=ae, n_cyl=n, seal=seal, g_leak=P["cylinders.leak_g"],
                          hose_length_m=hose.length_m, hose_bore_m=hose.bore_m,
                          mu=mu, rho=rho, d=d, cs=cs, cf=cf, cv=cv, t0=t0, wc_pump=wcp)
        return float(ch["w_p"]), float(ch["dp_p"])

    def free_residual(wa):
        w, dpp = free_state(wa)
        cur = motor_t(w, dpp) / K
        return applied(w, cur) - (R * cur + K * w)

    w_hi = 1.2 * P["motor.max_duty"] * v_oc / K * d / (ae * r)
    wa = brentq(free_residual, 1e-6, w_hi, xtol=1e-9, rtol=1e-12)
    w_nl, dpp_nl = free_state(wa)
    return {"stall_torque_nm": stall, "stall_pump_pressure_pa": dpp_s,
            "stall_current_a": motor_t(w_s, dpp_s) / K,
            "no_load_speed_deg_s": math.degrees(wa), "no_load_pump_pressure_pa": dpp_nl,
            "no_load_motor_speed_rad_s": w_nl, "viscosity_pa_s": mu, "soc": soc,
            "open_circuit_voltage_v": v_oc}


def quasi_static_device_torque_nm(command_nm, velocity_rad_s, stall_torque_nm: float,
                                  no_load_speed_rad_s: float):
    """Torque [N·m] a pump-controlled actuator puts on the ankle, quasi-static (ankle sign
    convention, +dorsiflexion for torque and velocity): the command clipped to the
    four-quadrant torque–speed envelope of its voltage- and current-limited DC motor.

    The motor's steady torque at full voltage falls linearly with speed,
    ``T = K (V − K ω) / R`` (the DC motor's torque–speed line, e.g. Hughes & Drury, *Electric
    Motors and Drives*, the d.c. motor chapter), and a fixed-displacement pump driving the
    cylinders is a fixed ratio of torque to pressure and of speed to flow (the ideal pump,
    ``T = d Δp / 2π``, ``Q = d ω / 2π``; Manring, *Hydraulic Control Systems*). At the ankle
    the line runs through the stall torque ``T_s`` and the no-load speed ``ω_0``
    (:func:`predict_bench`): plantarflexion torque up to ``T_s (1 − ω_pf/ω_0)`` at
    plantarflexion speed ``ω_pf``, dorsiflexion torque the same way, and the driver's current
    limit bounds either at ``T_s``. Past ``ω_0`` the bound
    changes sign: the ankle back-drives the pump, the motor's EMF exceeds what the driver
    applies, and the device resists the motion whatever it is commanded (it brakes). Losses
    (friction, leakage, line drop) are left out: they only take more work from the ankle, so a
    net negative work predicted here is not an artefact of the simplification.
    """
    cmd = np.asarray(command_nm, dtype=float)
    w = np.asarray(velocity_rad_s, dtype=float)
    lo = -stall_torque_nm * (1.0 + w / no_load_speed_rad_s)    # most plantarflexion torque
    hi = stall_torque_nm * (1.0 - w / no_load_speed_rad_s)     # most dorsiflexion torque
    return np.clip(np.clip(cmd, lo, hi), -stall_torque_nm, stall_torque_nm)


def walk_work_check(scenario, cfg, predicted_bench: dict, n: int = WALK_CHECK_SAMPLES) -> dict:
    """Does the written device assist or brake the walk it is written for? The net work of the
    design on the ankle per stride, from the design's quasi-static model
    (:func:`quasi_static_device_torque_nm` with the predicted stall torque and no-load speed),
    over the written walk's own gait: the reference ankle velocity of ``design_walk.toml``
    (its ``[gait]``, at its cycle time) and, per condition, its command (``transparent``: zero
    torque; ``assist``: the ``[assistance]`` profile). No walk is simulated.

    Work per stride ``W = Σ τ_dev ω Δt`` (ankle power = moment × angular velocity, both
    +dorsiflexion; Winter, *Biomechanics and Motor Control of Human Movement*, the chapter on
    mechanical work, energy and power).
    Returns per condition the positive, negative and net work [J/stride], the peak
    plantarflexion velocity of the gait, the fraction of the stride the ankle plantarflexes
    faster than the no-load speed (back-driven), ``brakes`` (a net work < 0 in any condition)
    and ``warning`` (a sentence naming the cause and the requirement to change, or None).

    A ``corner`` requirement's duty cycle is Winter's stride scaled to the corner's speed, so it
    cannot show this; the written walk is at the reference's own speed."""
    ref = scenario.load_reference()
    cyc = float(scenario.cycle_time_s(ref))
    phase = (np.arange(n) + 0.5) / n
    w = np.asarray(ref.velocities_rad_s(phase, cyc))[..., 2]
    stall = float(predicted_bench["stall_torque_nm"])
    w0 = math.radians(float(predicted_bench["no_load_speed_deg_s"]))
    dt = cyc / n
    commands = {"transparent": np.zeros(n)}
    if cfg.profile is not None:
        prof = np.asarray(cfg.profile, dtype=float)
        commands["assist"] = np.interp(phase, np.linspace(0.0, 1.0, prof.size), prof)
    out: dict[str, Any] = {
        "model": "quasi-static: command clipped to the DC motor's torque-speed envelope through "
                 "the predicted stall torque and no-load speed, lossless, over the reference "
                 "gait (not a simulated walk)",
        "gait": f"{scenario.reference}/{scenario.condition}", "cycle_time_s": cyc,
        "samples": n, "stall_torque_nm": stall,
        "no_load_speed_deg_s": math.degrees(w0),
        "peak_plantarflexion_velocity_deg_s": math.degrees(float(max(-np.min(w), 0.0))),
        "back_driven_fraction_of_stride": float(np.mean(-w > w0)),
        "conditions": {}}
    for name, cmd in commands.items():
        if name not in cfg.conditions:
            continue
        p = quasi_static_device_torque_nm(cmd, w, stall, w0) * w
        pos = float(np.sum(np.clip(p, 0.0, None)) * dt)
        neg = float(np.sum(np.clip(p, None, 0.0)) * dt)
        out["conditions"][name] = {"positive_work_j_per_stride": pos,
                                   "negative_work_j_per_stride": neg,
                                   "net_work_j_per_stride": pos + neg}
    negative = {k: v["net_work_j_per_stride"] for k, v in out["conditions"].items()
                if v["net_work_j_per_stride"] < 0.0}
    out["brakes"] = bool(negative)
    out["warning"] = None
    if negative:
        works = ", ".join(f"{k} {v:.1f} J/stride" for k, v in negative.items())
        msg = (f"design_walk.toml: the designed device does net negative work on the ankle "
               f"over the walk's gait ({out['gait']}, {cyc:.2f} s stride; {works}, "
               f"quasi-static, no walk simulated): it brakes the walker")
        if out["peak_plantarflexion_velocity_deg_s"] > out["no_load_speed_deg_s"]:
            msg += (f". Cause: its no-load speed {out['no_load_speed_deg_s']:.1f} deg/s is below "
                    f"the gait's peak plantarflexion velocity "
                    f"{out['peak_plantarflexion_velocity_deg_s']:.1f} deg/s, so the ankle "
                    f"back-drives the pump for {100 * out['back_driven_fraction_of_stride']:.0f} "
                    f"% of the stride; to assist this walk, require a no-load speed >= "
                    f"{math.ceil(out['peak_plantarflexion_velocity_deg_s'])} deg/s "
                    f"(requirement.peak_velocity_deg_s of a corner profile, or profile = "
                    f"\"normative\" with this gait)")
        out["warning"] = msg
    return out
