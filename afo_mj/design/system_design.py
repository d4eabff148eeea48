"""Minimum-weight hydraulic ankle actuation designed from requirements (the seed's ch. 3 tool).

:func:`compute_design` searches a grid of designs for the lightest one that meets the
requirements (:mod:`afo_mj.design.design_requirements`, :func:`read_requirements`), explains
which constraint binds when none does, derives the best design as scenarios that ``afo-mj run``
accepts (:mod:`afo_mj.design.design_scenarios`) and runs the design-guideline studies; it
writes nothing. ``afo-mj design REQUIREMENTS.toml --out DIR`` is :func:`afo_mj.app.design.design`,
which writes the results (:mod:`afo_mj.outputs.design_report`).

The search (:func:`size_system`), pump-controlled architecture
---------------------------------------------------------------
Design variables: operating pressure ``p`` (fixed or a geometric grid over the allowed range),
cylinder bore ``D`` (grid step ``search.cylinder_bore_step_m``), pulley radius ``r``, hose bore,
pump displacement, oil grade and motor rated power ``P``. The stages, each vectorised with
numpy broadcasting and each pruning by constraints before the next multiplies the grid:

1. **actuator** (``p × D × r``): cable from its breaking load at the relief's full-open pressure,
   effective area ``A_e = n π/4 (D² − d_c²)``; torque constraint ``A_e r p ≥ τ_max`` (the largest
   torque asked); kept: for each ``(p, r)`` the bores whose ``A_e r`` is within
   ``BORE_WINDOW`` of the smallest that carries the torque (a bigger bore at the same pressure
   and arm only adds mass, friction and flow).
2. **hydraulic chain** (× hose bore × displacement × oil) at the constraint points, cold oil
   (ambient: the device starts cold, as the bench does): pump pressure ``|Δp_p| ≤ p``, pump
   and motor speed limits, laminar hoses (``Re ≤ 2000``: the compiled actuator's hoses are
   laminar), pump pressure rating; then the duty-cycle sums every motor needs.
3. **motor** (× rated power): the winding's ``K`` is the largest that still reaches every
   constraint point at ``duty_max`` of the pack voltage at ``min_state_of_charge``
   (``v = K (T_m/k_m² + ω)``, so copper loss ``(T_m/k_m)²`` does not depend on ``K`` but the
   currents fall as ``K`` rises); the driver's current limit is the largest constraint current,
   so the stall torque is the torque asked. Motor thermal (mean loss ≤ its continuous
   rating) and peak (copper ≤ ``motor_peak_loss_ratio`` × continuous) limits, driver current,
   battery sized for the runtime energy and its C-rate, skin-safe pack surface temperature.
4. **exact evaluation** (:func:`evaluate_designs`) of the best screened designs (and the best
   per pressure and per oil, for the studies): oil at its steady temperature (fixed point with
   the pack's natural convection and radiation), the battery's Rint loss per sample, the
   winding and current limit recomputed with the actual voltage sag and hot and cold oil.
   Designs are ranked by total mass (one side: ankle parts + power supply at the waist).

The objective is mass alone: losses cost battery (and motor) mass through the runtime, so
``total mass`` is the mass + loss objective of the seed's tool.

Valve-controlled and digital circuits (``architecture = "valve" | "digital"``) are sized on the
same worn parts (:func:`_size_valve`, see its docstring); they are reported, not bench-tested:
the torque–velocity bench drives the pump-controlled kernel only.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

from afo_mj.design.design_models import (CHEMISTRIES, DesignAssumptions, SupplyFigures,
                                           cable_diameter_m, chain_steady, cylinder_masses,
                                           hose_wall_mass_kg_per_m, line_steady, motor_scaling,
                                           oil_viscosity_pa_s, oring_cross_section_m,
                                           pack_geometry, pack_thermal_resistance_k_w,
                                           pulley_mass_kg, pump_inertia_kg_m2, pump_mass_kg,
                                           servo_centre_leak_m3_s, supply_steady)
from afo_mj.design.design_requirements import (DesignError, DutyCycle, Requirements,
                                                 duty_cycle, load_requirements,
                                                 parse_requirements)
from afo_mj.hydraulics import laws
from afo_mj.hydraulics.battery import BatteryParams
from afo_mj.hydraulics.geometry import annulus_area_m2
from afo_mj.hydraulics.seal import cylinder_seal_law_args, seal_law_args
from afo_mj.hydraulics.fluid import FLUID_PRESETS, Fluid

__all__ = ["DesignError", "DesignResult", "load_requirements", "parse_requirements",
           "size_system", "evaluate_designs", "design_overrides", "design_params",
           "predict_bench", "mass_check", "guideline_studies", "hose_bore_study",
           "read_requirements", "compute_design", "CONSTRAINTS", "BORE_WINDOW",
           "quasi_static_device_torque_nm",
           "walk_work_check", "WALK_CHECK_SAMPLES"]

#: Bores kept per (pressure, arm): those whose ``A_e r`` is within this fraction of the smallest
#: that carries the torque (friction and line loss at speed need a little more).
BORE_WINDOW = 0.10
#: Laminar limit of the hoses (conduit module; the compiled actuator models laminar hoses).
RE_LAMINAR = 2000.0
#: Designs carried from the screening into the exact evaluation (best by screened mass).
N_EXACT = 240
#: Duty samples the screening evaluates (every k-th, weighted); the exact pass uses all.
SCREEN_SAMPLES = 32
#: A design whose mass bound exceeds the lightest found at its pressure and oil by more than
#: this fraction is not evaluated further (it cannot rank near the top).
BOUND_SLACK = 0.03
#: The screening keeps the pack this fraction of the allowed temperature rise below the limit.
SCREEN_TEMPERATURE_MARGIN = 0.02
#: Larger motors tried beside the screened one in the exact pass.
MOTOR_ALTERNATIVES = 2
#: Rounds and breadth of the local search around the lightest exact designs.
REFINE_ROUNDS = 3
REFINE_TOP = 6
#: Designs (lowest mass bounds) looked at in full to explain an infeasible motor stage.
DIAGNOSE_DESIGNS = 3000
#: Up to this many constraint points the screening's motor stage checks each exactly; a
#: profile's many points are screened through per-design envelope bounds.
ENVELOPE_EXACT_POINTS = 8

#: Samples of the written walk's stride in :func:`walk_work_check`.
WALK_CHECK_SAMPLES = 1000

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


# ----------------------------------------------------------------------------------------------
# common pieces
# ----------------------------------------------------------------------------------------------
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


# ----------------------------------------------------------------------------------------------
# exact evaluation of fully specified designs
# ----------------------------------------------------------------------------------------------
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


# ----------------------------------------------------------------------------------------------
# the screening search
# ----------------------------------------------------------------------------------------------
@dataclasses.dataclass
class DesignResult:
    """What :func:`size_system` found (its JSON form:
    :func:`afo_mj.outputs.design_report.build_summary`)."""

    requirements: Requirements
    assumptions: DesignAssumptions
    duty: DutyCycle
    feasible: bool
    designs: dict | None                 # evaluate_designs output for the ranked designs
    order: np.ndarray | None             # ranked feasible indices into ``designs``
    explanation: str | None
    binding: list[str]
    counts: dict                         # designs ruled out per constraint, per stage
    grid: dict
    screened: int
    wall_s: float
    best_limits: dict = dataclasses.field(default_factory=dict)

    def row(self, k: int = 0) -> dict:
        """The ``k``-th best design as a flat dict of scalars (SI units in the names)."""
        return _row(self.designs, int(self.order[k]), self.requirements)


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


def _pareto_samples(tau: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Indices of the samples the screening checks a profile's constraints at: per sign
    quadrant of ``(τ, θ̇)``, the Pareto fronts maximising ``(|τ|, |θ̇|)`` and ``(|τ|, −|θ̇|)``.
    Within a quadrant the pump pressure, flow, pump speed and motor current are monotone in
    ``|τ|`` and ``|θ̇|`` (rising in both where the ankle takes power; where it gives power back,
    rising in ``|τ|`` and falling in ``|θ̇|`` for the pressure), so their maxima lie on these
    fronts. The exact pass (:func:`evaluate_designs`) checks every sample."""
    keep = set()
    q = (np.sign(tau) >= 0).astype(int) * 2 + (np.sign(vel) >= 0).astype(int)
    for quad in range(4):
        idx = np.flatnonzero(q == quad)
        if idx.size == 0:
            continue
        at, av = np.abs(tau[idx]), np.abs(vel[idx])
        for sy in (1.0, -1.0):
            x, y = at, sy * av
            for j in range(idx.size):
                dom = (x >= x[j]) & (y >= y[j]) & ((x > x[j]) | (y > y[j]))
                if not np.any(dom):
                    keep.add(int(idx[j]))
    return np.array(sorted(keep), dtype=int)


def size_system(req: Requirements, assumptions: DesignAssumptions | None = None,
                n_exact: int = N_EXACT) -> DesignResult:
    """Search the design grid of ``req`` for the lightest feasible designs (module
    docstring). ``architecture = "valve" | "digital"`` goes to :func:`_size_valve`."""
    t0 = time.perf_counter()
    a = assumptions or DesignAssumptions()
    base = _base()
    duty = duty_cycle(req)
    grids = _grids(req)
    counts: dict[str, int] = {}
    limits: dict[str, Any] = {}
    t_need = float(np.max(np.abs(duty.constraint_torque_nm)))
    # ---- stage 1: actuator ------------------------------------------------------------------
    P, B, R = np.meshgrid(grids["pressure_pa"], grids["bore_m"], grids["arm_m"], indexing="ij")
    geo = actuator_geometry(P, B, R, req.range_of_motion_rad, a, base)
    ok_cable = geo["cable_m"] <= 0.5 * B
    # the servo valve needs its margin on top of the load pressure
    p_load = P - (_supply_figures().margin_pa if req.architecture == "valve" else 0.0)
    cap = np.where(ok_cable, geo["torque_per_pressure_m3"] * p_load, 0.0)
    ok_t = ok_cable & (cap >= t_need)
    counts["cable"] = int(np.count_nonzero(~ok_cable))
    counts["torque"] = int(np.count_nonzero(ok_cable & ~ok_t))
    j = int(np.argmax(cap))
    limits["torque"] = {"torque_nm": t_need, "max_torque_nm": float(cap.flat[j]),
                        "at_pressure_pa": float(P.flat[j]), "at_bore_m": float(B.flat[j]),
                        "at_arm_m": float(R.flat[j]),
                        "at_cable_m": float(geo["cable_m"].flat[j]),
                        "max_torque_per_pressure_m3": float(
                            geo["torque_per_pressure_m3"].flat[j]),
                        "needed_torque_per_pressure_m3": t_need / float(p_load.flat[j]),
                        "load_pressure_pa": float(p_load.flat[j])}
    if not np.any(ok_t):
        return _infeasible(req, a, duty, grids, counts, limits, ["torque"], t0, 0)
    aer = np.where(ok_t, geo["torque_per_pressure_m3"], np.inf)
    aer_min = aer.min(axis=1, keepdims=True)
    keep = ok_t & (aer <= aer_min * (1.0 + BORE_WINDOW))
    ip, ib, ir = np.nonzero(keep)
    act = {"pressure_pa": grids["pressure_pa"][ip], "bore_m": grids["bore_m"][ib],
           "arm_m": grids["arm_m"][ir]}
    # ---- stages 2 and 3: × hose × oil (line), × displacement (pump), × motor ---------------
    screened = ip.size * grids["hose_bore_m"].size * len(grids["oil"]) \
        * grids["displacement_m3_rev"].size
    cidx = (np.arange(duty.constraint_torque_nm.size) if req.profile == "corner"
            else _pareto_samples(duty.constraint_torque_nm, duty.constraint_velocity_rad_s))
    sc = _screen(act, req, duty, a, base, grids, cidx, counts, limits)
    if sc is None:
        return _infeasible(req, a, duty, grids, counts, limits, limits["stage2_binding"], t0,
                           screened)
    spec_f, best_m, best_mass = sc
    ok = np.isfinite(best_mass)
    if not np.any(ok):
        return _infeasible(req, a, duty, grids, counts, limits,
                           limits.get("motor_binding", []), t0, screened)
    # ---- stage 4: exact evaluation of the best (overall, per pressure, per oil) -------------
    cand = np.flatnonzero(ok)
    order = cand[np.argsort(best_mass[cand], kind="stable")]
    pick = list(order[:n_exact])
    for key in ("pressure_pa", "oil", "displacement_m3_rev", "hose_bore_m"):
        vals = spec_f[key][order]
        _, first = np.unique(vals, return_index=True)
        pick.extend(order[first])
        if key == "pressure_pa":          # a few per pressure for the studies
            for v in np.unique(vals):
                pick.extend(order[vals == v][:16])
    pick = np.unique(np.asarray(pick, dtype=int))
    # each picked design with its screened motor and the next larger ones (the exact pass may
    # find a little more heat than the screening: a larger motor sheds less copper loss)
    nmot = grids["motor_power_w"].size
    reps = [np.minimum(best_m[pick] + j, nmot - 1) for j in range(MOTOR_ALTERNATIVES + 1)]
    spec_x = {k: np.concatenate([v[pick]] * len(reps)) for k, v in spec_f.items()}
    spec_x["motor_power_w"] = grids["motor_power_w"][np.concatenate(reps)]
    ev = evaluate_designs(spec_x, req, duty, a, base)
    ev = _refine(ev, grids, req, duty, a, base)
    ev["feasible"] = ev["feasible"] & _lightest_motor_only(ev)
    feas = np.flatnonzero(ev["feasible"])
    if feas.size == 0:
        worst = {}
        for k, v in ev["margins"].items():
            worst[k] = int(np.count_nonzero(v < -1e-9))
        counts.update({f"exact:{k}": v for k, v in worst.items() if v})
        binding = [max(worst, key=worst.get)] if worst else []
        res = _infeasible(req, a, duty, grids, counts, limits, binding, t0, screened)
        res.designs = ev
        return res
    ranked = feas[np.argsort(ev["total_kg"][feas], kind="stable")]
    return DesignResult(requirements=req, assumptions=a, duty=duty, feasible=True, designs=ev,
                        order=ranked, explanation=None, binding=[], counts=counts,
                        grid={k: (list(map(float, v)) if k != "oil" else v)
                              for k, v in grids.items()},
                        screened=screened, wall_s=time.perf_counter() - t0, best_limits=limits)


_AXES = ("pressure_pa", "bore_m", "arm_m", "hose_bore_m", "displacement_m3_rev",
         "motor_power_w")


def _hydraulic_key(spec: dict, i: int) -> tuple:
    return tuple(round(float(spec[k][i]), 12) for k in _AXES[:-1]) + (int(spec["oil"][i]),)


def _lightest_motor_only(ev: dict) -> np.ndarray:
    """Mask keeping, per hydraulic design (everything but the motor), its lightest feasible
    motor."""
    sp = ev["spec"]
    mass = np.where(ev["feasible"], ev["total_kg"], np.inf)
    best: dict[tuple, int] = {}
    for i in range(mass.size):
        k = _hydraulic_key(sp, i)
        if k not in best or mass[i] < mass[best[k]]:
            best[k] = i
    keep = np.zeros(mass.size, dtype=bool)
    for i in best.values():
        keep[i] = np.isfinite(mass[i])
    return keep


def _concat(x, y):
    """Two :func:`evaluate_designs` outputs joined design-wise."""
    if isinstance(x, dict):
        return {k: _concat(x[k], y[k]) for k in x}
    if isinstance(x, tuple):
        return tuple(_concat(u, v) for u, v in zip(x, y))
    if isinstance(x, np.ndarray) and x.ndim >= 1:
        return np.concatenate([x, y])
    return x


def _refine(ev: dict, grids: dict, req, duty, a, base, rounds: int = REFINE_ROUNDS,
            top: int = REFINE_TOP) -> dict:
    """Local search around the lightest exactly evaluated designs: each design variable one
    grid step either way (every other oil), evaluated exactly, for a few rounds or until the
    lightest design stops improving (the screening's approximations can miss a neighbour)."""
    seen = {tuple(_hydraulic_key(ev["spec"], i)) + (round(float(ev["spec"]["motor_power_w"][i]),
                                                          9),)
            for i in range(ev["total_kg"].size)}
    gv = {k: np.asarray(grids[k]) for k in _AXES}
    noil = len(grids["oil"])
    for _ in range(rounds):
        mass = np.where(ev["feasible"], ev["total_kg"], np.inf)
        if not np.any(np.isfinite(mass)):
            return ev
        best_before = float(mass.min())
        tops = np.argsort(mass, kind="stable")[:top]
        tops = tops[np.isfinite(mass[tops])]
        new = {k: [] for k in _AXES + ("oil",)}
        for i in tops:
            cur = {k: float(ev["spec"][k][i]) for k in _AXES}
            cur["oil"] = int(ev["spec"]["oil"][i])
            cands = []
            for k in _AXES:
                j = int(np.argmin(np.abs(gv[k] - cur[k])))
                for dj in (-1, 1):
                    if 0 <= j + dj < gv[k].size:
                        c = dict(cur)
                        c[k] = float(gv[k][j + dj])
                        cands.append(c)
            for o in range(noil):
                if o != cur["oil"]:
                    c = dict(cur)
                    c["oil"] = o
                    cands.append(c)
            for c in cands:
                key = tuple(round(c[k], 12) for k in _AXES[:-1]) + (c["oil"],) \
                    + (round(c["motor_power_w"], 9),)
                if key in seen:
                    continue
                seen.add(key)
                for k in new:
                    new[k].append(c[k])
        if not new["oil"]:
            return ev
        spec_n = {k: np.asarray(v, dtype=int if k == "oil" else float) for k, v in new.items()}
        ev = _concat(ev, evaluate_designs(spec_n, req, duty, a, base))
        mass = np.where(ev["feasible"], ev["total_kg"], np.inf)
        if float(mass.min()) >= best_before - 1e-9:
            return ev
    return ev


def _screen(act, req, duty, a, base, grids, cidx, counts, limits):
    """Stages 2 and 3 (module docstring) on the actuator candidates ``act``.

    The line side (cylinders, hoses) depends on actuator × hose × oil, the pump side also on
    the displacement: groups ``g`` (actuator, hose, oil) × ``K`` displacements. Constraint
    points with cold oil (ambient), the duty's energy with the oil at the skin-safe limit
    (where the lightest designs end up). The duty sums use at most :data:`SCREEN_SAMPLES` samples
    (every k-th, weighted by its time). Designs are then evaluated in order of a lower bound on
    their mass (every part but motor and battery is known; the smallest motor; a battery holding at
    least the net ankle work plus the ankle-side losses for the runtime) and a design is skipped
    once its bound exceeds ``1 + BOUND_SLACK`` times the lightest design found at its pressure and
    oil (counted as ``bound``). The motor is chosen from the duty cycle's sufficient statistics:
    copper loss is quadratic in the motor torque ``T_p + c g``, ``g`` the reference motor
    friction and ``c`` its scale with rated power. Returns ``(spec, best_motor_index,
    best_mass)`` for the designs left after stage 2, or None when stage 2 leaves nothing."""
    fluids = _fluids(req, a)
    pu, mo, dr = base.pump, base.motor, base.driver
    mu_o = np.array([oil_viscosity_pa_s(f, req.ambient_temperature_k) for f in fluids])
    # the duty cycle's energy with the oil at the skin-safe limit, where the lightest designs
    # end up (the thin oil's pump slip is the heat that limits them)
    mu_hot = np.array([oil_viscosity_pa_s(f, req.max_surface_temperature_k) for f in fluids])
    rho_o = np.array([f.density_kg_m3 for f in fluids])
    na, nh, no = act["pressure_pa"].size, grids["hose_bore_m"].size, len(grids["oil"])
    disps = grids["displacement_m3_rev"]
    nk = disps.size
    dk = disps / (2.0 * math.pi)
    ia, ih, io = (x.ravel() for x in np.meshgrid(np.arange(na), np.arange(nh), np.arange(no),
                                                 indexing="ij"))
    geo = actuator_geometry(act["pressure_pa"], act["bore_m"], act["arm_m"],
                            req.range_of_motion_rad, a, base)
    p_g = act["pressure_pa"][ia]
    mu_g, rho_g = mu_o[io], rho_o[io]
    hb_g = grids["hose_bore_m"][ih]
    col = (slice(None), None)
    speed_lim = min(pu.max_speed_rad_s, a.motor_max_speed_rad_s)
    step = max(1, int(math.ceil(duty.torque_nm.size / SCREEN_SAMPLES)))
    tau_d = duty.torque_nm[::step]
    vel_d = duty.velocity_rad_s[::step]
    dt_d = duty.dt_s[::step] * (np.sum(duty.dt_s) / np.sum(duty.dt_s[::step]))
    ct, cv = duty.constraint_torque_nm[cidx], duty.constraint_velocity_rad_s[cidx]

    def line(g, tau, vel, mu=mu_g):
        i = ia[g]
        return line_steady(tau[None, :], vel[None, :], r=act["arm_m"][i][col],
                           ae=geo["effective_area_m2"][i][col], n_cyl=base.cylinders,
                           seal=tuple(np.asarray(x)[i][col] if np.ndim(x) else x
                                      for x in geo["seal"]),
                           g_leak=geo["leak_conductance_m3"][i][col],
                           hose_length_m=req.conduit_length_m, hose_bore_m=hb_g[g][col],
                           mu=mu[g][col], rho=rho_g[g][col])

    arch = req.architecture
    sf = _supply_figures() if arch != "pump" else None

    def pump(q, dp, mu, d, rho, w_set=None):
        return supply_steady(arch, q, dp, mu=mu, rho=rho, d=d, cs=pu.slip_coefficient,
                             cf=pu.coulomb_coefficient, cv=pu.viscous_coefficient,
                             t0=pu.drag_torque_nm, wc_pump=pu.smoothing_speed_rad_s, sf=sf,
                             w_set=w_set)

    mu_gh = mu_hot[io]
    ld = line(slice(None), tau_d, vel_d, mu_gh)                    # duty, line side (hot)
    # ---- stage 2: constraint points -----------------------------------------------------------
    ok_pp = p_g <= a.pump_max_pressure_pa
    cl = line(slice(None), ct, cv)
    margin = sf.margin_pa if arch == "valve" else 0.0
    dpm = (np.max(np.abs(cl["dp_p"]), axis=1) + margin) / p_g
    rem = np.max(cl["reynolds"], axis=1) / RE_LAMINAR
    ok_g = ok_pp & (dpm <= 1.0) & (rem <= 1.0)
    # digital: a constant pump speed giving the peak flow with the preset's margin
    w_set_gk = (sf.flow_margin * np.maximum(np.max(np.abs(cl["q"]), axis=1),
                                            np.max(np.abs(ld["q"]), axis=1))[:, None]
                / dk[None, :]) if arch == "digital" else None
    # pump speed at the constraint points (the supply's flow over the displacement, plus slip)
    if arch == "digital":
        wm = w_set_gk / speed_lim
    else:
        if arch == "valve":
            ps = np.maximum(np.abs(cl["dp_p"]) + sf.margin_pa, sf.rail_min_pa)
            qs = np.abs(cl["q"]) + servo_centre_leak_m3_s(ps, sf, rho_g[:, None])
        else:
            ps, qs = cl["dp_p"], cl["q"]
        wm = np.max(np.abs(laws.pump_speed_for_flow_rad_s(
            qs[:, None, :], ps[:, None, :], dk[None, :, None], pu.slip_coefficient, 0.0,
            mu_g[:, None, None])), axis=2) / speed_lim                   # (G, K)
    ok_gk = ok_g[:, None] & (wm <= 1.0)
    counts.update({"pump_pressure": int(np.count_nonzero(~ok_pp)) * nk,
                   "pressure": int(np.count_nonzero(dpm > 1.0)) * nk,
                   "laminar": int(np.count_nonzero(rem > 1.0)) * nk,
                   "pump_speed": int(np.count_nonzero(wm > 1.0))})
    limits["stage2_best_ratio"] = {"pressure": float(dpm.min()), "laminar": float(rem.min()),
                                   "pump_speed": float(wm.min())}
    limits["speed"] = _speed_limit_info(req, duty, grids, a, base, geo, act)
    if not np.any(ok_gk):
        passes = {"pump_pressure": np.broadcast_to(ok_pp[:, None], wm.shape),
                  "pressure": np.broadcast_to((dpm <= 1.0)[:, None], wm.shape),
                  "laminar": np.broadcast_to((rem <= 1.0)[:, None], wm.shape),
                  "pump_speed": wm <= 1.0}
        limits["stage2_binding"] = _drop_one(passes)
        return None
    gsel, ksel = np.nonzero(ok_gk)
    nf = gsel.size
    spec_f = {"pressure_pa": p_g[gsel], "bore_m": act["bore_m"][ia[gsel]],
              "arm_m": act["arm_m"][ia[gsel]], "hose_bore_m": hb_g[gsel],
              "displacement_m3_rev": disps[ksel], "oil": io[gsel]}
    # ---- masses known before the motor, and the lower bound ----------------------------------
    bat = _battery_figures(req)
    chem = bat["chemistry"]
    rt = _runtime(req, duty.stride_time_s)
    stride = duty.stride_time_s
    walk_frac = rt["walking_s"] / rt["total_s"]
    rho_f = rho_o[spec_f["oil"]]
    fixed = _budget_fixed(base, arch)
    gi = ia[gsel]
    cyl = cylinder_masses(spec_f["bore_m"], geo["stroke_m"][gi], geo["cable_m"][gi],
                          geo["wall_pressure_pa"][gi], rho_f, base.cylinder.dead_volume_a_m3, a)
    hoses = 2.0 * req.conduit_length_m * (hose_wall_mass_kg_per_m(
        spec_f["hose_bore_m"], geo["wall_pressure_pa"][gi], a)
        + rho_f * annulus_area_m2(spec_f["hose_bore_m"], 0.0))
    pump_kg = pump_mass_kg(spec_f["displacement_m3_rev"], a)
    base_kg = (base.cylinders * cyl["total_kg"] + geo["pulley_kg"][gi] + hoses + pump_kg
               + sum(fixed.values()))
    waist_fix = _waist_fixed(fixed)
    row_of = np.arange(ia.size)
    e_ankle = ((ld["p_mech"] + ld["p_line"] + ld["p_seal"] + ld["p_leak"]) @ dt_d)
    e_lb = rt["strides"] * np.maximum(e_ankle[row_of[gsel]], 0.0)
    kg_per_j = 1.0 / bat["usable_j_per_ah"] * bat["full_j_per_ah"] / 3600.0 \
        / (chem.cell_specific_energy_wh_kg * a.battery_pack_factor)
    powers = grids["motor_power_w"]
    # the smallest motor whose short-time copper rating carries the peak pump torque:
    # (T/k_m)² ≤ ratio · frac · P with k_m = k_ref s^α, P = P_ref s  →  s^(1+2α) ≥ …
    if ct.size <= ENVELOPE_EXACT_POINTS:
        cp_f = pump(cl["q"][gsel], cl["dp_p"][gsel], mu_g[gsel][:, None], dk[ksel][:, None],
                    rho_g[gsel][:, None],
                    None if w_set_gk is None else w_set_gk[gsel, ksel][:, None])
        t_pk2 = np.max(cp_f["t_p"] ** 2, axis=1)
    else:
        # a profile: the motor is screened against per-design bounds of its envelope (the
        # exact pass checks every sample). Pump torque d Δp + (C_f d |Δp| + T_0) + C_v d μ ω
        # rises with |Δp| and |ω|: the largest pressure and speed bound it from above, and
        # with the friction taken off, from below (for the mass bound).
        if arch == "valve":
            p_need = np.max(np.maximum(np.abs(cl["dp_p"]) + sf.margin_pa, sf.rail_min_pa),
                            axis=1)
        else:
            p_need = np.max(np.abs(cl["dp_p"]), axis=1)
        pf = p_need[gsel]
        d_f, mu_f = dk[ksel], mu_g[gsel]
        w_f = wm[gsel, ksel] * speed_lim
        if arch == "digital":      # the open on/off valve's drop for the pump's flow
            pf = np.maximum(pf, laws.orifice_dp_for_flow_pa(d_f * w_f, sf.onoff_area_m2,
                                                            sf.onoff_cd, rho_g[gsel],
                                                            sf.onoff_pcr_pa))
        cf_, t0_, cv_ = pu.coulomb_coefficient, pu.drag_torque_nm, pu.viscous_coefficient
        t_ub = d_f * pf + cf_ * d_f * (pf + 1e4) + t0_ + cv_ * d_f * mu_f * w_f
        t_lb = np.maximum(d_f * pf * (1.0 - cf_) - t0_ - cv_ * d_f * mu_f * w_f, 0.0)
        cp_f = {"t_p": t_ub[:, None], "w_p": w_f[:, None]}
        t_pk2 = t_lb ** 2
    s_min = (t_pk2 / (a.motor_constant_ref_nm_per_sqrt_w ** 2 * a.motor_peak_loss_ratio
                      * a.motor_continuous_loss_fraction * a.motor_reference_power_w)) \
        ** (1.0 / (1.0 + 2.0 * a.motor_constant_exponent))
    p_lb = np.maximum(s_min * a.motor_reference_power_w, powers[0])
    lb = base_kg + p_lb / a.motor_specific_power_w_kg + np.maximum(
        e_lb * kg_per_j, a.battery_min_capacity_ah * bat["full_j_per_ah"] / 3600.0
        / (chem.cell_specific_energy_wh_kg * a.battery_pack_factor))
    group_key = (np.searchsorted(grids["pressure_pa"], spec_f["pressure_pa"]) * no
                 + spec_f["oil"])
    incumbent = np.full(group_key.max() + 1, np.inf)
    # ---- stage 3 in order of the bound --------------------------------------------------------
    order = np.argsort(lb, kind="stable")
    best_mass = np.full(nf, np.inf)
    best_m = np.zeros(nf, dtype=int)
    mfails = {k: 0 for k in ("driver_current", "motor_peak", "motor_thermal", "winding",
                             "surface_temperature")}
    def gmot(w):
        """Motor friction at P_ref (:func:`~afo_mj.hydraulics.laws.motor_friction_torque_nm`)."""
        return laws.motor_friction_torque_nm(w, mo.coulomb_torque_nm,
                                             mo.viscous_coefficient_nm_s_rad,
                                             mo.smoothing_speed_rad_s)

    def chunk_inputs(idx):
        """Duty sums and constraint-point pump torque/speed of designs ``idx``."""
        rows = row_of[gsel[idx]]
        mu_i = mu_gh[gsel[idx]][:, None]
        d_i = dk[ksel[idx]][:, None]
        pp_ = pump(ld["q"][rows], ld["dp_p"][rows], mu_i, d_i, rho_g[gsel[idx]][:, None],
                   None if w_set_gk is None else w_set_gk[gsel[idx], ksel[idx]][:, None])
        tp, w = pp_["t_p"], pp_["w_p"]
        gm = gmot(w)
        su = {"pp": (tp * tp) @ dt_d, "pg": (tp * gm) @ dt_d, "gg": (gm * gm) @ dt_d,
              "pw": (tp * w) @ dt_d, "gw": (gm * w) @ dt_d,
              "pumpline": (pp_["p_pump_vol"] + pp_["p_pump_mech"] + pp_["p_valve"]) @ dt_d
              + ld["p_line"][rows] @ dt_d, "valve_el": pp_["p_valve_el"] @ dt_d,
              "maxpw": np.max(tp * w, axis=1), "maxtp2": np.max(tp * tp, axis=1)}
        tcw = cp_f["t_p"][idx]
        ww = cp_f["w_p"][idx]
        return su, tcw, ww, gmot(ww)

    chunk_max = max(256, int(2e6 // tau_d.size))
    chunk = 512
    pruned = 0
    t_min = np.inf
    pos = 0
    while pos < nf:
        idx = order[pos:pos + chunk]
        pos += chunk
        chunk = min(2 * chunk, chunk_max)
        live = lb[idx] <= incumbent[group_key[idx]] * (1.0 + BOUND_SLACK)
        pruned += int(np.count_nonzero(~live))
        idx = idx[live]
        if idx.size == 0:
            continue
        bm, bmass, tmn = _motor_stage(*chunk_inputs(idx), base_kg[idx], pump_kg[idx],
                                      waist_fix, powers, req, a, dr, bat, chem, rt, stride,
                                      walk_frac, mfails,
                                      incumbent[group_key[idx]] * (1.0 + BOUND_SLACK))
        t_min = min(t_min, tmn)
        best_m[idx], best_mass[idx] = bm, bmass
        np.minimum.at(incumbent, group_key[idx], bmass)
    if not np.any(np.isfinite(best_mass)):
        # why: every motor of the grid for the designs with the lowest bounds, all constraints
        idx = order[:DIAGNOSE_DESIGNS]
        diag = _motor_stage(*chunk_inputs(idx), base_kg[idx], pump_kg[idx], waist_fix, powers,
                            req, a, dr, bat, chem, rt, stride, walk_frac,
                            {k: 0 for k in mfails}, np.full(idx.size, np.inf), diagnose=True)
        limits["motor_binding"] = _drop_one(diag["passes"])
        limits["motor_ratios"] = {k: float(np.min(v)) for k, v in diag["ratios"].items()}
    counts.update(mfails)
    counts["bound"] = pruned
    fin = np.isfinite(best_mass)
    limits["bound_gap_kg"] = float(np.median(best_mass[fin] - lb[fin])) if np.any(fin) else None
    limits["motor"] = {"min_surface_temperature_k": t_min, "largest_motor_w": float(powers[-1]),
                       "designs_after_stage2": int(nf)}
    return spec_f, best_m, best_mass


def _motor_stage(sums, tcw, ww, gcw, base_kg, pump_kg, waist_fix, powers, req, a, dr, bat,
                 chem, rt, stride, walk_frac, mfails, cap_kg, diagnose: bool = False):
    """Stage 3 for one chunk of designs: every motor of the grid (winding from the voltage
    envelope of the constraint points, battery from the duty energy), then the surface
    temperature motor by motor in order of mass until one passes; a motor that makes the design
    heavier than ``cap_kg`` (the bound of its group) is not looked at. Returns
    ``(best motor index, best mass, lowest surface temperature seen)``; with ``diagnose`` every
    constraint of every (design, motor) instead: ``{"passes": {name: bool (n, motors)},
    "ratios": {name: value / limit}}``."""
    nf = base_kg.size
    nm = powers.size
    ratios = {k: np.zeros((nf, nm)) for k in ("driver_current", "motor_peak", "motor_thermal",
                                               "winding", "surface_temperature")}
    totals = np.full((nf, nm), np.inf)
    heats = np.zeros((nf, nm))
    waists = np.zeros((nf, nm))
    vavail0 = dr.max_duty * bat["v_oc_min"] * 0.95
    for m, pw in enumerate(powers):
        ms = motor_scaling(pw, a)
        km = float(ms["motor_constant_nm_per_sqrt_w"])
        cfr = (pw / a.motor_reference_power_w) ** a.motor_friction_exponent
        tm_c = tcw + cfr * gcw
        x_env = np.max(np.abs(tm_c / km ** 2 + ww), axis=1)
        k_t = vavail0 / x_env
        r_w = (k_t / km) ** 2
        tpk2 = np.max(tm_c * tm_c, axis=1)
        i_lim = np.sqrt(tpk2) / k_t
        quad = sums["pp"] + 2 * cfr * sums["pg"] + cfr ** 2 * sums["gg"]
        e_cu = quad / km ** 2
        e_mf = cfr * sums["gw"]
        e_drv = dr.on_resistance_ohm * quad / k_t ** 2 + dr.quiescent_power_w * stride
        e_bus = sums["pw"] + e_mf + e_cu + e_drv + sums["valve_el"]
        e_chem = e_bus / 0.97
        e_run = rt["strides"] * e_chem + rt["idle_s"] * dr.quiescent_power_w
        p_peak = sums["maxpw"] + sums["maxtp2"] / km ** 2 + dr.quiescent_power_w
        cap = np.maximum(np.maximum(e_run / bat["usable_j_per_ah"],
                                    p_peak / bat["v_oc_min"] / chem.max_c_rate_per_h),
                         a.battery_min_capacity_ah)
        batt_kg = cap * bat["full_j_per_ah"] / 3600.0 / (chem.cell_specific_energy_wh_kg
                                                         * a.battery_pack_factor)
        c_drv = i_lim <= a.driver_max_current_a
        c_pk = tpk2 / km ** 2 <= a.motor_peak_loss_ratio * ms["continuous_loss_w"]
        c_th = (e_cu + e_mf) / stride <= ms["continuous_loss_w"]
        c_wd = (k_t <= 10.0) & (r_w <= 100.0)
        for k_, c_ in (("driver_current", c_drv), ("motor_peak", c_pk),
                       ("motor_thermal", c_th), ("winding", c_wd)):
            mfails[k_] += int(np.count_nonzero(~c_))
        good = c_drv & c_pk & c_th & c_wd
        if diagnose:
            ratios["driver_current"][:, m] = i_lim / a.driver_max_current_a
            ratios["motor_peak"][:, m] = tpk2 / km ** 2 / (a.motor_peak_loss_ratio
                                                           * ms["continuous_loss_w"])
            ratios["motor_thermal"][:, m] = (e_cu + e_mf) / stride / ms["continuous_loss_w"]
            ratios["winding"][:, m] = np.maximum(k_t / 10.0, r_w / 100.0)
            good = np.ones(nf, dtype=bool)
        totals[:, m] = np.where(good, base_kg + ms["mass_kg"] + batt_kg, np.inf)
        heats[:, m] = walk_frac * ((e_chem - e_bus) + e_drv + e_cu + e_mf
                                   + sums["pumpline"] + sums["valve_el"]) / stride \
            + (1.0 - walk_frac) * dr.quiescent_power_w
        waists[:, m] = batt_kg + ms["mass_kg"] + pump_kg + waist_fix
    totals[totals > cap_kg[:, None]] = np.inf
    # a little margin below the limit: the exact pass finds slightly more heat
    t_limit = req.max_surface_temperature_k - SCREEN_TEMPERATURE_MARGIN * (
        req.max_surface_temperature_k - req.ambient_temperature_k)
    if diagnose:
        geom = pack_geometry(waists, a)
        t_s, _ = pack_thermal_resistance_k_w(heats, geom["diameter_m"], geom["exposed_area_m2"],
                                             req.ambient_temperature_k, a, iterations=3)
        ratios["surface_temperature"][:] = (t_s - req.ambient_temperature_k) / (
            req.max_surface_temperature_k - req.ambient_temperature_k)
        passes = {k: v <= 1.0 for k, v in ratios.items()}
        passes["surface_temperature"] = t_s <= t_limit
        return {"passes": passes, "ratios": ratios, "surface_temperature_k": t_s}
    best_mass = np.full(nf, np.inf)
    best_m = np.zeros(nf, dtype=int)
    cand = np.flatnonzero(np.isfinite(totals).any(axis=1))
    t_min = np.inf
    while cand.size:
        m = np.argmin(totals[cand], axis=1)
        tot = totals[cand, m]
        live = np.isfinite(tot)
        cand, m, tot = cand[live], m[live], tot[live]
        if cand.size == 0:
            break
        geom = pack_geometry(waists[cand, m], a)
        t_s, _ = pack_thermal_resistance_k_w(heats[cand, m], geom["diameter_m"],
                                             geom["exposed_area_m2"],
                                             req.ambient_temperature_k, a, iterations=3)
        t_min = min(t_min, float(t_s.min()))
        passed = t_s <= t_limit
        mfails["surface_temperature"] += int(np.count_nonzero(~passed))
        best_mass[cand[passed]] = tot[passed]
        best_m[cand[passed]] = m[passed]
        totals[cand[~passed], m[~passed]] = np.inf
        cand = cand[~passed]
    return best_m, best_mass, t_min


def _speed_limit_info(req, duty, grids, a, base, geo, spec) -> dict:
    """The flow the fastest constraint point needs and the largest pump's flow at the speed
    limit (for the explanation of an infeasible speed)."""
    v = float(np.max(np.abs(duty.constraint_velocity_rad_s)))
    aer = np.asarray(geo["torque_per_pressure_m3"])
    q_need = float(aer.min()) * v
    speed_lim = min(base.pump.max_speed_rad_s, a.motor_max_speed_rad_s)
    q_max = float(grids["displacement_m3_rev"].max()) / (2.0 * math.pi) * speed_lim
    return {"velocity_rad_s": v, "flow_needed_m3_s": q_need, "largest_flow_m3_s": q_max,
            "speed_limit_rad_s": speed_lim}


def _drop_one(passes: dict) -> list[str]:
    """The binding constraints of a stage where no design passes them all. ``passes``:
    name → bool array (designs, alternatives), an alternative being e.g. a motor of the grid.
    A constraint binds if dropping it alone would let some design through (ordered by how many);
    if no single one does, those that fail in the closest design, the (design, alternative)
    with the fewest failures."""
    names = list(passes)
    stack = np.stack([np.asarray(passes[n], dtype=bool) for n in names])   # (c, n, alt)
    out = []
    for j, n in enumerate(names):
        others = np.delete(stack, j, axis=0).all(axis=0)
        k = int(np.count_nonzero(others.any(axis=-1)))
        if k:
            out.append((k, n))
    if out:
        return [n for _, n in sorted(out, reverse=True)]
    fails = (~stack).sum(axis=0)
    i = np.unravel_index(int(np.argmin(fails)), fails.shape)
    return [n for j, n in enumerate(names) if not stack[(j,) + i]]


# ----------------------------------------------------------------------------------------------
# infeasibility
# ----------------------------------------------------------------------------------------------
def _infeasible(req, a, duty, grids, counts, limits, binding, t0, screened) -> DesignResult:
    return DesignResult(requirements=req, assumptions=a, duty=duty, feasible=False, designs=None,
                        order=None, explanation=explain(req, grids, counts, limits, binding, a),
                        binding=list(binding), counts=counts,
                        grid={k: (list(map(float, v)) if k != "oil" else v)
                              for k, v in grids.items()},
                        screened=screened, wall_s=time.perf_counter() - t0, best_limits=limits)


def explain(req: Requirements, grids: dict, counts: dict, limits: dict, binding,
            a: DesignAssumptions) -> str:
    """A sentence per binding constraint, with the numbers that bind."""
    out = []
    plo, phi = req.pressure_range_pa
    for name in binding[:3]:
        if name == "torque":
            t = limits["torque"]
            pl = t.get("load_pressure_pa", phi)
            via = ("" if pl == phi else f" ({phi / 1e6:.1f} MPa less the servo valve's "
                   f"{(phi - pl) / 1e6:.1f} MPa margin)")
            out.append(
                f"torque {t['torque_nm']:.0f} N·m needs A_e r ≥ "
                f"{t['torque_nm'] / pl:.3g} m³ at {pl / 1e6:.1f} MPa{via} (the highest "
                f"operating pressure allowed); the largest bore "
                f"{grids['bore_m'].max() * 1e3:.1f} mm "
                f"(with a {t['at_cable_m'] * 1e3:.1f} mm cable) and arm "
                f"{grids['arm_m'].max() * 1e3:.0f} mm give A_e r = "
                f"{t['max_torque_per_pressure_m3']:.3g} m³, {t['max_torque_nm']:.0f} N·m at most"
                f" — raise operating_pressure_pa, search.cylinder_bore_range_m or "
                f"moment_arm_m [constraint: torque]")
        elif name == "cable":
            out.append("no bore holds a cable strong enough for its own piston force "
                       "[constraint: cable]")
        elif name == "pump_pressure":
            out.append(f"the operating pressure {plo / 1e6:.1f} MPa exceeds the pump rating "
                       f"{a.pump_max_pressure_pa / 1e6:.1f} MPa [constraint: pump_pressure]")
        elif name == "pressure":
            r_ = limits.get("stage2_best_ratio", {}).get("pressure", math.nan)
            out.append(f"at speed, seal friction and line loss (and a servo valve's margin) add "
                       f"to the load: the best design needs {r_:.3f} × the operating pressure "
                       f"at a constraint point — widen search.cylinder_bore_range_m or "
                       f"moment_arm_m [constraint: pressure]")
        elif name == "pump_speed":
            s = limits["speed"]
            out.append(
                f"speed {math.degrees(s['velocity_rad_s']):.0f} deg/s needs a pump flow of "
                f"{s['flow_needed_m3_s'] * 6e4:.2f} L/min with the smallest A_e r; the largest "
                f"pump {grids['displacement_m3_rev'].max() * 1e6:.2f} cm³/rev at the "
                f"{s['speed_limit_rad_s']:.0f} rad/s speed limit gives "
                f"{s['largest_flow_m3_s'] * 6e4:.2f} L/min — widen "
                f"search.pump_displacement_range_m3_rev [constraint: pump_speed]")
        elif name == "laminar":
            r_ = limits.get("stage2_best_ratio", {}).get("laminar", math.nan)
            out.append(f"even the widest hose {grids['hose_bore_m'].max() * 1e3:.1f} mm runs "
                       f"turbulent: Reynolds number {r_ * RE_LAMINAR:.0f} > {RE_LAMINAR:.0f} — "
                       f"widen search.hose_bore_range_m [constraint: laminar]")
        elif name == "surface_temperature":
            tmin = limits.get("motor", {}).get("min_surface_temperature_k", math.nan)
            rr = limits.get("motor_ratios", {}).get(name)
            if rr is not None:
                tmin = req.ambient_temperature_k + rr * (req.max_surface_temperature_k
                                                         - req.ambient_temperature_k)
            out.append(f"even the coolest design and motor tried reach a pack surface of "
                       f"{tmin:.1f} K "
                       f"({tmin - 273.15:.1f} °C) > the skin-safe "
                       f"{req.max_surface_temperature_k:.1f} K: the duty's losses cannot leave "
                       f"the pack by natural convection and radiation "
                       f"[constraint: surface_temperature]")
        elif name in ("motor_thermal", "motor_peak"):
            rr = limits.get("motor_ratios", {}).get(name, math.nan)
            what = ("mean loss over the duty cycle" if name == "motor_thermal"
                    else "peak copper loss")
            out.append(f"no motor of {grids['motor_power_w'].min():.0f}–"
                       f"{grids['motor_power_w'].max():.0f} W sheds the {what} within its "
                       f"rating: at best {rr:.2f} × the rating (the power asked, "
                       f"{_rated_power(req):.0f} W, is too much for the motor range) — widen "
                       f"search.motor_power_range_w or lower the requirement "
                       f"[constraint: {name}]")
        elif name == "driver_current":
            rr = limits.get("motor_ratios", {}).get(name, math.nan)
            out.append(f"the current limit would be at least {rr:.2f} × the driver's "
                       f"{a.driver_max_current_a:.0f} A [constraint: driver_current]")
        elif name == "winding":
            out.append("no realisable winding (K ≤ 10 N·m/A, R ≤ 100 Ω) [constraint: winding]")
        else:
            out.append(f"[constraint: {name}]")
    if not out:
        out.append("no design met every constraint")
    return "infeasible: " + "; ".join(out)


# ----------------------------------------------------------------------------------------------
# the written device
# ----------------------------------------------------------------------------------------------
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


# ----------------------------------------------------------------------------------------------
# studies
# ----------------------------------------------------------------------------------------------
def hose_bore_study(result: DesignResult, k: int = 0, bores=None) -> dict:
    """The hose bore trade-off of the ``k``-th best design: only the hose bore changes, the
    battery is re-sized for the energy the line loss costs. ``total_kg`` holds the motor too
    (the pure trade-off: hose wall and oil mass against the battery that pays for the viscous
    loss, the mass + loss objective); ``total_reoptimised_kg`` lets each bore take its lightest
    feasible motor of the grid (inf where none is feasible) and ``feasible`` says whether the
    held-motor design meets every constraint."""
    ev, i = result.designs, int(result.order[k])
    req = result.requirements
    bores = np.asarray(bores if bores is not None else np.geomspace(
        *req.search.hose_bore_range_m, 25), dtype=float)
    spec = {key: np.repeat(np.asarray(v)[i], bores.size) for key, v in ev["spec"].items()}
    spec["hose_bore_m"] = bores
    e2 = evaluate_designs(spec, req, result.duty, result.assumptions)
    powers = np.asarray(result.grid["motor_power_w"])
    spec_m = {key: np.repeat(v, powers.size) for key, v in spec.items()}
    spec_m["motor_power_w"] = np.tile(powers, bores.size)
    e3 = evaluate_designs(spec_m, req, result.duty, result.assumptions)
    m3 = np.where(e3["feasible"], e3["total_kg"], np.inf).reshape(bores.size, powers.size)
    return {"hose_bore_m": bores, "total_kg": e2["total_kg"],
            "battery_kg": e2["mass"]["battery"], "hoses_kg": e2["mass"]["hoses"],
            "line_loss_j_per_stride": e2["energy_j"]["line"],
            "system_efficiency": e2["system_efficiency"], "feasible": e2["feasible"],
            "surface_temperature_k": e2["surface_temperature_k"],
            "peak_reynolds": e2["peak_reynolds"], "total_reoptimised_kg": m3.min(axis=1),
            "motor_reoptimised_w": powers[np.argmin(m3, axis=1)]}


def _best_by(result: DesignResult, key: str) -> dict:
    """The lightest feasible exact-evaluated design per value of ``spec[key]``."""
    ev = result.designs
    vals = ev["spec"][key]
    out = {}
    for v in np.unique(vals):
        sel = np.flatnonzero((vals == v) & ev["feasible"])
        if sel.size:
            out[v.item() if hasattr(v, "item") else v] = int(sel[np.argmin(ev["total_kg"][sel])])
    return out


def _study_row(result: DesignResult, i: int) -> dict:
    row = _row(result.designs, i, result.requirements)
    return {"operating_pressure_pa": row["operating_pressure_pa"], "oil": row["oil"],
            "rated_output_power_w": row["rated_output_power_w"],
            "total_kg": row["total_kg"], "ankle_kg": row["ankle_kg"],
            "waist_kg": row["waist_kg"], "system_efficiency": row["system_efficiency"],
            "pump_efficiency": row["efficiency"]["pump"],
            "motor_efficiency": row["efficiency"]["motor"],
            "lines_efficiency": row["efficiency"]["lines"],
            "cylinders_efficiency": row["efficiency"]["cylinders"],
            "hydraulic_power_density_w_kg": row["hydraulic_power_density_w_kg"],
            "system_energy_density_wh_kg": row["system_energy_density_wh_kg"],
            "cylinder_bore_m": row["cylinder_bore_m"], "pulley_radius_m": row["pulley_radius_m"],
            "hose_bore_m": row["hose_bore_m"],
            "pump_displacement_m3_rev": row["pump_displacement_m3_rev"],
            "motor_rated_power_w": row["motor_rated_power_w"],
            "surface_temperature_k": row["surface_temperature_k"],
            "runtime_h": row["runtime_h"]}


def guideline_studies(req: Requirements, assumptions: DesignAssumptions | None = None,
                      pressure_range_pa=(4e6, 21e6), pressure_points: int = 8,
                      power_factors=(0.25, 0.5, 1.0, 2.0, 3.0)) -> dict:
    """The seed's design-guideline studies on ``req``: for each operating pressure (a sweep
    over ``pressure_range_pa``), each oil grade and each output power (the requirement's
    speed, or profile torque, scaled by ``power_factors``), the lightest feasible design's
    mass, efficiencies, hydraulic power density (rated output power / mass of motor, pump,
    manifold, hoses, cylinders and pulley) and system energy density (positive work over the
    runtime / total mass). The studies search a coarser grid than the design itself (at most
    12 motors, 7 arms, 60 duty samples). Returns
    ``{"pressure": [rows], "oil": [rows], "power": [rows]}``.
    """
    a = assumptions or DesignAssumptions()
    out = {"pressure": [], "oil": [], "power": []}
    g = req.search
    coarse = dataclasses.replace(                 # the studies' grid: coarser than the design's
        g, motor_power_points=min(g.motor_power_points, 12),
        moment_arm_points=min(g.moment_arm_points, 7),
        duty_samples=min(g.duty_samples, 60))
    req = req.with_changes(search=coarse)
    sweep = req.with_changes(pressure_range_pa=tuple(pressure_range_pa),
                             search=dataclasses.replace(coarse,
                                                        pressure_points=pressure_points))
    res = size_system(sweep, a, n_exact=120)
    if res.feasible:
        for p, i in sorted(_best_by(res, "pressure_pa").items()):
            out["pressure"].append(_study_row(res, i))
        for o, i in sorted(_best_by(res, "oil").items()):
            out["oil"].append(_study_row(res, i))
    for f in power_factors:
        if req.profile == "corner":
            r2 = req.with_changes(peak_velocity_rad_s=req.peak_velocity_rad_s * f)
        elif req.profile == "normative":
            r2 = req.with_changes(torque_fraction=req.torque_fraction * f)
        else:
            r2 = req.with_changes(profile_torque_nm=tuple(np.asarray(req.profile_torque_nm) * f))
        rr = size_system(r2, a, n_exact=40)
        row = {"power_factor": f, "rated_output_power_w": _rated_power(r2, rr.duty),
               "feasible": rr.feasible}
        if rr.feasible:
            row.update(_study_row(rr, int(rr.order[0])))
        else:
            row["binding"] = rr.binding
        out["power"].append(row)
    return out


# ----------------------------------------------------------------------------------------------
# the whole design (the files: afo_mj.app.design)
# ----------------------------------------------------------------------------------------------
def read_requirements(requirements_path, overrides=()) -> tuple[Requirements, str]:
    """Read and validate a requirements file; returns ``(requirements, text as read)``.

    ``overrides``: ``key=value`` strings as for ``afo-mj run --set`` (e.g.
    ``requirement.runtime_h=3``), applied before validation (``text`` then holds the document
    with them applied). Raises :class:`DesignError` for an unreadable file, a bad override or
    invalid requirements."""
    from pathlib import Path

    path = Path(requirements_path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DesignError(f"{path}: cannot read the requirements file "
                          f"({exc.strerror or exc})") from None
    if overrides:
        import tomllib

        from afo_mj.design.design_requirements import toml_dumps
        from afo_mj.scenarios.walk_scenario import ScenarioError, apply_overrides
        try:
            doc = apply_overrides(tomllib.loads(text), overrides, str(path))
        except (ScenarioError, tomllib.TOMLDecodeError) as exc:
            raise DesignError(str(exc)) from None
        text = toml_dumps(doc)
    req = parse_requirements(text, origin=str(path), default_name=path.stem, source_path=path)
    return req, text


def compute_design(req: Requirements, *, studies: bool = True, verify: bool = False) -> dict:
    """Everything ``afo-mj design`` computes, nothing written (the files are written by
    :func:`afo_mj.app.design.design` through :mod:`afo_mj.outputs.design_report`).

    Searches the designs (:func:`size_system`); when feasible, runs the design-guideline
    studies (``studies``, :func:`guideline_studies`) and the hose-bore trade-off
    (:func:`hose_bore_study`); for a pump-controlled design, derives the written device
    (:func:`design_params`, :func:`predict_bench`, :func:`mass_check`), parses the scenarios
    about to be written as ``afo-mj run`` will and checks the walk (:func:`walk_work_check`,
    quasi-static, no simulation: a device that does net negative work on the ankle brakes the
    walker, reported as ``written["walk_check"]["warning"]``). ``verify=True`` also runs the
    torque–velocity bench on the written parameters.

    Returns ``{"result": DesignResult, "written": dict | None (row, overrides, params,
    predicted_bench, mass_check, walk_check), "study": dict | None, "hose": dict | None,
    "bench": dict | None (simulated stall torque, no-load speed, energy error), "wall_s":
    float}``. An infeasible requirement is not an error (``result.feasible`` False, with its
    explanation)."""
    t0 = time.perf_counter()
    result = size_system(req)
    study = guideline_studies(req) if studies and result.feasible else None
    hose = hose_bore_study(result) if result.feasible else None
    bench = None
    written = None
    if result.feasible and req.architecture == "pump":
        row = result.row(0)
        ov, params = design_params(row, req, result.assumptions)
        written = {"row": row, "overrides": ov, "params": params,
                   "predicted_bench": predict_bench(params),
                   "mass_check": mass_check(row, params)}
        _validate_written(req, written)
        if verify:
            from afo_mj.experiments.hafo_bench import torque_velocity
            s, _ = torque_velocity(params, velocities_deg_s=(0.0,))
            bench = {"stall_torque_nm": s["stall_torque_nm"],
                     "no_load_speed_deg_s": s["no_load_speed_deg_s"],
                     "energy_error_max": s["energy_error_max"]}
    return {"result": result, "written": written, "study": study, "hose": hose,
            "bench": bench, "wall_s": time.perf_counter() - t0}


def _validate_written(req: Requirements, written: dict) -> None:
    """Parse the scenarios about to be written as ``afo-mj run`` will (a failure here is a bug
    of the tool, reported as such, not a bad requirement)."""
    from afo_mj.design.design_requirements import toml_dumps
    from afo_mj.design.design_scenarios import bench_scenario, walk_scenario
    from afo_mj.scenarios.bench_scenario import parse_bench_scenario
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, parse_scenario
    ov = written["overrides"]
    try:
        parse_bench_scenario(toml_dumps(bench_scenario(req, ov)), origin="design_bench.toml")
        sc = parse_scenario(toml_dumps(walk_scenario(
            req, ov, written["predicted_bench"]["stall_torque_nm"])), origin="design_walk.toml")
        cfg = device_config(sc)
    except ScenarioError as exc:
        raise RuntimeError(f"afo-mj design wrote a scenario afo-mj run rejects: {exc}") from exc
    written["walk_check"] = walk_work_check(sc, cfg, written["predicted_bench"])


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


def _oil_resistance(row: dict) -> float:
    """The resistance to write as the simulator's ``thermal_resistance_k_w``. The design's pack
    is one thermal node holding oil, motor, driver and cells; the simulator's oil node receives
    only the oil's own heat (pump, lines, seals) and sends the motor's and driver's straight to
    the ambient. Writing ``R_pack · Q_pack / Q_oil`` makes the simulator's steady oil
    temperature the design's pack temperature (clipped to the parameter's range)."""
    q_oil = row["heat_to_oil_w"]
    r = row["pack_resistance_k_w"] * row["heat_w"] / q_oil if q_oil > 1e-9 else 1e3
    return float(min(max(r, 0.01), 1e3))
