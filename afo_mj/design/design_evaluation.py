"""Exact evaluation of fully specified designs (the design tool's model of a whole device).

:func:`evaluate_designs` takes arrays of design variables (operating pressure, cylinder bore,
pulley radius, hose bore, pump displacement, oil, motor rated power) and returns every figure
the tool reports: masses by part and where worn, the winding, the battery, the energy of every
loss over the stride (the simulator ledger's names), the stage efficiencies, heat and
temperatures, runtime and the constraint margins (:data:`CONSTRAINTS`).
:func:`actuator_geometry` derives the cylinders, cable, seals and pulley from ``(p, D, r)``
through the components' own geometry (:mod:`afo_mj.hydraulics.geometry`,
:mod:`afo_mj.hydraulics.seal`); the chain in steady state is
:mod:`afo_mj.design.design_models`. The search (:mod:`afo_mj.design.design_search`) calls
these; :func:`afo_mj.design.system_design.compute_design` is the whole tool.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from afo_mj.design.design_models import (CHEMISTRIES, DesignAssumptions, SupplyFigures,
                                           cable_diameter_m, cylinder_masses,
                                           hose_wall_mass_kg_per_m, line_steady, motor_scaling,
                                           oil_viscosity_pa_s, oring_cross_section_m,
                                           pack_geometry, pack_thermal_resistance_k_w,
                                           pulley_mass_kg, pump_mass_kg, supply_steady)
from afo_mj.design.design_requirements import DutyCycle, Requirements, duty_cycle
from afo_mj.hydraulics import laws
from afo_mj.hydraulics.battery import BatteryParams
from afo_mj.hydraulics.fluid import FLUID_PRESETS
from afo_mj.hydraulics.geometry import annulus_area_m2
from afo_mj.hydraulics.seal import cylinder_seal_law_args, seal_law_args


#: Laminar limit of the hoses (conduit module; the compiled actuator models laminar hoses).
RE_LAMINAR = 2000.0
#: Constraint names, in chain order, with what each one checks.
CONSTRAINTS = {
    "cable": "the cable for the relief's full-open force fits the bore (d_c ≤ D/2)",
    "torque": "A_e r p ≥ the largest torque asked (pressure × bore × arm)",
    "pump_pressure": "operating pressure within the pump's rating",
    "pressure": "pump pressure at every constraint point ≤ the operating pressure",
    "pump_speed": "pump and motor speed within their limits at every constraint point",
    "laminar": "hose flow laminar (Re ≤ 2000) at every constraint point",
    "driver_current": "current limit within the driver's rating",
    "motor_peak": "peak copper loss within the motor's short-time rating",
    "motor_thermal": "mean motor loss over the duty cycle within its continuous rating",
    "winding": "a realisable winding (K ≤ 10 N·m/A, R ≤ 100 Ω)",
    "surface_temperature": "steady pack surface temperature ≤ the skin-safe limit",
}


def _base():
    from afo_mj.devices.hafo import PRESETS
    return PRESETS["hafo"]


def _budget_fixed(base, arch: str = "pump") -> dict:
    """Masses of the brace and pack parts the tool does not size, from the HAFO's
    :func:`~afo_mj.devices.hafo.mass_budget` (by item name); the valve circuits carry the
    valve presets' valve block (and, pressure-following, accumulator) instead of the HAFO's
    manifold (:func:`~afo_mj.devices.valve_afo.valve_mass_budget`)."""
    from afo_mj.devices.hafo import mass_budget
    items = {it.name: it for it in mass_budget(base)}
    out = {k: items[k].mass_kg for k in ("shank_cuff_struts", "foot_plate", "electronics",
                                         "enclosure_belt")}
    if arch == "pump":
        out["manifold_reservoir_valves"] = items["manifold_reservoir_valves"].mass_kg
    else:
        sf = _supply_figures()
        out["valve_block"] = sf.valve_block_kg
        if arch == "valve":
            out["accumulator"] = sf.accumulator_kg
    return out


_SUPPLY = None


def _supply_figures():
    global _SUPPLY
    if _SUPPLY is None:
        _SUPPLY = SupplyFigures.from_presets()
    return _SUPPLY


#: Names of the supply's valve losses per architecture (ledger style).
VALVE_LOSS_NAME = {"valve": "servo_throttling", "digital": "switching_valves"}


def _waist_fixed(fixed: dict) -> float:
    return sum(v for k, v in fixed.items() if k not in ("shank_cuff_struts", "foot_plate"))


def _grids(req: Requirements) -> dict:
    g = req.search
    lo, hi = req.pressure_range_pa
    pressures = np.array([lo]) if lo == hi else np.geomspace(lo, hi, g.pressure_points)
    blo, bhi = g.cylinder_bore_range_m
    bores = np.arange(blo, bhi + 0.5 * g.cylinder_bore_step_m, g.cylinder_bore_step_m)
    alo, ahi = req.moment_arm_range_m
    arms = np.array([alo]) if alo == ahi else np.linspace(alo, ahi, g.moment_arm_points)
    return {"pressure_pa": pressures, "bore_m": bores, "arm_m": arms,
            "hose_bore_m": np.geomspace(*g.hose_bore_range_m, g.hose_bore_points),
            "displacement_m3_rev": np.geomspace(*g.pump_displacement_range_m3_rev,
                                                g.pump_displacement_points)
            if g.pump_displacement_points > 1 else np.array([g.pump_displacement_range_m3_rev[0]]),
            "motor_power_w": np.geomspace(*g.motor_power_range_w, g.motor_power_points),
            "oil": list(req.oil_grades)}


def _fluids(req: Requirements, a: DesignAssumptions):
    return [FLUID_PRESETS[o].replace(air_fraction=a.air_fraction) for o in req.oil_grades]


def actuator_geometry(pressure_pa, bore_m, arm_m, rom_rad: float, a: DesignAssumptions,
                      base=None) -> dict:
    """Cylinder pair, cable and pulley for ``(p, D, r)`` (arrays broadcast).

    * relief cracking ``p_cr = margin · p``; the largest pressure difference is the relief's
      full-open ``p_cr + override``; walls see that plus the charge pressure;
    * cable: :func:`~afo_mj.design.design_models.cable_diameter_m` for the piston force at the
      largest pressure difference on the full bore area (conservative);
    * ``A_e = n π/4 (D² − d_c²)`` (:func:`~afo_mj.hydraulics.geometry.annulus_area_m2`, as
      :attr:`~afo_mj.hydraulics.cylinder.CylinderParams.area_a_m2`), stroke
      ``r × range of motion``;
    * seals: the preset's nitrile O-rings, piston ring cross-section by bore
      (:func:`~afo_mj.design.design_models.oring_cross_section_m`), per cylinder one piston seal
      and two cable seals lumped as the circuit packs them
      (:func:`~afo_mj.hydraulics.seal.seal_law_args`,
      :func:`~afo_mj.hydraulics.seal.cylinder_seal_law_args`; Coulomb level seed eq. 2.7);
    * internal leakage conductance of one cylinder (as the kernel packs it).
    """
    base = base or _base()
    p = np.asarray(pressure_pa, dtype=float)
    d = np.asarray(bore_m, dtype=float)
    r = np.asarray(arm_m, dtype=float)
    n = base.cylinders
    crack = a.relief_margin * p
    dp_max = crack + a.relief_override_pa
    cable = cable_diameter_m(dp_max * annulus_area_m2(d, 0.0), a)
    ae = n * annulus_area_m2(d, cable)
    cy = base.cylinder
    cs = oring_cross_section_m(d)
    # one piston seal and two cable seals per cylinder, the seal_friction_n arguments as the
    # pulley_cylinders component packs them (its pressure part is not used here)
    fc, strib, v_st, v_c, fv, _ = cylinder_seal_law_args(
        seal_law_args(cy.piston_seal, d, cross_section_m=cs),
        seal_law_args(cy.rod_seal, cable), 2)
    g_leak = laws.annular_gap_conductance_m3(d, cy.radial_clearance_m, cy.land_length_m)
    return {"relief_cracking_pa": crack, "max_dp_pa": dp_max,
            "wall_pressure_pa": a.reservoir_pressure_pa + dp_max, "cable_m": cable,
            "effective_area_m2": ae, "torque_per_pressure_m3": ae * r,
            "stroke_m": r * rom_rad, "piston_seal_cross_section_m": cs,
            "seal": (fc, strib, v_st, v_c, fv), "seal_coulomb_n": fc,
            "leak_conductance_m3": g_leak, "pulley_kg": pulley_mass_kg(r, a)}


def _runtime(req: Requirements, stride_s: float) -> dict:
    wf = req.walking_fraction
    if req.runtime_h is not None:
        total = req.runtime_h * 3600.0
        walk = total * wf
        strides = walk / stride_s
    else:
        strides = req.runtime_strides
        walk = strides * stride_s
        total = walk / wf
    return {"total_s": total, "walking_s": walk, "idle_s": total - walk, "strides": strides}


def _battery_figures(req: Requirements) -> dict:
    """Per ampere-hour of an ``N_s``-cell pack: full energy, usable energy down to
    ``min_state_of_charge`` (J), open-circuit voltage at that charge and at mid-use."""
    b = BatteryParams(capacity_ah=1.0, cells_series=float(req.cells_series), mass_kg=1.0)
    soc_lo = req.min_state_of_charge
    return {"full_j_per_ah": b.energy_wh * 3600.0,
            "usable_j_per_ah": float(b.stored_energy_j(1.0) - b.stored_energy_j(soc_lo)),
            "v_oc_min": float(b.open_circuit_voltage_v(soc_lo)),
            "v_oc_mid": float(b.open_circuit_voltage_v(0.5 * (1.0 + soc_lo))),
            "chemistry": CHEMISTRIES[req.battery_chemistry]}


def evaluate_designs(spec: dict, req: Requirements, duty: DutyCycle | None = None,
                     a: DesignAssumptions | None = None, base=None,
                     temperature_iterations: int = 3) -> dict:
    """Every figure of the designs in ``spec`` (arrays of equal length:
    ``pressure_pa, bore_m, arm_m, hose_bore_m, displacement_m3_rev, oil`` (index into
    ``req.oil_grades``), ``motor_power_w``).

    Per design (arrays): masses by part and where worn, the winding (``K``, ``R``), current
    limit, battery, energies per stride by loss name (the simulator ledger's names),
    stage efficiencies over the stride, system efficiency (positive ankle work / chemical
    energy), heat, steady oil/surface temperature, runtime, the constraint margins and
    ``feasible``. Equations: :func:`~afo_mj.design.design_models.line_steady` and
    :func:`~afo_mj.design.design_models.supply_steady` (the architecture's supply) per sample,
    motor ``v = R i + K ω``, driver ``R_on i² + P_q``, battery Rint per sample, pack thermal
    resistance from natural convection and radiation, oil viscosity at the steady temperature
    (fixed point, ``temperature_iterations`` sweeps).
    """
    a = a or DesignAssumptions()
    base = base or _base()
    duty = duty or duty_cycle(req)
    fluids = _fluids(req, a)
    bat = _battery_figures(req)
    chem = bat["chemistry"]
    rt = _runtime(req, duty.stride_time_s)
    arch = req.architecture
    sf = _supply_figures() if arch != "pump" else None
    fixed = _budget_fixed(base, arch)
    dr, mo, pu = base.driver, base.motor, base.pump
    p_op = np.asarray(spec["pressure_pa"], dtype=float)
    n = p_op.size
    oil = np.asarray(spec["oil"], dtype=int)
    geo = actuator_geometry(p_op, spec["bore_m"], spec["arm_m"], req.range_of_motion_rad, a,
                            base)
    r = np.asarray(spec["arm_m"], dtype=float)
    hb = np.asarray(spec["hose_bore_m"], dtype=float)
    disp = np.asarray(spec["displacement_m3_rev"], dtype=float)
    d = disp / (2.0 * math.pi)
    rho = np.array([f.density_kg_m3 for f in fluids])[oil]
    c_oil = np.array([f.specific_heat_j_kg_k for f in fluids])[oil]
    pm = np.asarray(spec["motor_power_w"], dtype=float)
    ms = motor_scaling(pm, a)
    km = ms["motor_constant_nm_per_sqrt_w"]
    tc, bv = ms["coulomb_torque_nm"], ms["viscous_coefficient_nm_s_rad"]
    col = (slice(None), None)

    def mu_at(temp):
        out = np.empty(n)
        for k, f in enumerate(fluids):
            sel = oil == k
            if np.any(sel):
                out[sel] = oil_viscosity_pa_s(f, np.asarray(temp)[sel] if np.ndim(temp)
                                              else temp)
        return out

    def line(tau, vel, mu):
        return line_steady(tau[None, :], vel[None, :], r=r[col], ae=geo["effective_area_m2"][col],
                           n_cyl=base.cylinders, seal=tuple(np.asarray(s)[col] if np.ndim(s)
                                                            else s for s in geo["seal"]),
                           g_leak=geo["leak_conductance_m3"][col],
                           hose_length_m=req.conduit_length_m, hose_bore_m=hb[col],
                           mu=mu[col], rho=rho[col])

    w_set = None

    def chain(tau, vel, mu):
        out = line(tau, vel, mu)
        out.update(supply_steady(arch, out["q"], out["dp_p"], mu=mu[col], rho=rho[col],
                                 d=d[col], cs=pu.slip_coefficient, cf=pu.coulomb_coefficient,
                                 cv=pu.viscous_coefficient, t0=pu.drag_torque_nm,
                                 wc_pump=pu.smoothing_speed_rad_s, sf=sf,
                                 w_set=None if w_set is None else w_set[col]))
        return out

    def motor_torque(ch):
        return ch["t_p"] + laws.motor_friction_torque_nm(ch["w_p"], tc[col], bv[col],
                                                         mo.smoothing_speed_rad_s)

    # -- masses independent of the temperature -----------------------------------------------
    cyl = cylinder_masses(spec["bore_m"], geo["stroke_m"], geo["cable_m"],
                          geo["wall_pressure_pa"], rho, base.cylinder.dead_volume_a_m3, a)
    cylinders_kg = base.cylinders * cyl["total_kg"]
    hose_wall_kg = 2.0 * req.conduit_length_m * hose_wall_mass_kg_per_m(
        hb, geo["wall_pressure_pa"], a)
    hose_volume = annulus_area_m2(hb, 0.0) * req.conduit_length_m   # one hose, as HoseParams
    hose_oil_kg = 2.0 * rho * hose_volume
    pump_kg = pump_mass_kg(disp, a)
    motor_kg = ms["mass_kg"]
    ankle_fixed = fixed["shank_cuff_struts"] + fixed["foot_plate"]
    waist_fixed = _waist_fixed(fixed)
    oil_volume = (2.0 * hose_volume + base.cylinders * cyl["oil_volume_m3"]
                  + 2.0 * base.pump_port_volume_m3)
    heat_capacity = rho * oil_volume * c_oil + a.metal_specific_heat_j_kg_k * pump_kg

    # -- cold constraint points ----------------------------------------------------------------
    mu_cold = mu_at(req.ambient_temperature_k)
    if arch == "digital":   # constant pump speed: the peak flow with the preset's margin
        q_pk = np.maximum(
            np.max(np.abs(line(duty.constraint_torque_nm, duty.constraint_velocity_rad_s,
                               mu_cold)["q"]), axis=1),
            np.max(np.abs(line(duty.torque_nm, duty.velocity_rad_s, mu_cold)["q"]), axis=1))
        w_set = sf.flow_margin * q_pk / d
    cc = chain(duty.constraint_torque_nm, duty.constraint_velocity_rad_s, mu_cold)
    tm_cold = motor_torque(cc)
    t_oil = np.full(n, req.ambient_temperature_k + 5.0)
    cap = np.full(n, 1.0)
    out: dict[str, Any] = {}
    for it in range(max(temperature_iterations, 1) + 1):
        mu = mu_at(t_oil)
        ch = chain(duty.torque_nm, duty.velocity_rad_s, mu)
        ch_c = chain(duty.constraint_torque_nm, duty.constraint_velocity_rad_s, mu)
        tm = motor_torque(ch)
        tm_c = motor_torque(ch_c)
        t_peak = np.maximum(np.max(np.abs(tm_cold), axis=1), np.max(np.abs(tm_c), axis=1))
        # battery and winding: the pack's resistance depends on its capacity (sized below).
        # The winding constant K is the largest that reaches every envelope point (cold and hot
        # constraint points; the duty samples too for a profile) with the pack, at its lowest
        # allowed charge, sagging under that point's own current: v = K (T/k_m² + ω) ≤
        # duty_max (V_oc − R_b I_b).
        r_bat = a.battery_cell_resistance_ohm_ah * req.cells_series / cap
        vmin = bat["v_oc_min"]
        env = [(tm_cold, cc["w_p"]), (tm_c, ch_c["w_p"])]
        if req.profile != "corner":
            env.append((tm, ch["w_p"]))

        def bus(tq, w, kt):
            i_ = tq / kt[col]
            p_ = np.maximum(tq * w + tq ** 2 / km[col] ** 2 + dr.on_resistance_ohm * i_ ** 2
                            + dr.quiescent_power_w + valve_el_peak[:, None], 0.0)
            ib = laws.battery_current_a(p_, vmin, r_bat[col])
            return p_, ib, vmin - r_bat[col] * ib

        valve_el_peak = np.max(ch["p_valve_el"], axis=1)
        k_t = np.full(n, 0.05)
        for _ in range(4):
            cand = [np.min(dr.max_duty * bus(tq, w, k_t)[2]
                           / np.maximum(np.abs(tq / km[col] ** 2 + w), 1e-12), axis=1)
                    for tq, w in env]
            k_t = np.minimum(np.minimum.reduce(cand), 10.0)
        i_bat_peak = np.max(np.concatenate([bus(tq, w, k_t)[1] for tq, w in env]
                                           + [bus(tm, ch["w_p"], k_t)[1]], axis=1), axis=1)
        v_avail = dr.max_duty * (vmin - r_bat * i_bat_peak)
        r_w = (k_t / km) ** 2
        i_lim = t_peak / k_t
        # energies per stride (J)
        dt = duty.dt_s[None, :]
        i_d = tm / k_t[col]
        copper = tm ** 2 / km[col] ** 2
        mfric = (tm - ch["t_p"]) * ch["w_p"]
        drv = dr.on_resistance_ohm * i_d ** 2 + dr.quiescent_power_w
        p_motor_in = tm * ch["w_p"] + copper
        p_bus = p_motor_in + drv + ch["p_valve_el"]
        vmid = bat["v_oc_mid"]
        i_b = laws.battery_current_a(p_bus, vmid, r_bat[col])
        p_chem = vmid * i_b
        e = {k: np.sum(v * dt, axis=1) for k, v in (
            ("battery_internal", p_chem - p_bus), ("driver", drv), ("motor_copper", copper),
            ("motor_friction", mfric), ("pump_volumetric", ch["p_pump_vol"]),
            ("pump_mechanical", ch["p_pump_mech"]), ("line", ch["p_line"]),
            ("seal_friction", ch["p_seal"]), ("leakage", ch["p_leak"]))}
        if arch != "pump":
            e[VALVE_LOSS_NAME[arch]] = np.sum(ch["p_valve"] * dt, axis=1)
            e["valve_coils"] = np.sum(ch["p_valve_el"] * dt, axis=1)
        e_chem = np.sum(p_chem * dt, axis=1)
        e_bus = np.sum(p_bus * dt, axis=1)
        # runtime energy and the pack it needs
        e_run = rt["strides"] * e_chem + rt["idle_s"] * dr.quiescent_power_w
        cap_energy = e_run / bat["usable_j_per_ah"]
        cap_power = i_bat_peak / chem.max_c_rate_per_h
        cap = np.maximum(np.maximum(cap_energy, cap_power), a.battery_min_capacity_ah)
        battery_kg = cap * bat["full_j_per_ah"] / 3600.0 / (chem.cell_specific_energy_wh_kg
                                                              * a.battery_pack_factor)
        # heat in the pack (everything but the ankle's seal friction and piston leakage)
        stride = duty.stride_time_s
        walk_frac = rt["walking_s"] / rt["total_s"]
        heat_walk = (e["battery_internal"] + e["driver"] + e["motor_copper"]
                     + e["motor_friction"] + e["pump_volumetric"] + e["pump_mechanical"]
                     + e["line"] + e.get(VALVE_LOSS_NAME.get(arch, ""), 0.0)
                     + e.get("valve_coils", 0.0)) / stride
        heat_oil_walk = (e["pump_volumetric"] + e["pump_mechanical"] + e["line"]
                         + e["seal_friction"] + e["leakage"]
                         + e.get(VALVE_LOSS_NAME.get(arch, ""), 0.0)) / stride
        heat = walk_frac * heat_walk + (1.0 - walk_frac) * dr.quiescent_power_w
        heat_oil = walk_frac * heat_oil_walk
        waist_kg = battery_kg + motor_kg + pump_kg + waist_fixed
        geom = pack_geometry(waist_kg, a)
        t_surf, r_pack = pack_thermal_resistance_k_w(heat, geom["diameter_m"],
                                                     geom["exposed_area_m2"],
                                                     req.ambient_temperature_k, a)
        t_oil = t_surf
    # -- efficiencies over the stride: each stage's output over its input where the input is
    # positive (motoring), system: positive ankle work / chemical energy ----------------------
    p_to_lines = ch["p_hyd_pump"] - ch["p_valve"]          # Δp_L q, what the lines receive
    stages = [("battery", p_chem, p_bus), ("driver", p_bus, p_motor_in),
              ("motor", p_motor_in, ch["t_p"] * ch["w_p"]),
              ("pump", ch["t_p"] * ch["w_p"], ch["p_hyd_pump"])]
    if arch != "pump":
        stages.append(("valves", ch["p_hyd_pump"], p_to_lines))
    stages += [("lines", p_to_lines, p_to_lines - ch["p_line"]),
               ("cylinders", p_to_lines - ch["p_line"], ch["p_mech"])]
    eff = {}
    for name, pin, pout in stages:
        m = pin > 0
        num = np.sum(np.where(m, pout, 0.0) * dt, axis=1)
        den = np.sum(np.where(m, pin, 0.0) * dt, axis=1)
        eff[name] = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
    w_pos = np.broadcast_to(np.sum(np.maximum(ch["p_mech"], 0.0) * dt, axis=1), (n,)).copy()
    w_net = np.broadcast_to(np.sum(ch["p_mech"] * dt, axis=1), (n,)).copy()
    eta_sys = np.where(e_chem > 0, w_pos / np.where(e_chem > 0, e_chem, 1.0), np.nan)
    # -- constraints ---------------------------------------------------------------------------
    mot_loss_mean = (e["motor_copper"] + e["motor_friction"]) / stride
    w_max = np.maximum(np.max(np.abs(cc["w_p"]), axis=1), np.max(np.abs(ch_c["w_p"]), axis=1))
    if req.profile != "corner":
        w_max = np.maximum(w_max, np.max(np.abs(ch["w_p"]), axis=1))
    dp_max = np.maximum(np.max(cc["p_required"], axis=1), np.max(ch_c["p_required"], axis=1))
    re_max = np.maximum(np.max(cc["reynolds"], axis=1), np.max(ch_c["reynolds"], axis=1))
    speed_lim = min(pu.max_speed_rad_s, a.motor_max_speed_rad_s)
    margins = {  # ≥ 0 where met (relative)
        "cable": 1.0 - geo["cable_m"] / (0.5 * np.asarray(spec["bore_m"], dtype=float)),
        "torque": geo["torque_per_pressure_m3"] * (p_op - (sf.margin_pa if arch == "valve"
                                                           else 0.0))
        / float(np.max(np.abs(duty.constraint_torque_nm))) - 1.0,
        "pump_pressure": 1.0 - p_op / a.pump_max_pressure_pa,
        "pressure": 1.0 - dp_max / p_op,
        "pump_speed": 1.0 - w_max / speed_lim,
        "laminar": 1.0 - re_max / RE_LAMINAR,
        "driver_current": 1.0 - i_lim / a.driver_max_current_a,
        "motor_peak": 1.0 - np.max(tm_c ** 2, axis=1) / km ** 2
        / (a.motor_peak_loss_ratio * ms["continuous_loss_w"]),
        "motor_thermal": 1.0 - mot_loss_mean / ms["continuous_loss_w"],
        "winding": np.minimum(1.0 - k_t / 10.0, 1.0 - r_w / 100.0),
        "surface_temperature": (req.max_surface_temperature_k - t_surf)
        / (req.max_surface_temperature_k - req.ambient_temperature_k),
    }
    feasible = np.ones(n, dtype=bool)
    for v in margins.values():
        feasible &= np.isfinite(v) & (v >= -1e-9)
    ankle_kg = cylinders_kg + geo["pulley_kg"] + ankle_fixed
    hoses_kg = hose_wall_kg + hose_oil_kg
    waist_all = waist_kg + hoses_kg
    total = ankle_kg + waist_all
    mean_power = e_chem / stride
    runtime_h = (cap * bat["usable_j_per_ah"]) / (walk_frac * mean_power + (1.0 - walk_frac)
                                                  * dr.quiescent_power_w) / 3600.0
    out.update({
        "total_kg": total, "ankle_kg": ankle_kg, "waist_kg": waist_all,
        "mass": {"cylinders": cylinders_kg, "shank_cuff_struts": np.full(n, fixed[
            "shank_cuff_struts"]), "pulley_bearings": geo["pulley_kg"],
                 "foot_plate": np.full(n, fixed["foot_plate"]), "battery": battery_kg,
                 "motor": motor_kg, "pump": pump_kg,
                 **{k: np.full(n, v) for k, v in fixed.items()
                    if k not in ("shank_cuff_struts", "foot_plate")},
                 "hoses": hoses_kg},
        "mass_detail": {"hose_wall_kg": hose_wall_kg, "hose_oil_kg": hose_oil_kg,
                        "cylinder_oil_kg": base.cylinders * cyl["oil_kg"],
                        "cylinder_wall_m": cyl["wall_m"],
                        "cylinder_outer_diameter_m": cyl["outer_diameter_m"]},
        "geometry": geo, "spec": {k: np.asarray(v) for k, v in spec.items()},
        "torque_constant_nm_a": k_t, "resistance_ohm": r_w, "current_limit_a": i_lim,
        "motor_constant_nm_per_sqrt_w": km, "motor": ms,
        "battery_capacity_ah": cap, "battery_resistance_ohm": r_bat,
        "battery_peak_current_a": i_bat_peak, "battery_max_current_a":
            chem.max_c_rate_per_h * cap, "voltage_available_v": v_avail,
        "energy_j": e, "chemical_j": e_chem, "bus_j": e_bus, "positive_work_j": w_pos,
        "net_work_j": w_net, "efficiency": eff, "system_efficiency": eta_sys,
        "heat_w": heat, "heat_oil_w": heat_oil, "surface_temperature_k": t_surf,
        "oil_temperature_k": t_oil, "pack_resistance_k_w": r_pack,
        "pack_diameter_m": geom["diameter_m"], "pack_area_m2": geom["exposed_area_m2"],
        "oil_volume_m3": oil_volume, "heat_capacity_j_k": heat_capacity,
        "viscosity_pa_s": mu, "runtime_h": runtime_h, "runtime_strides":
            runtime_h * 3600.0 * walk_frac / stride, "mean_walking_power_w": mean_power,
        "peak_pump_pressure_pa": dp_max, "peak_pump_speed_rad_s": w_max,
        "peak_reynolds": re_max, "margins": margins, "feasible": feasible,
        "motor_mean_loss_w": mot_loss_mean,
        "pump_speed_set_rad_s": w_set if w_set is not None else np.full(n, np.nan),
    })
    return out


def _row(ev: dict, i: int, req: Requirements) -> dict:
    sp = ev["spec"]
    geo = ev["geometry"]
    r = {"operating_pressure_pa": float(sp["pressure_pa"][i]),
         "cylinder_bore_m": float(sp["bore_m"][i]), "pulley_radius_m": float(sp["arm_m"][i]),
         "hose_bore_m": float(sp["hose_bore_m"][i]),
         "pump_displacement_m3_rev": float(sp["displacement_m3_rev"][i]),
         "oil": req.oil_grades[int(sp["oil"][i])],
         "motor_rated_power_w": float(sp["motor_power_w"][i]),
         "cable_diameter_m": float(geo["cable_m"][i]),
         "cylinder_stroke_m": float(geo["stroke_m"][i]),
         "piston_seal_cross_section_m": float(geo["piston_seal_cross_section_m"][i]),
         "torque_per_pressure_m3": float(geo["torque_per_pressure_m3"][i]),
         "relief_cracking_pa": float(geo["relief_cracking_pa"][i]),
         "total_kg": float(ev["total_kg"][i]), "ankle_kg": float(ev["ankle_kg"][i]),
         "waist_kg": float(ev["waist_kg"][i]),
         "mass_kg": {k: float(v[i]) for k, v in ev["mass"].items()},
         "torque_constant_nm_a": float(ev["torque_constant_nm_a"][i]),
         "resistance_ohm": float(ev["resistance_ohm"][i]),
         "current_limit_a": float(ev["current_limit_a"][i]),
         "battery_capacity_ah": float(ev["battery_capacity_ah"][i]),
         "battery_resistance_ohm": float(ev["battery_resistance_ohm"][i]),
         "battery_peak_current_a": float(ev["battery_peak_current_a"][i]),
         "losses_j_per_stride": {k: float(v[i]) for k, v in ev["energy_j"].items()},
         "chemical_j_per_stride": float(ev["chemical_j"][i]),
         "positive_work_j_per_stride": float(ev["positive_work_j"][i]),
         "net_work_j_per_stride": float(ev["net_work_j"][i]),
         "efficiency": {k: _f(v[i]) for k, v in ev["efficiency"].items()},
         "system_efficiency": _f(ev["system_efficiency"][i]),
         "heat_w": float(ev["heat_w"][i]), "heat_to_oil_w": float(ev["heat_oil_w"][i]),
         "oil_temperature_k": float(ev["oil_temperature_k"][i]),
         "surface_temperature_k": float(ev["surface_temperature_k"][i]),
         "pack_resistance_k_w": float(ev["pack_resistance_k_w"][i]),
         "runtime_h": float(ev["runtime_h"][i]),
         "heat_capacity_j_k": float(ev["heat_capacity_j_k"][i]),
         "runtime_strides": float(ev["runtime_strides"][i]),
         "mean_walking_power_w": float(ev["mean_walking_power_w"][i]),
         "peak_pump_pressure_pa": float(ev["peak_pump_pressure_pa"][i]),
         "peak_pump_speed_rad_s": float(ev["peak_pump_speed_rad_s"][i]),
         "peak_reynolds": float(ev["peak_reynolds"][i]),
         "margins": {k: _f(v[i]) for k, v in ev["margins"].items()},
         "feasible": bool(ev["feasible"][i])}
    r["oil_thermal_resistance_k_w"] = _oil_resistance(r)
    hyd_kg = (r["mass_kg"]["motor"] + r["mass_kg"]["pump"] + r["mass_kg"]["hoses"]
              + r["mass_kg"]["cylinders"] + r["mass_kg"]["pulley_bearings"]
              + sum(r["mass_kg"].get(k, 0.0) for k in ("manifold_reservoir_valves",
                                                       "valve_block", "accumulator")))
    r["hydraulic_system_kg"] = hyd_kg
    r["rated_output_power_w"] = _rated_power(req)
    r["hydraulic_power_density_w_kg"] = r["rated_output_power_w"] / hyd_kg
    r["system_energy_density_wh_kg"] = (r["positive_work_j_per_stride"] * r["runtime_strides"]
                                        / 3600.0 / r["total_kg"])
    return r


def _f(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _rated_power(req: Requirements, duty: DutyCycle | None = None) -> float:
    """Output power the actuator is rated for: corner torque × corner speed, or the largest
    |τ θ̇| of the profile."""
    if req.profile == "corner":
        return req.peak_torque_nm * req.peak_velocity_rad_s
    return (duty or duty_cycle(req)).peak_power_w


def _oil_resistance(row: dict) -> float:
    """The resistance to write as the simulator's ``thermal_resistance_k_w``. The design's pack
    is one thermal node holding oil, motor, driver and cells; the simulator's oil node receives
    only the oil's own heat (pump, lines, seals) and sends the motor's and driver's straight to
    the ambient. Writing ``R_pack · Q_pack / Q_oil`` makes the simulator's steady oil
    temperature the design's pack temperature (clipped to the parameter's range)."""
    q_oil = row["heat_to_oil_w"]
    r = row["pack_resistance_k_w"] * row["heat_w"] / q_oil if q_oil > 1e-9 else 1e3
    return float(min(max(r, 0.01), 1e3))
