"""The lab bench (:func:`afo_mj.circuits.library.lab_bench` and its overrides) written out by
hand as one ODE and integrated by scipy's Radau at a tight tolerance: the reference the
generated kernels are compared against (tests/test_circuits.py, tests/test_circuit_accuracy.py).

It is a second implementation of the assembly the code generator writes (node continuity,
shaft and joint equations from the component parameters, each term a call to the same laws),
so it shares the laws with the kernel but neither the generated code nor the stepper: Radau
with error control at ``rtol`` 1e-9 stands for the exact solution of the model's equations.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from component_reference import Cylinder

from afo_mj.circuits.circuit import Circuit
from afo_mj.hydraulics import laws as L
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA, Fluid

#: rows of the reference solution ``sol.y`` and the kernel's log names of the same signals
ROWS = {"motor.current_a": 0, "shaft": 1, "line_a": 2, "line_b": 3, "chamber_a": 4,
        "chamber_b": 5, "angle_rad": 6, "velocity_rad_s": 7}


def reference_lab_bench(circuit: Circuit, cmd_fn, t_end, inertia, k_load, c_load,
                        ext_fn=None, rtol=1e-9):
    """The lab bench with its load (inertia ``J`` on a spring ``k`` and damper ``c``, external
    torque ``ext_fn(t)``) driven by the open-loop voltage ``cmd_fn(t)``, as one ODE (motor
    current, shaft speed, four node pressures, joint angle and velocity), integrated by Radau
    and sampled every 1 ms from 1 ms to ``t_end``. Each side's components are read separately
    (``hose_b``, ``check_b``, ``relief_ba``, ``port_b``), so an override of one side is
    followed. The oil temperature is held at ambient (the kernel heats it by the losses; a
    bench run of a few seconds moves the viscosity by < 0.1 %)."""
    comp = {c.name: c.params for c in circuit.components}
    fl = circuit.fluid
    fluid = Fluid(fl)
    T = circuit.thermal.ambient_temperature_k
    mu = L.dynamic_viscosity_pa_s(T, fluid.walther_b, fluid.walther_c, fl.density_kg_m3,
                                  fl.thermal_expansion_per_k, fl.reference_temperature_k)
    rho = L.oil_density_kg_m3(T, fl.density_kg_m3, fl.thermal_expansion_per_k,
                              fl.reference_temperature_k)
    m, dr = comp["motor"].motor, comp["motor"].driver
    pu = comp["pump"]
    d = pu.displacement_m3_rev / (2 * math.pi)
    cyp = comp["cylinder"]
    cy = cyp.cylinder
    cyl = Cylinder(cy)
    A, r, s = cyl.area_a_m2, cyp.pulley_radius_m, cy.stroke_m
    ps, rs = cyl.piston_seal, cyl.rod_seal
    fc = ps.coulomb_force_n + 2 * rs.coulomb_force_n
    gst = ps._stribeck_gain + 2 * rs._stribeck_gain
    fv = ps._fv + 2 * rs._fv
    p_res = comp["charge"].pressure_pa
    vbus = circuit.options.supply_voltage_v
    air = fl.air_fraction
    ext_fn = ext_fn or (lambda t: 0.0)

    def hose(name):
        ho = comp[name]
        half = 0.5 * math.pi / 4 * ho.bore_m ** 2 * ho.length_m
        return ho, half, half / ho.wall_bulk_modulus_pa

    (ho_a, vh_a, wall_a), (ho_b, vh_b, wall_b) = hose("hose_a"), hose("hose_b")
    vport_a, vport_b = comp["port_a"].volume_m3, comp["port_b"].volume_m3

    def cap(p, vol):
        b = L.bulk_modulus_pa(max(p + ATMOSPHERIC_PRESSURE_PA, fl.pressure_floor_pa),
                              fl.liquid_bulk_modulus_pa, air, fl.polytropic_index,
                              ATMOSPHERIC_PRESSURE_PA)
        return vol / b

    def relief(rv, dp):
        if dp > 0:
            area = L.relief_valve_area_m2(dp, rv.cracking_dp_pa, rv.override_dp_pa,
                                          rv.max_area_m2, rv.leakage_area_m2)
        else:
            area = rv.leakage_area_m2
        return L.orifice_flow_m3_s(dp, area, rv.discharge_coefficient, rho,
                                   rv.transition_pressure_pa)

    def check(ck, dp):
        return L.check_valve_flow_m3_s(dp, ck.conductance_m3_s_pa, ck.cracking_pa, ck.band_pa)

    def hose_flow(ho, dp):
        return L.hose_flow_m3_s(dp, ho.length_m, ho.bore_m, mu, rho, 0.0, 1.0)

    def f(t, z):
        i, w, pa, pb, ca, cb, th, thd = z
        v = L.driver_voltage_v(cmd_fn(t), m.torque_constant_nm_a * w, m.resistance_ohm,
                               dr.current_limit_a, 1.0, dr.max_duty, vbus)
        di = (v - m.resistance_ohm * i - m.torque_constant_nm_a * w) / m.inductance_h
        dp = pa - pb
        q = L.pump_flow_m3_s(w, dp, d, pu.slip_coefficient, 0.0, mu)
        tf = L.pump_friction_torque_nm(w, dp, d, pu.coulomb_coefficient,
                                       pu.viscous_coefficient, pu.drag_torque_nm,
                                       pu.smoothing_speed_rad_s, mu)
        tm = L.motor_friction_torque_nm(w, m.coulomb_torque_nm,
                                        m.viscous_coefficient_nm_s_rad, m.smoothing_speed_rad_s)
        dw = (m.torque_constant_nm_a * i - tm - d * dp - tf) / (
            m.rotor_inertia_kg_m2 + pu.rotor_inertia_kg_m2)
        qa = hose_flow(ho_a, pa - ca)
        qb = hose_flow(ho_b, pb - cb)
        qr = relief(comp["relief_ab"], dp) - relief(comp["relief_ba"], -dp)
        qca = check(comp["check_a"], p_res - pa)
        qcb = check(comp["check_b"], p_res - pb)
        x = 0.5 * s - r * th
        xd = -r * thd
        ql = L.laminar_gap_flow_m3_s(ca - cb, cyl.leakage_conductance_m3, mu)
        fs = L.seal_friction_n(xd, ca - cb, fc, gst, ps._v_st, ps._v_c, fv, 0.0)
        fe = L.end_stop_force_n(x, xd, s, cy.end_stop_stiffness_n_m, cy.end_stop_damping_n_s_m)
        cpa = cap(pa, vport_a + vh_a) + wall_a
        cpb = cap(pb, vport_b + vh_b) + wall_b
        cca = cap(ca, max(cy.dead_volume_a_m3 + A * x, 0.5 * cy.dead_volume_a_m3) + vh_a) \
            + wall_a
        ccb = cap(cb, max(cy.dead_volume_b_m3 + A * (s - x), 0.5 * cy.dead_volume_b_m3)
                  + vh_b) + wall_b
        tau = -r * (A * (ca - cb) - fs + fe)
        thdd = (tau - k_load * th - c_load * thd + ext_fn(t)) / inertia
        return [di, dw, (q - qa - qr + qca) / cpa, (-q - qb + qr + qcb) / cpb,
                (qa - A * xd - ql) / cca, (qb + A * xd + ql) / ccb, thd, thdd]

    p0 = circuit.options.initial_pressure_pa
    z0 = [0.0, 0.0, p0, p0, p0, p0, 0.0, 0.0]
    t_eval = np.arange(1, int(round(t_end / 1e-3)) + 1) * 1e-3
    sol = solve_ivp(f, (0.0, t_end), z0, method="Radau", rtol=rtol, atol=[1e-9, 1e-7] +
                    [1e-3] * 4 + [1e-10, 1e-8], t_eval=t_eval, max_step=2e-4)
    assert sol.success, sol.message
    return sol


def nrmse(a, b):
    """RMS of ``a − b`` over the range of the reference ``b``."""
    return float(np.sqrt(np.mean((a - b) ** 2)) / (np.max(b) - np.min(b)))
