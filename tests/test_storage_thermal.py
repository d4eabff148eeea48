"""Accumulators, battery and thermal network against independent references.

References are hand formulas, scipy quadrature/ODE integration, a matrix exponential and
textbook property tables, never the code's own outputs.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.linalg import expm

from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.accumulator import GasAccumulatorParams, SpringAccumulatorParams
from afo_mj.hydraulics.battery import BatteryParams
from afo_mj.hydraulics.thermal import (
    AMBIENT, ThermalNetwork, ThermalNetworkParams, ThermalNodeParams, air_properties,
    convection_resistance_k_w, fluid_only, natural_convection_h_cylinder)
from component_reference import Battery, GasAccumulator, SpringAccumulator


def _raises_naming(factory, *fields):
    with pytest.raises(ParameterError) as info:
        factory()
    for name in fields:
        assert name in str(info.value), (name, str(info.value))


# --------------------------------------------------------------------------- gas accumulator

@pytest.mark.parametrize("n", [1.0, 1.2, 1.4, 1.67])
def test_gas_law_p_vgas_n_constant(n):
    params = GasAccumulatorParams(gas_volume_m3=0.16e-3, precharge_pressure_pa=1.2e6,
                                  max_pressure_pa=7e6, polytropic_index=n)
    acc = GasAccumulator(params)
    vf = np.linspace(0.0, 0.9 * params.gas_volume_m3, 41)
    p = acc.pressure_pa(vf)
    invariant = p * (params.gas_volume_m3 - vf) ** n
    ref = params.precharge_pressure_pa * params.gas_volume_m3 ** n
    np.testing.assert_allclose(invariant, ref, rtol=1e-9)


def test_isothermal_energy_log_formula():
    v0, p0 = 0.1e-3, 1.0e6
    acc = GasAccumulator(GasAccumulatorParams(gas_volume_m3=v0, precharge_pressure_pa=p0,
                                              max_pressure_pa=5e6, polytropic_index=1.0))
    vf = np.linspace(0.0, 0.8 * v0, 9)
    vg = v0 - vf
    np.testing.assert_allclose(acc.stored_energy_j(vf), p0 * v0 * np.log(v0 / vg),
                               rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n", [1.4, 1.3, 1.0 + 1e-9])
def test_polytropic_energy_matches_quadrature(n):
    v0, p0 = 75e-6, 1.5e6
    acc = GasAccumulator(GasAccumulatorParams(gas_volume_m3=v0, precharge_pressure_pa=p0,
                                              max_pressure_pa=6e6, polytropic_index=n))
    for vf in (1e-6, 20e-6, 41e-6, 60e-6):
        vg = v0 - vf
        ref, _ = quad(lambda v: p0 * (v0 / v) ** n, vg, v0, epsabs=0.0, epsrel=1e-12)
        assert acc.stored_energy_j(vf) == pytest.approx(ref, rel=1e-6)


def test_capacity_matches_hand_formula_and_inverse():
    v0, p0, pmax, n = 0.2e-3, 2e6, 9e6, 1.4
    acc = GasAccumulator(GasAccumulatorParams(gas_volume_m3=v0, precharge_pressure_pa=p0,
                                              max_pressure_pa=pmax, polytropic_index=n))
    cap = v0 * (1.0 - (p0 / pmax) ** (1.0 / n))
    assert acc.capacity_m3 == pytest.approx(cap, rel=1e-12)
    assert acc.fluid_volume_m3(pmax) == pytest.approx(cap, rel=1e-12)
    assert acc.pressure_pa(cap) == pytest.approx(pmax, rel=1e-12)
    np.testing.assert_array_equal(acc.fluid_volume_m3(np.array([0.5e6, 1e6, p0])), 0.0)
    vf = np.linspace(0.0, 1.3 * cap, 11)
    np.testing.assert_allclose(acc.fluid_volume_m3(acc.pressure_pa(vf)), vf, rtol=1e-9,
                               atol=1e-15)


def test_gas_limits_finite_monotone_and_flagged():
    acc = GasAccumulator()
    v0 = acc.params.gas_volume_m3
    vf = np.concatenate([np.linspace(-1e-6, 0.0, 50), np.linspace(0.0, 1.5 * v0, 400)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = acc.pressure_pa(vf)
        e = acc.stored_energy_j(vf)
        k = acc.stiffness_pa_m3(vf)
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(e)) and np.all(np.isfinite(k))
    assert np.all(np.diff(p) >= 0.0)
    # Below empty: straight line of slope B_stop/V_port from the precharge.
    slope = acc.params.stop_bulk_modulus_pa / acc.params.port_volume_m3
    assert acc.pressure_pa(-1e-10) == pytest.approx(acc.params.precharge_pressure_pa
                                                     - slope * 1e-10, rel=1e-12)
    assert acc.pressure_pa(0.0) == pytest.approx(acc.params.precharge_pressure_pa, rel=1e-15)
    np.testing.assert_array_equal(acc.below_empty(np.array([-1e-9, 0.0, 1e-9])),
                                  [True, False, False])
    cap = acc.capacity_m3
    np.testing.assert_array_equal(acc.over_capacity(np.array([0.5 * cap, cap * 1.001])),
                                  [False, True])
    # The gas law continues just above capacity.
    vf_over = 1.1 * cap
    assert acc.pressure_pa(vf_over) == pytest.approx(
        acc.params.precharge_pressure_pa * (v0 / (v0 - vf_over)) ** acc.params.polytropic_index,
        rel=1e-12)


@pytest.mark.parametrize("kind", ["gas", "spring"])
def test_energy_slope_equals_power_per_flow_in_every_region(kind):
    acc = GasAccumulator() if kind == "gas" else SpringAccumulator()
    vent = 0.0 if kind == "gas" else acc.params.vent_pressure_pa
    cap = acc.capacity_m3
    top = 0.995 * acc.params.gas_volume_m3 if kind == "gas" else 1.0001 * cap
    points = np.array([-2e-10, 0.1 * cap, 0.5 * cap, 0.99 * cap, 1.0005 * cap, top])
    h = 1e-12 if kind == "spring" else 1e-13
    for vf in points:
        dedv = (acc.stored_energy_j(vf + h) - acc.stored_energy_j(vf - h)) / (2 * h)
        assert dedv == pytest.approx(acc.pressure_pa(vf) - vent, rel=2e-4)
    q = np.linspace(-2e-5, 2e-5, len(points))
    flow = acc.power(points, q)
    np.testing.assert_allclose(flow.residual_w, 0.0, atol=1e-9)
    np.testing.assert_allclose(flow.in_w, acc.pressure_pa(points) * q, rtol=1e-12)
    np.testing.assert_allclose(flow.stored_w, (acc.pressure_pa(points) - vent) * q, rtol=1e-12)


def test_vectorised_matches_scalar():
    acc = GasAccumulator()
    vf = np.array([-1e-9, 0.0, 1e-5, 3e-5, 6e-5])
    p_vec = acc.pressure_pa(vf)
    assert p_vec.shape == (5,)
    for i, v in enumerate(vf):
        assert float(acc.pressure_pa(float(v))) == p_vec[i]


def test_precharge_at_or_above_max_raises():
    for p0 in (6e6, 7e6):
        _raises_naming(lambda: GasAccumulatorParams(precharge_pressure_pa=p0, max_pressure_pa=6e6),
                       "precharge_pressure_pa", "max_pressure_pa")


@pytest.mark.parametrize("field, value", [
    ("gas_volume_m3", 0.0), ("gas_volume_m3", -1e-5), ("precharge_pressure_pa", 0.0),
    ("max_pressure_pa", -1.0), ("polytropic_index", 0.9), ("polytropic_index", 1.8),
    ("stop_bulk_modulus_pa", 0.0), ("port_volume_m3", 0.0), ("gas_volume_m3", float("nan")),
    ("gas_volume_m3", "big"),
])
def test_gas_bad_values_raise(field, value):
    _raises_naming(lambda: GasAccumulatorParams(**{field: value}), field)


def test_gas_compression_ratio_too_large_raises():
    _raises_naming(lambda: GasAccumulatorParams(precharge_pressure_pa=1e5, max_pressure_pa=9e7,
                                                polytropic_index=1.0),
                   "max_pressure_pa", "precharge_pressure_pa")


# ------------------------------------------------------------------------ spring accumulator

def test_spring_pressure_energy_capacity_hand_formulas():
    area, k, f0, stroke = 3.0e-4, 2.0e4, 150.0, 0.03
    params = SpringAccumulatorParams(piston_area_m2=area, spring_rate_n_m=k, preload_n=f0,
                                     stroke_m=stroke, max_pressure_pa=5e6)
    acc = SpringAccumulator(params)
    assert acc.capacity_m3 == pytest.approx(area * stroke, rel=1e-15)
    x = np.linspace(0.0, stroke, 7)
    vf = x * area
    np.testing.assert_allclose(acc.pressure_pa(vf), 101_325.0 + (f0 + k * x) / area, rtol=1e-12)
    np.testing.assert_allclose(acc.stored_energy_j(vf), 0.5 * k * x ** 2 + f0 * x, rtol=1e-12,
                               atol=1e-15)
    p = 101_325.0 + (f0 + k * x[1:-1]) / area
    np.testing.assert_allclose(acc.fluid_volume_m3(p), vf[1:-1], rtol=1e-9)
    assert acc.fluid_volume_m3(101_325.0 + 0.5 * f0 / area) == 0.0
    # Stops: stiff, finite, flagged.
    s = params.stop_bulk_modulus_pa / params.port_volume_m3
    assert acc.pressure_pa(-1e-10) == pytest.approx(101_325.0 + f0 / area - s * 1e-10, rel=1e-12)
    top = acc.capacity_m3 + 1e-10
    assert acc.pressure_pa(top) == pytest.approx(
        101_325.0 + (f0 + k * stroke) / area + s * 1e-10, rel=1e-12)
    assert bool(acc.over_capacity(top)) and bool(acc.below_empty(-1e-10))


@pytest.mark.parametrize("field, value", [
    ("piston_area_m2", 0.0), ("spring_rate_n_m", 0.0), ("preload_n", -1.0), ("stroke_m", 0.0),
    ("max_pressure_pa", 0.0), ("vent_pressure_pa", -1.0), ("port_volume_m3", 0.0),
])
def test_spring_bad_values_raise(field, value):
    _raises_naming(lambda: SpringAccumulatorParams(**{field: value}), field)


def test_spring_full_stroke_above_rating_raises():
    _raises_naming(lambda: SpringAccumulatorParams(spring_rate_n_m=1e5, max_pressure_pa=2e6),
                   "max_pressure_pa", "spring_rate_n_m", "stroke_m")


# ---------------------------------------------------------------------------------- battery

def test_ocv_table_endpoints_and_nominal():
    b = Battery()
    ns = b.params.cells_series
    assert b.open_circuit_voltage_v(0.0) == pytest.approx(3.0 * ns)
    assert b.open_circuit_voltage_v(1.0) == pytest.approx(4.2 * ns)
    v = b.open_circuit_voltage_v(np.linspace(0, 1, 101))
    assert np.all(np.diff(v) >= 0)
    soc, volts = np.array(b.params.ocv_soc), np.array(b.params.ocv_cell_v)
    mean_cell = np.sum(np.diff(soc) * 0.5 * (volts[1:] + volts[:-1]))
    assert 3.6 <= mean_cell <= 3.8
    assert b.energy_wh == pytest.approx(ns * b.params.capacity_ah * mean_cell, rel=1e-12)
    assert b.open_circuit_voltage_v(0.5) == pytest.approx(3.75 * ns)


def test_current_for_power_delivers_requested_power():
    b = Battery()
    r = b.params.internal_resistance_ohm
    soc = np.repeat(np.array([0.05, 0.3, 0.6, 0.95]), 5)
    power = np.tile(np.array([-300.0, 0.0, 1e-3, 150.0, 700.0]), 4)
    i = b.current_for_power_a(soc, power)
    delivered = b.terminal_voltage_v(soc, i) * i
    np.testing.assert_allclose(delivered, power, rtol=1e-9, atol=1e-9)
    # Same root as the textbook quadratic formula (stable branch).
    voc = b.open_circuit_voltage_v(soc)
    np.testing.assert_allclose(i, (voc - np.sqrt(voc ** 2 - 4 * r * power)) / (2 * r),
                               rtol=1e-8, atol=1e-9)
    assert not np.any(b.power_limited(soc, power))


def test_power_beyond_maximum_is_clipped_without_nan():
    b = Battery()
    r = b.params.internal_resistance_ohm
    soc = np.array([0.1, 0.5, 0.9])
    voc = b.open_circuit_voltage_v(soc)
    p_max = voc ** 2 / (4 * r)
    np.testing.assert_allclose(b.max_power_w(soc), p_max, rtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        i = b.current_for_power_a(soc, 2.0 * p_max)
    assert np.all(np.isfinite(i))
    np.testing.assert_allclose(i, voc / (2 * r), rtol=1e-12)
    np.testing.assert_allclose(b.terminal_voltage_v(soc, i) * i, p_max, rtol=1e-12)
    assert np.all(b.power_limited(soc, 2.0 * p_max))
    assert bool(b.over_current(25.0)) and not bool(b.over_current(-10.0))


def test_soc_falls_by_charge_drawn_and_energy_matches_integral():
    params = BatteryParams(capacity_ah=3.0, cells_series=7, internal_resistance_ohm=0.1)
    b = Battery(params)
    current, t_end, soc0 = 6.0, 600.0, 0.9
    sol = solve_ivp(lambda t, y: b.soc_rate_per_s(current), (0.0, t_end), [soc0],
                    rtol=1e-10, atol=1e-12)
    soc_end = sol.y[0, -1]
    assert soc_end == pytest.approx(soc0 - current * t_end / (3600.0 * 3.0), rel=1e-9)
    # Chemical energy released = ∫ V_oc I dt along the discharge.
    released, _ = quad(lambda t: b.open_circuit_voltage_v(soc0 - current * t / 10800.0)
                       * current, 0.0, t_end, limit=200, epsrel=1e-11)
    assert b.stored_energy_j(soc0) - b.stored_energy_j(soc_end) == pytest.approx(released,
                                                                                  rel=1e-9)
    flow = b.power(np.array([0.2, 0.8, 0.8]), np.array([10.0, -5.0, 0.0]))
    np.testing.assert_allclose(flow.residual_w, 0.0, atol=1e-12)
    np.testing.assert_allclose(flow.heat_w, 0.1 * np.array([100.0, 25.0, 0.0]), rtol=1e-12)


@pytest.mark.parametrize("field, value", [
    ("capacity_ah", 0.0), ("cells_series", 0.0), ("cells_series", 2.5),
    ("internal_resistance_ohm", 0.0), ("max_current_a", -1.0), ("mass_kg", 0.0),
    ("ocv_soc", (0.0, 0.5)), ("ocv_soc", (0.1, 0.5, 1.0)), ("ocv_soc", (0.0, 0.6, 0.5, 1.0)),
    ("ocv_cell_v", (3.0, 4.2)), ("ocv_cell_v", (3.0, 3.5, 3.4, 3.6, 3.7, 3.8, 3.9, 4.0, 4.1,
                                               4.15, 4.18, 4.2)),
])
def test_battery_bad_values_raise(field, value):
    if field == "ocv_soc":
        kwargs = {"ocv_soc": value, "ocv_cell_v": tuple(np.linspace(3.0, 4.2, len(value)))}
    else:
        kwargs = {field: value}
    _raises_naming(lambda: BatteryParams(**kwargs), field)


# ---------------------------------------------------------------------------------- thermal

def test_single_node_step_response_matches_exponential():
    c, r, t_amb, t0, q = 350.0, 4.0, 293.15, 303.15, 12.0
    net = ThermalNetwork(fluid_only(c, r, t_amb, initial_temperature_k=t0))
    t_inf = t_amb + q * r
    times = np.linspace(0.0, 5 * r * c, 26)
    sol = solve_ivp(lambda t, y: net.temperature_rates_k_s(y, np.array([q])), (0.0, times[-1]),
                    net.initial_temperatures_k, t_eval=times, rtol=1e-8, atol=1e-10)
    analytic = t_inf + (t0 - t_inf) * np.exp(-times / (r * c))
    rise = sol.y[0] - t_amb
    np.testing.assert_allclose(rise, analytic - t_amb, rtol=5e-3)
    stepped = net.advance_k(np.array([t0]), q, times[-1])
    assert stepped[0] == pytest.approx(analytic[-1], rel=1e-12)
    assert net.time_constants_s[0] == pytest.approx(r * c, rel=1e-12)


def test_two_node_series_steady_state_and_transient():
    r1, r2, t_amb = 2.0, 3.0, 298.15
    params = ThermalNetworkParams(
        ambient_temperature_k=t_amb,
        nodes=[ThermalNodeParams(name="motor", heat_capacity_j_k=150.0),
               ThermalNodeParams(name="block", heat_capacity_j_k=600.0)],
        resistances=[("motor", "block", r1), ("block", AMBIENT, r2)])
    assert isinstance(params.nodes, tuple) and isinstance(params.resistances, tuple)
    net = ThermalNetwork(params)
    q = np.array([10.0, 5.0])
    t_block = t_amb + (10.0 + 5.0) * r2
    t_motor = t_block + 10.0 * r1
    np.testing.assert_allclose(net.steady_state_k(q), [t_motor, t_block], rtol=1e-12)
    np.testing.assert_allclose(net.temperature_rates_k_s(np.array([t_motor, t_block]), q), 0.0,
                               atol=1e-12)
    assert net.heat_to_ambient_w(np.array([t_motor, t_block])) == pytest.approx(15.0, rel=1e-12)
    np.testing.assert_allclose(net.link_heat_flows_w(np.array([t_motor, t_block])), [10.0, 15.0],
                               rtol=1e-12)
    # Transient against the matrix exponential of the hand-built state matrix.
    c = np.array([150.0, 600.0])
    a = np.array([[-1 / r1, 1 / r1], [1 / r1, -1 / r1 - 1 / r2]]) / c[:, None]
    b = (q + np.array([0.0, t_amb / r2])) / c
    t0 = np.array([300.0, 299.0])
    x_ss = -np.linalg.solve(a, b)
    for dt in (10.0, 500.0, 5000.0):
        ref = x_ss + expm(a * dt) @ (t0 - x_ss)
        np.testing.assert_allclose(net.advance_k(t0, q, dt), ref, rtol=1e-10)
    # Batch of states (n, k).
    batch = np.stack([t0, t0 + 5.0, t0 - 3.0], axis=1)
    rates = net.temperature_rates_k_s(batch, np.broadcast_to(q[:, None], batch.shape))
    assert rates.shape == (2, 3)
    np.testing.assert_allclose(rates, a @ batch + b[:, None], rtol=1e-12)
    flow = net.power(batch, q)
    np.testing.assert_allclose(flow.residual_w, 0.0, atol=1e-10)


def test_churchill_chu_cylinder_hand_calculation():
    d, ts, ta = 0.03, 313.15, 293.15
    h = natural_convection_h_cylinder(d, ts, ta)
    assert 3.0 <= h <= 10.0
    # Hand calculation with Incropera Table A.4 air at 300 K (film 303 K).
    nu_air, alpha, k, pr = 15.89e-6, 22.5e-6, 0.0263, 0.707
    ra = 9.81 * (1 / 303.15) * 20.0 * d ** 3 / (nu_air * alpha)
    nusselt = (0.60 + 0.387 * ra ** (1 / 6) / (1 + (0.559 / pr) ** (9 / 16)) ** (8 / 27)) ** 2
    assert h == pytest.approx(nusselt * k / d, rel=0.03)
    # Symmetric in the sign of the difference, vectorised, and finite at zero difference.
    hs = natural_convection_h_cylinder(np.array([d, d, d, d]), np.array([ts, ta, ta, 333.15]),
                                       np.array([ta, ta, ts, ta]))
    assert np.all(np.isfinite(hs)) and hs[1] > 0
    assert hs[0] == pytest.approx(h) and hs[2] == pytest.approx(h)
    assert hs[1] < hs[0] < hs[3]


def test_air_properties_against_table():
    air = air_properties(300.0)
    # Incropera Table A.4, 300 K.
    assert air.dynamic_viscosity_pa_s == pytest.approx(184.6e-7, rel=0.01)
    assert air.thermal_conductivity_w_m_k == pytest.approx(26.3e-3, rel=0.01)
    assert air.prandtl == pytest.approx(0.707, rel=0.01)
    assert air.density_kg_m3 == pytest.approx(1.1614, rel=0.015)
    assert air.kinematic_viscosity_m2_s == pytest.approx(15.89e-6, rel=0.015)


def test_convection_resistance():
    assert convection_resistance_k_w(0.02, 5.0) == pytest.approx(10.0)
    np.testing.assert_allclose(convection_resistance_k_w(np.array([0.01, 0.04]), 25.0),
                               [4.0, 1.0])


def _node(**kw):
    return ThermalNodeParams(**kw)


@pytest.mark.parametrize("factory, field", [
    (lambda: ThermalNodeParams(heat_capacity_j_k=0.0), "heat_capacity_j_k"),
    (lambda: ThermalNodeParams(initial_temperature_k=-5.0), "initial_temperature_k"),
    (lambda: ThermalNodeParams(name=""), "name"),
    (lambda: ThermalNodeParams(name=AMBIENT), "name"),
    (lambda: ThermalNetworkParams(ambient_temperature_k=0.0), "ambient_temperature_k"),
    (lambda: ThermalNetworkParams(nodes=()), "nodes"),
    (lambda: ThermalNetworkParams(nodes=("fluid",)), "nodes"),
    (lambda: ThermalNetworkParams(nodes=(_node(), _node())), "nodes"),
    (lambda: ThermalNetworkParams(resistances=(("fluid", AMBIENT, 0.0),)), "resistances"),
    (lambda: ThermalNetworkParams(resistances=(("fluid", AMBIENT, -2.0),)), "resistances"),
    (lambda: ThermalNetworkParams(resistances=(("fluid", AMBIENT, math.inf),)), "resistances"),
    (lambda: ThermalNetworkParams(resistances=(("pump", AMBIENT, 2.0),)), "resistances"),
    (lambda: ThermalNetworkParams(resistances=(("fluid", "fluid", 2.0),)), "resistances"),
    (lambda: ThermalNetworkParams(resistances=(("fluid", AMBIENT),)), "resistances"),
    (lambda: ThermalNetworkParams(resistances=()), "resistances"),
    (lambda: ThermalNetworkParams(nodes=(_node(name="a"), _node(name="b")),
                                  resistances=(("a", AMBIENT, 1.0),)), "resistances"),
    (lambda: fluid_only(0.0, 5.0, 298.15), "heat_capacity_j_k"),
])
def test_thermal_bad_values_raise(factory, field):
    _raises_naming(factory, field)


def test_fluid_only_preset():
    p = fluid_only(400.0, 5.0, 300.0)
    net = ThermalNetwork(p)
    assert net.names == ("fluid",)
    assert net.initial_temperatures_k[0] == 300.0
    assert net.steady_state_k(np.array([10.0]))[0] == pytest.approx(350.0)
    # Ambient given first is accepted too.
    p2 = ThermalNetworkParams(resistances=((AMBIENT, "fluid", 5.0),))
    assert ThermalNetwork(p2).steady_state_k(np.array([2.0]))[0] == pytest.approx(308.15)
