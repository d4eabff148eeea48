"""Seal, cylinder, pump and motor models against hand calculations and analytic solutions."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from afo_mj.hydraulics.cylinder import CylinderParams
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA, Fluid, FluidParams
from afo_mj.hydraulics.motor import DriverParams, MotorParams
from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.pump import AXIAL_PISTON_PUMP_SMALL, GEAR_PUMP_SMALL, PumpParams
from afo_mj.hydraulics.seal import OringSeal, OringSealParams
from component_reference import BrushlessMotor, Cylinder, Pump

PA = ATMOSPHERIC_PRESSURE_PA


def test_oring_coulomb_level_hand_calculation():
    seal = OringSeal(OringSealParams(cross_section_m=1.78e-3, squeeze_ratio=0.12,
                                     friction_coefficient=0.4, elastic_modulus_pa=3.5e6), 10e-3)
    expected = 0.4 * 3.5e6 * math.pi * 10e-3 * 1.78e-3 * 0.12 ** 1.5
    assert seal.coulomb_force_n == pytest.approx(expected, rel=1e-12)
    assert 2.0 < expected < 5.0  # a few newtons for a 10 mm bore (seed §2.3 scale)
    # grows with squeeze as lambda^1.5
    s2 = OringSeal(OringSealParams(squeeze_ratio=0.24), 10e-3)
    assert s2.coulomb_force_n / seal.coulomb_force_n == pytest.approx(2 ** 1.5)


def test_stribeck_curve_shape():
    p = OringSealParams(breakaway_ratio=1.5, breakaway_velocity_m_s=0.005,
                        viscous_coefficient_n_s_m=20.0)
    seal = OringSeal(p, 10e-3)
    fc, fb = seal.coulomb_force_n, seal.breakaway_force_n
    # peak of the Stribeck form at v = v_brk: F_brk + f_v v_brk (tanh(10) ≈ 1)
    assert seal.friction_force_n(0.005) == pytest.approx(fb + 20.0 * 0.005, rel=1e-3)
    v = np.linspace(1e-5, 0.5, 20001)
    f = seal.friction_force_n(v)
    i_peak = int(np.argmax(f[v < 0.05]))
    assert v[i_peak] == pytest.approx(0.005, rel=0.05)
    # falls through the mixed region to ~F_C, then rises viscously
    assert seal.friction_force_n(0.03) == pytest.approx(fc + 20 * 0.03, rel=0.01)
    assert f[-1] > f[np.searchsorted(v, 0.05)]
    # odd and dissipative
    assert np.allclose(seal.friction_force_n(-v), -f)
    assert np.all(seal.power(v).heat_w >= 0)
    off = OringSeal(OringSealParams(stribeck_enabled=False, viscous_enabled=False), 10e-3)
    assert off.friction_force_n(0.005) == pytest.approx(off.coulomb_force_n * math.tanh(10))


def test_cylinder_geometry_force_and_leakage():
    cyl = Cylinder(CylinderParams(kind="piston_cable", bore_m=12e-3, rod_diameter_m=2e-3,
                                  stroke_m=0.03))
    a = math.pi / 4 * (12e-3 ** 2 - 2e-3 ** 2)
    assert cyl.area_a_m2 == pytest.approx(a) and cyl.area_b_m2 == pytest.approx(a)
    va, vb = cyl.chamber_volumes_m3(0.01)
    assert va == pytest.approx(0.2e-6 + a * 0.01) and vb == pytest.approx(0.2e-6 + a * 0.02)
    assert cyl.hydraulic_force_n(PA + 10e6, PA) == pytest.approx(10e6 * a)
    single_rod = Cylinder(CylinderParams(kind="double_acting", bore_m=12e-3, rod_diameter_m=4e-3))
    # equal absolute pressures on both sides push out with p_gauge * rod area
    assert single_rod.hydraulic_force_n(PA + 1e6, PA + 1e6) == pytest.approx(
        1e6 * math.pi / 4 * 4e-3 ** 2)
    mu = 0.04
    q = cyl.internal_leakage_m3_s(PA + 1e7, PA, mu)
    assert q == pytest.approx(math.pi * 12e-3 * (10e-6) ** 3 * 1e7 / (12 * mu * 5e-3))
    # end stops push back only when penetrated
    assert cyl.end_stop_force_n(0.015, 0.0) == 0.0
    assert cyl.end_stop_force_n(-1e-5, 0.0) == pytest.approx(5e7 * 1e-5)
    assert cyl.end_stop_force_n(0.03 + 1e-5, 0.0) == pytest.approx(-5e7 * 1e-5)


def test_cylinder_hydraulic_natural_frequency_from_free_oscillation():
    """ω = √(B A² (1/V1 + 1/V2) / m), recovered from a simulated free oscillation within 2 %."""
    fluid = Fluid(FluidParams(air_fraction=0.0))
    cyl = Cylinder(CylinderParams(bore_m=10e-3, rod_diameter_m=2e-3, stroke_m=0.03,
                                  dead_volume_a_m3=0.5e-6, dead_volume_b_m3=0.5e-6,
                                  seal_friction_enabled=False, internal_leakage_enabled=False))
    mass, x0, p0 = 1.0, 0.012, 2e6
    b_l = 1.5e9

    def f(t, y):
        pa, pb, x, v = y
        va, vb = cyl.chamber_volumes_m3(x)
        return [-fluid.bulk_modulus_pa(pa) * cyl.area_a_m2 * v / va,
                fluid.bulk_modulus_pa(pb) * cyl.area_b_m2 * v / vb,
                v, cyl.hydraulic_force_n(pa, pb) / mass]

    y0 = np.array([p0, p0, x0, 0.02])  # small initial velocity: linear oscillation
    va, vb = cyl.chamber_volumes_m3(x0)
    omega = math.sqrt(b_l * cyl.area_a_m2 ** 2 * (1 / va + 1 / vb) / mass)
    period = 2 * math.pi / omega
    ts = np.arange(1, int(10 * 200) + 1) * (period / 200)
    sol = solve_ivp(f, (0.0, ts[-1]), y0, method="Radau", t_eval=ts, rtol=1e-9,
                    atol=[1.0, 1.0, 1e-12, 1e-9])
    assert sol.success, sol.message
    xs = sol.y[2] - x0
    up = np.flatnonzero((xs[:-1] < 0) & (xs[1:] >= 0))
    tc = ts[up] - xs[up + 1] * (ts[up + 1] - ts[up]) / (xs[up + 1] - xs[up])  # linear interp
    measured = 2 * math.pi / np.mean(np.diff(tc))
    assert 100 < omega / 2 / math.pi < 2000  # hundreds of Hz for a small bore (facts.md)
    assert measured == pytest.approx(omega, rel=0.02)


@pytest.mark.parametrize("params", [GEAR_PUMP_SMALL, AXIAL_PISTON_PUMP_SMALL])
def test_pump_efficiency_bounds_and_trends(params):
    pump = Pump(params)
    w = np.linspace(100, 1000, 10)
    dp = np.linspace(1e6, 15e6, 10)
    W, DP = np.meshgrid(w, dp)
    ev, em, et = pump.efficiencies(W, DP, 0.04)
    for e in (ev, em, et):
        assert np.all((e > 0) & (e < 1))
    # η_v falls with Δp and rises with speed and viscosity
    assert np.all(np.diff(ev, axis=0) < 0) and np.all(np.diff(ev, axis=1) > 0)
    assert pump.efficiencies(500, 10e6, 0.02)[0] < pump.efficiencies(500, 10e6, 0.08)[0]
    # η_m falls as μ·ω grows
    assert pump.efficiencies(500, 10e6, 0.08)[1] < pump.efficiencies(500, 10e6, 0.02)[1]
    assert np.all(np.diff(em, axis=1) < 0)
    # four-quadrant power balance: in = out + heat, heat >= 0
    ww = np.array([-800, -50, 0.0, 50, 800])[:, None]
    dd = np.array([-12e6, -1e5, 0, 1e5, 12e6])[None, :]
    pf = pump.power(ww, dd, 0.05)
    assert np.allclose(pf.residual_w, 0, atol=1e-9)
    assert np.all(pf.heat_w >= -1e-12)


def test_pump_preset_rated_efficiencies():
    # the figures stated at the presets
    ev, em, _ = Pump(GEAR_PUMP_SMALL).efficiencies(4000 * 2 * math.pi / 60, 10e6, 0.04)
    assert ev == pytest.approx(0.93, abs=0.01) and em == pytest.approx(0.92, abs=0.01)
    ev, em, _ = Pump(AXIAL_PISTON_PUMP_SMALL).efficiencies(3000 * 2 * math.pi / 60, 10e6, 0.04)
    assert ev == pytest.approx(0.96, abs=0.01) and em == pytest.approx(0.95, abs=0.01)


def test_variable_displacement():
    pump = Pump(PumpParams(variable_displacement_enabled=True, leakage_enabled=False))
    assert pump.flow_m3_s(500.0, 0.0, 0.04, 0.5) == pytest.approx(
        0.5 * 0.2e-6 / (2 * math.pi) * 500)
    fixed = Pump(PumpParams(leakage_enabled=False))
    assert fixed.flow_m3_s(500.0, 0.0, 0.04, 0.5) == pytest.approx(0.2e-6 / (2 * math.pi) * 500)


def test_motor_steady_state_and_current_limit():
    m = MotorParams(resistance_ohm=0.5, torque_constant_nm_a=0.02, coulomb_torque_nm=0.0,
                    viscous_coefficient_nm_s_rad=1e-5)
    motor = BrushlessMotor(m, DriverParams(current_limit_a=10.0))
    # steady no-load speed: K i = b ω and v = R i + K ω  →  ω = v K / (K² + R b)
    v = 12.0
    w = v * 0.02 / (0.02 ** 2 + 0.5 * 1e-5)
    i = 1e-5 * w / 0.02
    assert motor.current_rate_a_s(v, i, w) == pytest.approx(0.0, abs=1e-9)
    # at stall the clamp applies R * I_max (the driver law rounds the clamp's corners over
    # 0.05 V, so 7 V past it the value is off by 0.05²/(4·7) + 0.05²/(4·17) ≈ 1.3e-4 V)
    assert motor.applied_voltage_v(12.0, 0.0, 24.0) == pytest.approx(0.5 * 10.0, abs=2e-4)
    # and never more than the duty limit of the bus
    assert motor.applied_voltage_v(50.0, 5000.0, 24.0) == pytest.approx(0.95 * 24.0, abs=2e-4)
    pf = motor.power(v, 3.0, 100.0, motor.current_rate_a_s(v, 3.0, 100.0))
    assert pf.residual_w == pytest.approx(0.0, abs=1e-12)
    assert motor.bus_power_w(10.0, 2.0) == pytest.approx(20.0 + 0.02 * 4 + 0.3)


@pytest.mark.parametrize("cls, field, value", [
    (CylinderParams, "bore_m", -0.01), (CylinderParams, "stroke_m", 0.0),
    (CylinderParams, "dead_volume_a_m3", 0.0), (CylinderParams, "kind", "rotary"),
    (CylinderParams, "rod_diameter_m", 0.02), (OringSealParams, "squeeze_ratio", 0.0),
    (PumpParams, "displacement_m3_rev", -1e-6), (MotorParams, "resistance_ohm", 0.0),
    (DriverParams, "max_duty", 1.5)])
def test_actuator_bad_input(cls, field, value):
    with pytest.raises(ParameterError, match=field):
        cls(**{field: value})
