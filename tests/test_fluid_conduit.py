"""Fluid and conduit models against analytic and published references."""

import math

import numpy as np
import pytest

from afo_mj.hydraulics.conduit import HoseParams, friction_factor_ratio
from afo_mj.hydraulics.fluid import (Fluid, FluidParams, ISO_VG32, ISO_VG46,
                                     effective_bulk_modulus_pa, walther_viscosity_m2_s)
from afo_mj.hydraulics.params import ParameterError
from component_reference import Hose


@pytest.mark.parametrize("p_abs, expected_gpa",
                         [(0.2e6, 0.04), (1e6, 0.49), (3e6, 1.14), (7e6, 1.40)])
def test_bulk_modulus_eq_2_5(p_abs, expected_gpa):
    # facts.md: B_L = 1.5 GPa, alpha = 0.01, n = 1.4 (values given to two decimals)
    b = effective_bulk_modulus_pa(p_abs, 1.5e9, 0.01, 1.4) / 1e9
    assert b == pytest.approx(expected_gpa, abs=0.006)


def test_bulk_modulus_limits_and_air_fraction_trend():
    assert effective_bulk_modulus_pa(5e6, 1.5e9, 0.0, 1.4) == pytest.approx(1.5e9)
    # with air it approaches B_L from below at high pressure, and more air means softer oil
    assert effective_bulk_modulus_pa(1e9, 1.5e9, 0.01, 1.4) == pytest.approx(1.5e9, rel=1e-3)
    b = [float(effective_bulk_modulus_pa(1e6, 1.5e9, a, 1.0)) for a in (0.001, 0.005, 0.02)]
    assert b[0] > b[1] > b[2]


def test_walther_vg46_published_points():
    f = Fluid(ISO_VG46)
    # the two datasheet points it was built on, and the third published one (580 cSt at 0 °C)
    assert f.kinematic_viscosity_m2_s(313.15) == pytest.approx(46e-6, rel=1e-9)
    assert f.kinematic_viscosity_m2_s(373.15) == pytest.approx(6.7e-6, rel=1e-9)
    assert f.kinematic_viscosity_m2_s(273.15) == pytest.approx(580e-6, rel=0.05)
    # Modelica OpenHydraulics GenericOil constants b = 9.32, c = 3.65: a VG 46-like oil
    assert walther_viscosity_m2_s(313.15, 9.32, 3.65) == pytest.approx(46e-6, rel=0.12)


def test_vg32_thinner_than_vg46_and_viscosity_falls_with_temperature():
    t = np.linspace(273.15, 373.15, 11)
    nu32 = Fluid(ISO_VG32).kinematic_viscosity_m2_s(t)
    nu46 = Fluid(ISO_VG46).kinematic_viscosity_m2_s(t)
    assert np.all(nu32 < nu46)
    assert np.all(np.diff(nu46) < 0)


def test_density_and_pressure_floor():
    f = Fluid(ISO_VG46)
    assert f.density_kg_m3(101325.0, 288.15) == pytest.approx(879.0)
    assert f.density_kg_m3(101325.0 + 15e6, 288.15) == pytest.approx(879.0 * (1 + 15e6 / 1.5e9))
    # cavitation rule: full stiffness well above the floor, tiny near it, never negative
    assert f.cavitation_factor(1e6) == pytest.approx(1.0)
    assert 0 < f.cavitation_factor(2.0e3) < 1e-3
    p, n = f.clamp_pressure(np.array([-1e5, 1e3, 5e5]))
    assert n == 2 and np.all(p >= f.params.pressure_floor_pa)
    assert np.all(np.isfinite(f.bulk_modulus_pa(np.array([-1e5, 0.0, 1e3]))))


@pytest.mark.parametrize("field, value", [("air_fraction", 1.0), ("air_fraction", -0.1),
                                          ("liquid_bulk_modulus_pa", 0.0),
                                          ("polytropic_index", 2.0),
                                          ("density_kg_m3", float("nan"))])
def test_fluid_bad_input(field, value):
    with pytest.raises(ParameterError, match=field):
        FluidParams(**{field: value})


def test_hagen_poiseuille_exact_in_laminar_range():
    hose = Hose(HoseParams(length_m=1.5, bore_m=3e-3))
    nu, rho = 40e-6, 870.0
    q = 5e-6  # Re = 4Q/(pi D nu) = 53
    dp = hose.pressure_loss_pa(q, rho, nu)
    assert dp == pytest.approx(128 * rho * nu * 1.5 * q / (math.pi * 3e-3 ** 4), rel=1e-12)
    assert hose.pressure_loss_pa(-q, rho, nu) == pytest.approx(-dp)


def test_turbulent_blasius_and_haaland():
    d, nu, rho, length = 4e-3, 1e-6, 1000.0, 2.0  # water-like to reach Re 1e4
    hose = Hose(HoseParams(length_m=length, bore_m=d))
    re = 1e4
    q = re * nu * math.pi * d / 4
    v = q / (math.pi * d * d / 4)
    f_blasius = 0.3164 * re ** -0.25
    assert hose.pressure_loss_pa(q, rho, nu) == pytest.approx(
        f_blasius * length / d * rho * v * v / 2, rel=1e-9)
    rough = Hose(HoseParams(length_m=length, bore_m=d, roughness_m=4e-6))
    f_haaland = (-1.8 * math.log10((1e-3 / 3.7) ** 1.11 + 6.9 / re)) ** -2
    assert rough.pressure_loss_pa(q, rho, nu) == pytest.approx(
        f_haaland * length / d * rho * v * v / 2, rel=1e-9)


def test_transition_is_continuous_and_monotonic():
    re = np.linspace(1500, 4500, 3001)
    phi = friction_factor_ratio(re, 0.0)   # the law (a ufunc): roughness 0 = smooth wall
    assert phi[0] == 1.0
    assert np.max(np.abs(np.diff(phi))) < 0.01  # no jump
    dp = phi * re  # Δp ∝ φ Re at fixed geometry
    assert np.all(np.diff(dp) > 0)


def test_hose_capacitance_with_wall():
    hose = Hose(HoseParams(length_m=1.0, bore_m=4e-3, wall_bulk_modulus_pa=0.5e9))
    v = math.pi * 4e-3 ** 2 / 4
    assert hose.capacitance_m3_pa(1.5e9) == pytest.approx(v * (1 / 1.5e9 + 1 / 0.5e9))
    stiff = Hose(HoseParams(length_m=1.0, bore_m=4e-3, wall_compliance_enabled=False))
    assert stiff.capacitance_m3_pa(1.5e9) == pytest.approx(v / 1.5e9)
    assert hose.inertance_kg_m4 * 870 == pytest.approx(870 * 1.0 / v)


@pytest.mark.parametrize("field, value", [("bore_m", -0.01), ("bore_m", 0.0), ("length_m", 0.0)])
def test_hose_bad_input(field, value):
    with pytest.raises(ParameterError, match=field):
        HoseParams(**{field: value})
