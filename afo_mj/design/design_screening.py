"""Stages 2 and 3 of the design search: screening the hydraulic chain and the motor.

:func:`_screen` takes the actuator candidates of stage 1 (:mod:`afo_mj.design.design_search`)
and multiplies them by hose bore, oil and pump displacement at the constraint points (cold oil),
then picks each design's lightest motor from the duty cycle's sufficient statistics
(:func:`_motor_stage`), visiting designs in order of a lower bound on their mass. Both stages
evaluate the same steady-state laws as the exact pass
(:mod:`afo_mj.design.design_models`, :mod:`afo_mj.hydraulics.laws`) on a reduced set of duty
samples; :func:`_drop_one` names the binding constraints when nothing passes.
"""

from __future__ import annotations

import math

import numpy as np

from afo_mj.design.design_evaluation import (RE_LAMINAR, _battery_figures, _budget_fixed,
                                              _fluids, _runtime, _supply_figures, _waist_fixed,
                                              actuator_geometry)
from afo_mj.design.design_models import (cylinder_masses, hose_wall_mass_kg_per_m, line_steady,
                                           motor_scaling, oil_viscosity_pa_s, pack_geometry,
                                           pack_thermal_resistance_k_w, pump_mass_kg,
                                           servo_centre_leak_m3_s, supply_steady)
from afo_mj.hydraulics import laws
from afo_mj.hydraulics.geometry import annulus_area_m2


#: Duty samples the screening evaluates (every k-th, weighted); the exact pass uses all.
SCREEN_SAMPLES = 32
#: A design whose mass bound exceeds the lightest found at its pressure and oil by more than
#: this fraction is not evaluated further (it cannot rank near the top).
BOUND_SLACK = 0.03
#: The screening keeps the pack this fraction of the allowed temperature rise below the limit.
SCREEN_TEMPERATURE_MARGIN = 0.02
#: Designs (lowest mass bounds) looked at in full to explain an infeasible motor stage.
DIAGNOSE_DESIGNS = 3000
#: Up to this many constraint points the screening's motor stage checks each exactly; a
#: profile's many points are screened through per-design envelope bounds.
ENVELOPE_EXACT_POINTS = 8


def _pareto_samples(tau: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Indices of the samples the screening checks a profile's constraints at: per sign
    quadrant of ``(τ, θ̇)``, the Pareto fronts maximising ``(|τ|, |θ̇|)`` and ``(|τ|, −|θ̇|)``.
    Within a quadrant the pump pressure, flow, pump speed and motor current are monotone in
    ``|τ|`` and ``|θ̇|`` (rising in both where the ankle takes power; where it gives power back,
    rising in ``|τ|`` and falling in ``|θ̇|`` for the pressure), so their maxima lie on these
    fronts. The exact pass (:func:`~afo_mj.design.design_evaluation.evaluate_designs`) checks
    every sample."""
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
