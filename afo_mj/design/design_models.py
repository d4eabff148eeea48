"""Steady-state component models for the minimum-weight design tool (seed ch. 3).

Two kinds of model live here, both vectorised over numpy arrays (any broadcastable shapes):

1. **The hydraulic chain in steady state** — the component laws of
   :mod:`afo_mj.hydraulics.laws` (compiled ufuncs, evaluated here over the design arrays; the
   component library and the simulated circuits call the same functions), with every time
   derivative set to zero:

   * seal friction per cylinder (piston seal + two cable seals), the Stribeck form of
     :class:`afo_mj.hydraulics.seal.OringSeal` with its Coulomb level from seed eq. 2.7
     (``F_C = μ_f E π D d λ^1.5``), so the ankle torque is
     ``τ = −r A_e Δp_c − r n F_seal(r θ̇)`` (the ``pulley_cylinders`` component
     of :mod:`afo_mj.circuits.components`);
   * internal piston leakage ``G_l Δp_c / μ`` (laminar annular gap, Merritt §3.2);
   * line loss per hose ``Δp = R_lam Q φ(Re)`` (:mod:`afo_mj.hydraulics.conduit`: Hagen–
     Poiseuille times the laminar/turbulent friction-factor ratio; the compiled actuator is
     laminar only, so the design keeps ``Re ≤ 2000`` where ``φ = 1``);
   * pump (Wilson 1950; McCandlish & Dorey 1984, :mod:`afo_mj.hydraulics.pump`):
     ``Q = d ω − C_s d Δp/μ``, ``T = d Δp + (C_f d |Δp| + T_0) tanh(ω/ω_c) + C_v d μ ω`` with
     ``d = D/2π`` and ``|Δp|`` rounded over 10 kPa as in the kernel;
   * motor (:mod:`afo_mj.hydraulics.motor`): ``K i = T_pump + T_c tanh(ω/ω_c) + b ω``,
     ``v = R i + K ω``; driver ``P_bus = v i + R_on i² + P_q``;
   * battery (:mod:`afo_mj.hydraulics.battery`, Rint): ``P_bus = (V_oc − R_b I) I``.

2. **Sizing laws** — mass, strength and thermal laws for the parts the tool chooses (each
   function says where its law comes from; constants are in :class:`DesignAssumptions`, with
   validated ranges, and each constant's ``doc`` says whether it is a published figure or our
   assumption anchored on the two HAFO presets of :mod:`afo_mj.devices.hafo`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from afo_mj.hydraulics import laws
from afo_mj.hydraulics.geometry import annulus_area_m2
from afo_mj.hydraulics.fluid import Fluid, FluidParams
from afo_mj.hydraulics.params import ParameterError, Parameters, param
from afo_mj.hydraulics.servo_valve import ServoValveParams
from afo_mj.hydraulics.thermal import natural_convection_h_cylinder

__all__ = ["DesignAssumptions", "BatteryChemistry", "CHEMISTRIES", "ORING_CROSS_SECTIONS_M",
           "STEFAN_BOLTZMANN_W_M2_K4",
           "motor_scaling", "pump_mass_kg", "pump_inertia_kg_m2", "hose_wall_thickness_m",
           "hose_wall_mass_kg_per_m", "cable_diameter_m", "oring_cross_section_m",
           "cylinder_masses", "pulley_mass_kg",
           "oil_viscosity_pa_s", "chain_steady", "line_steady",
           "pump_steady", "SupplyFigures", "servo_centre_leak_m3_s", "supply_steady",
           "pack_geometry", "pack_thermal_resistance_k_w", "radiation_h_w_m2_k"]

STEFAN_BOLTZMANN_W_M2_K4 = 5.670374419e-8

#: Standard O-ring cross-sections (AS568 / ISO 3601-1 series 000, 100, 200, 300, 400), m.
ORING_CROSS_SECTIONS_M = (1.02e-3, 1.78e-3, 2.62e-3, 3.53e-3, 5.33e-3)


@dataclasses.dataclass(frozen=True)
class DesignAssumptions(Parameters):
    """Constants of the sizing laws. "Preset-anchored" means chosen so that the law returns the
    HAFO presets' own values (``hafo``: 100 W class motor, 0.14 kg, K = 0.055 N·m/A, 0.6 Ω,
    0.2 cm³/rev pump 0.25 kg; ``hafo_gait``: 200 W class motor 0.30 kg, 0.2 Ω, 0.6 cm³/rev pump
    0.35 kg); these are our assumptions, not catalogue data."""

    # -- motor: catalogue-style scaling with rated power P (our assumption, preset-anchored) --
    motor_reference_power_w: float = param(100.0, unit="W", lo=1.0, hi=1e4,
                                           doc="P_ref: the HAFO motor's class")
    motor_specific_power_w_kg: float = param(700.0, unit="W/kg", lo=50.0, hi=5000.0,
                                             doc="m = P / this (preset-anchored: 100 W 0.14 kg,"
                                                 " 200 W 0.29 kg vs 0.30 kg)")
    motor_constant_ref_nm_per_sqrt_w: float = param(0.071, unit="N m/sqrt(W)", lo=1e-3,
                                                    hi=10.0,
                                                    doc="k_m = K/√R at P_ref (HAFO motor: "
                                                        "0.055/√0.6)")
    motor_constant_exponent: float = param(0.75, unit="-", lo=0.3, hi=1.5,
                                           doc="k_m ∝ P^this (geometric similarity gives 2/3 "
                                               "to 5/6; 0.75 meets hafo_gait's 0.123)")
    motor_coulomb_ref_nm: float = param(0.004, unit="N m", lo=0.0, hi=1.0,
                                        doc="motor Coulomb friction at P_ref (preset)")
    motor_viscous_ref_nm_s_rad: float = param(2e-6, unit="N m s/rad", lo=0.0, hi=1e-2,
                                              doc="motor viscous friction at P_ref (preset)")
    motor_friction_exponent: float = param(0.5, unit="-", lo=0.0, hi=2.0,
                                           doc="motor friction ∝ P^this (our assumption)")
    motor_inertia_ref_kg_m2: float = param(5e-7, unit="kg m^2", lo=1e-9, hi=1e-2,
                                           doc="rotor inertia at P_ref (preset)")
    motor_inertia_exponent: float = param(1.25, unit="-", lo=0.5, hi=2.5,
                                          doc="J ∝ P^this (preset-anchored: 1.2e-6 at 200 W)")
    motor_electrical_time_constant_s: float = param(1.7e-4, unit="s", lo=1e-5, hi=1e-2,
                                                    doc="L/R of the winding (HAFO: 0.1 mH/0.6 Ω)")
    motor_max_speed_rad_s: float = param(1700.0, unit="rad/s", lo=10.0, hi=1e4,
                                         doc="largest motor speed (preset)")
    motor_continuous_loss_fraction: float = param(0.15, unit="-", lo=0.01, hi=1.0,
                                                  doc="mean copper + friction loss a motor of "
                                                      "rated power P sheds continuously, / P "
                                                      "(≈ losses of an 85 % motor at rating)")
    motor_peak_loss_ratio: float = param(10.0, unit="-", lo=1.0, hi=100.0,
                                         doc="peak / continuous copper loss for short bursts "
                                             "(≈ 3× continuous current)")
    # -- driver ------------------------------------------------------------------------------
    driver_max_current_a: float = param(60.0, unit="A", lo=1.0, hi=1000.0,
                                        doc="largest current limit of the waist-pack driver")
    # -- pump (our assumption, preset-anchored) -----------------------------------------------
    pump_reference_displacement_m3_rev: float = param(0.2e-6, unit="m^3/rev", lo=1e-9, hi=1e-3)
    pump_reference_mass_kg: float = param(0.25, unit="kg", lo=0.01, hi=10.0)
    pump_mass_exponent: float = param(0.306, unit="-", lo=0.0, hi=1.5,
                                      doc="m ∝ D^this (0.2 cm³ 0.25 kg, 0.6 cm³ 0.35 kg)")
    pump_max_pressure_pa: float = param(21e6, unit="Pa", lo=1e6, hi=1e8,
                                        doc="continuous rating of small gear pumps (~21 MPa)")
    # -- hose: wall from hoop stress with a burst factor --------------------------------------
    hose_burst_safety_factor: float = param(4.0, unit="-", lo=1.0, hi=10.0,
                                            doc="burst / working pressure (ISO 1436, SAE J517)")
    hose_wall_strength_pa: float = param(250e6, unit="Pa", lo=1e6, hi=5e9,
                                         doc="equivalent hoop strength of a braided "
                                             "thermoplastic wall (our assumption)")
    hose_min_wall_m: float = param(1.65e-3, unit="m", lo=0.0, hi=0.02,
                                   doc="liner + cover thickness (chosen so a 3.2 mm hose for "
                                       "14 MPa is 45 g/m, the HAFO budget's figure)")
    hose_wall_density_kg_m3: float = param(1300.0, unit="kg/m^3", lo=500.0, hi=8000.0)
    # -- cylinder: aluminium barrel from hoop stress, piston-cable ----------------------------
    cylinder_yield_strength_pa: float = param(276e6, unit="Pa", lo=1e7, hi=3e9,
                                              doc="6061-T6 aluminium yield strength")
    cylinder_density_kg_m3: float = param(2700.0, unit="kg/m^3", lo=1000.0, hi=9000.0)
    cylinder_safety_factor: float = param(2.0, unit="-", lo=1.0, hi=10.0,
                                          doc="on yield at the design (relief) pressure")
    cylinder_min_wall_m: float = param(1.5e-3, unit="m", lo=1e-4, hi=0.02,
                                       doc="machinable barrel wall")
    cylinder_end_cap_m: float = param(6e-3, unit="m", lo=1e-3, hi=0.05,
                                      doc="each end cap's thickness")
    cylinder_piston_length_m: float = param(8e-3, unit="m", lo=1e-3, hi=0.05,
                                            doc="piston length (adds to the barrel)")
    cylinder_hardware_kg: float = param(0.11, unit="kg", lo=0.0, hi=2.0,
                                        doc="ports, fittings, mounts per cylinder (chosen so "
                                            "the prototype's two come to its 0.26 kg budget)")
    cable_strength_pa: float = param(800e6, unit="Pa", lo=1e7, hi=5e9,
                                     doc="breaking load / nominal area of small 7x19 steel "
                                         "wire rope (≈ 2.5 kN for 2 mm)")
    cable_safety_factor: float = param(2.2, unit="-", lo=1.0, hi=10.0,
                                       doc="on the cable's breaking load at the design pressure")
    cable_min_diameter_m: float = param(1.0e-3, unit="m", lo=1e-4, hi=0.01)
    # -- pulley -------------------------------------------------------------------------------
    pulley_width_m: float = param(0.010, unit="m", lo=1e-3, hi=0.1)
    pulley_solidity: float = param(0.5, unit="-", lo=0.05, hi=1.0,
                                   doc="fraction of the pulley disc left after lightening")
    pulley_fixed_kg: float = param(0.052, unit="kg", lo=0.0, hi=2.0,
                                   doc="axle and bearings (so a 40 mm pulley is the budget's "
                                       "0.12 kg)")
    # -- battery ------------------------------------------------------------------------------
    battery_pack_factor: float = param(0.7, unit="-", lo=0.1, hi=1.0,
                                       doc="pack specific energy / cell specific energy "
                                           "(casing, wiring, BMS)")
    battery_cell_resistance_ohm_ah: float = param(0.05, unit="ohm A h", lo=1e-4, hi=10.0,
                                                  doc="cell resistance × capacity (HAFO pack: "
                                                      "16.7 mΩ per 3 Ah cell)")
    battery_min_capacity_ah: float = param(0.2, unit="A h", lo=0.01, hi=100.0)
    # -- thermal ------------------------------------------------------------------------------
    pack_mean_density_kg_m3: float = param(800.0, unit="kg/m^3", lo=100.0, hi=5000.0,
                                           doc="waist pack mass / its enclosed volume (our "
                                               "assumption for a packed enclosure)")
    pack_exposed_fraction: float = param(0.5, unit="-", lo=0.05, hi=1.0,
                                         doc="share of the pack surface open to the air (the "
                                             "rest lies against the body and clothing)")
    pack_emissivity: float = param(0.85, unit="-", lo=0.0, hi=1.0,
                                   doc="anodised or painted enclosure (Incropera Table A.11)")
    metal_specific_heat_j_kg_k: float = param(900.0, unit="J/(kg K)", lo=100.0, hi=5000.0,
                                              doc="aluminium")
    # -- circuit ------------------------------------------------------------------------------
    relief_margin: float = param(1.03, unit="-", lo=1.0, hi=2.0,
                                 doc="relief cracking / operating pressure")
    relief_override_pa: float = param(1.0e6, unit="Pa", lo=1e4, hi=1e7,
                                      doc="pressure override of the relief (preset)")
    reservoir_pressure_pa: float = param(1.5e6, unit="Pa", lo=0.0, hi=5e6,
                                         doc="charge pressure of the closed loop (preset)")
    air_fraction: float = param(0.001, unit="-", lo=0.0, hi=0.5,
                                doc="entrained air after bleeding (preset)")


@dataclasses.dataclass(frozen=True)
class BatteryChemistry:
    """Cell figures of one lithium-ion chemistry.

    Specific energies are mid-range cell-level datasheet figures of cylindrical cells (NMC
    18650/21700: 220–270 Wh/kg; NCA: 240–270 Wh/kg); the pack factor of
    :class:`DesignAssumptions` turns them into pack figures (0.7 × 240 = 168 Wh/kg, the HAFO
    pack's 170 Wh/kg). ``max_c_rate_per_h`` is the continuous discharge rating of
    power-oriented cells (our assumption: high-drain 18650 cells are rated 6–10 C). Both use the
    NMC open-circuit table of :mod:`afo_mj.hydraulics.battery`, which the compiled simulator
    holds (an approximation for NCA, whose curve spans the same 3.0–4.2 V); chemistries with
    another voltage curve (LFP) are left out because the simulator could not walk them.
    """

    name: str
    cell_specific_energy_wh_kg: float
    max_c_rate_per_h: float


CHEMISTRIES = {
    "NMC": BatteryChemistry("NMC", 240.0, 8.0),
    "NCA": BatteryChemistry("NCA", 255.0, 6.0),
}


# -- sizing laws ------------------------------------------------------------------------------
def motor_scaling(rated_power_w, a: DesignAssumptions) -> dict:
    """Motor figures at rated power ``P`` (catalogue-style power laws, our assumption).

    * mass ``m = P / s`` with the specific power ``s`` (constant over 20–1000 W, as for the
      high-power-density brushless motors of 16–40 mm);
    * motor constant ``k_m = K/√R = k_ref (P/P_ref)^α`` (the winding-independent figure of a
      catalogue, "motor constant"; copper loss at torque ``T`` is ``(T/k_m)²`` whatever the
      winding);
    * friction ``T_c, b ∝ (P/P_ref)^β``; rotor inertia ``J ∝ (P/P_ref)^γ``.

    Example: ``P = 100 W`` → 0.143 kg, ``k_m`` = 0.071 N·m/√W (the HAFO motor);
    ``P = 200 W`` → 0.286 kg, ``k_m`` = 0.119 (``hafo_gait``: 0.30 kg, 0.123).
    """
    p = np.asarray(rated_power_w, dtype=float)
    s = p / a.motor_reference_power_w
    return {"mass_kg": p / a.motor_specific_power_w_kg,
            "motor_constant_nm_per_sqrt_w": a.motor_constant_ref_nm_per_sqrt_w
            * s ** a.motor_constant_exponent,
            "coulomb_torque_nm": a.motor_coulomb_ref_nm * s ** a.motor_friction_exponent,
            "viscous_coefficient_nm_s_rad": a.motor_viscous_ref_nm_s_rad
            * s ** a.motor_friction_exponent,
            "rotor_inertia_kg_m2": a.motor_inertia_ref_kg_m2 * s ** a.motor_inertia_exponent,
            "continuous_loss_w": a.motor_continuous_loss_fraction * p}


def pump_mass_kg(displacement_m3_rev, a: DesignAssumptions):
    """``m = m_ref (D/D_ref)^κ`` (our assumption through the two presets' pumps:
    0.2 cm³/rev 0.25 kg, 0.6 cm³/rev 0.35 kg). Example: 0.1 cm³/rev → 0.203 kg."""
    return a.pump_reference_mass_kg * (np.asarray(displacement_m3_rev, dtype=float)
                                       / a.pump_reference_displacement_m3_rev) \
        ** a.pump_mass_exponent


def pump_inertia_kg_m2(displacement_m3_rev, reference_inertia_kg_m2: float,
                       a: DesignAssumptions):
    """Gear rotor inertia proportional to displacement (the ``hafo_gait`` preset's 3× for 3×)."""
    return reference_inertia_kg_m2 * np.asarray(displacement_m3_rev, dtype=float) \
        / a.pump_reference_displacement_m3_rev


def hose_wall_thickness_m(bore_m, design_pressure_pa, a: DesignAssumptions):
    """Wall thickness ``t = t_min + S p D / (2 σ)``: the thin-wall (Barlow) hoop stress
    ``σ = p D / (2 t)`` of the reinforcement at the burst pressure ``S p`` (``S`` the burst
    factor of ISO 1436 / SAE J517 hydraulic hoses, 4), plus liner and cover ``t_min``.

    Example: 3.2 mm bore, 16.5 MPa → 0.42 + 1.65 = 2.07 mm.
    """
    d = np.asarray(bore_m, dtype=float)
    p = np.asarray(design_pressure_pa, dtype=float)
    return a.hose_min_wall_m + a.hose_burst_safety_factor * p * d / (2.0 * a.hose_wall_strength_pa)


def hose_wall_mass_kg_per_m(bore_m, design_pressure_pa, a: DesignAssumptions):
    """Wall mass per metre, ``ρ_w π (D + t) t`` (annulus of thickness ``t`` on bore ``D``).

    Example: 3.2 mm bore at 16.5 MPa → 1300 · π · 5.27e-3 · 2.07e-3 ≈ 0.0446 kg/m (the HAFO
    budget counts 0.045 kg/m).
    """
    d = np.asarray(bore_m, dtype=float)
    t = hose_wall_thickness_m(d, design_pressure_pa, a)
    return a.hose_wall_density_kg_m3 * math.pi * (d + t) * t


def cable_diameter_m(max_cable_force_n, a: DesignAssumptions):
    """Smallest cable with ``S F ≤ σ_b π d²/4`` (breaking load over nominal area), at least the
    minimum diameter. Example: 1.14 kN (the HAFO at 14 MPa) → 2.0 mm."""
    f = np.asarray(max_cable_force_n, dtype=float)
    return np.maximum(np.sqrt(4.0 * a.cable_safety_factor * f / (math.pi * a.cable_strength_pa)),
                      a.cable_min_diameter_m)


def oring_cross_section_m(bore_m):
    """Piston O-ring cross-section for a bore: the usual AS568 choice grows with the gland
    (≤ 6 mm: 1.02 mm, ≤ 25 mm: 1.78 mm, ≤ 50 mm: 2.62 mm, ≤ 100 mm: 3.53 mm, else 5.33 mm);
    the HAFO's 10.4 mm bore takes 1.78 mm."""
    d = np.asarray(bore_m, dtype=float)
    cs = ORING_CROSS_SECTIONS_M
    return np.select([d <= 6e-3, d <= 25e-3, d <= 50e-3, d <= 100e-3], list(cs[:4]), cs[4])


def cylinder_masses(bore_m, stroke_m, cable_m, design_pressure_pa, oil_density_kg_m3,
                    dead_volume_m3: float, a: DesignAssumptions) -> dict:
    """Mass of one piston-cable cylinder, part by part (kg).

    * barrel: aluminium tube, wall ``t = max(t_min, S p D / (2 σ_y))`` (thin-wall hoop stress
      at the design pressure with safety factor ``S`` on yield), length stroke + piston
      + two end caps;
    * end caps: two discs of the barrel's outer diameter;
    * piston: aluminium disc of the bore, piston length long;
    * oil: swept volume ``π/4 (D² − d_c²) s`` plus both dead volumes (the areas
      :func:`~afo_mj.hydraulics.geometry.annulus_area_m2`, as
      :class:`~afo_mj.hydraulics.cylinder.CylinderParams` has them);
    * hardware: ports, fittings and mounts (constant).

    Example (the HAFO's 10.4 mm, 45 mm stroke, 2 mm cable, 15.6 MPa, VG 32): 0.130 kg each,
    0.260 kg for two (budget: 0.26 kg).
    """
    d = np.asarray(bore_m, dtype=float)
    s = np.asarray(stroke_m, dtype=float)
    c = np.asarray(cable_m, dtype=float)
    p = np.asarray(design_pressure_pa, dtype=float)
    rho = a.cylinder_density_kg_m3
    t = np.maximum(a.cylinder_min_wall_m,
                   a.cylinder_safety_factor * p * d / (2.0 * a.cylinder_yield_strength_pa))
    length = s + a.cylinder_piston_length_m + 2.0 * a.cylinder_end_cap_m
    barrel = rho * math.pi * (d + t) * t * length
    caps = 2.0 * rho * annulus_area_m2(d + 2.0 * t, 0.0) * a.cylinder_end_cap_m
    piston = rho * annulus_area_m2(d, 0.0) * a.cylinder_piston_length_m
    oil_volume = annulus_area_m2(d, c) * s + 2.0 * dead_volume_m3
    oil = np.asarray(oil_density_kg_m3, dtype=float) * oil_volume
    total = barrel + caps + piston + oil + a.cylinder_hardware_kg
    return {"barrel_kg": barrel, "caps_kg": caps, "piston_kg": piston, "oil_kg": oil,
            "oil_volume_m3": oil_volume,
            "hardware_kg": np.full_like(total, a.cylinder_hardware_kg), "total_kg": total,
            "wall_m": t, "outer_diameter_m": d + 2.0 * t}


def pulley_mass_kg(radius_m, a: DesignAssumptions):
    """Lightened aluminium disc ``ρ π r² w φ`` plus axle and bearings. Example: 40 mm → 0.120 kg."""
    r = np.asarray(radius_m, dtype=float)
    return a.cylinder_density_kg_m3 * math.pi * r ** 2 * a.pulley_width_m * a.pulley_solidity \
        + a.pulley_fixed_kg


# -- oil ------------------------------------------------------------------------------------
def oil_viscosity_pa_s(fluid: FluidParams, temperature_k):
    """Dynamic viscosity ``μ = ρ(T) ν(T)`` of ``fluid``: Walther/ASTM D341 through the oil's two
    datasheet points times ``ρ0 / (1 + β (T − T0))``, the law
    :func:`afo_mj.hydraulics.laws.dynamic_viscosity_pa_s` (through
    :meth:`afo_mj.hydraulics.fluid.Fluid.dynamic_viscosity_pa_s`).

    Example: ISO VG 32 at 298.15 K → 0.0568 Pa s.
    """
    return Fluid(fluid).dynamic_viscosity_pa_s(np.asarray(temperature_k, dtype=float))


# -- the chain in steady state ----------------------------------------------------------------
def line_steady(torque_nm, velocity_rad_s, *, r, ae, n_cyl, seal, g_leak, hose_length_m,
                hose_bore_m, mu, rho) -> dict:
    """The ankle side of :func:`chain_steady`: cylinders and hoses (no pump). Seal friction
    :func:`~afo_mj.hydraulics.laws.seal_friction_n` (no pressure part), piston leakage
    :func:`~afo_mj.hydraulics.laws.laminar_gap_flow_m3_s`, hose loss
    :func:`~afo_mj.hydraulics.laws.hose_pressure_loss_pa` (smooth wall) and its Reynolds number
    :func:`~afo_mj.hydraulics.laws.pipe_reynolds_number`."""
    tau = np.asarray(torque_nm, dtype=float)
    thd = np.asarray(velocity_rad_s, dtype=float)
    xdot = r * thd
    fc, g_st, v_st, v_c, f_v = seal
    f_seal = n_cyl * laws.seal_friction_n(xdot, 0.0, fc, g_st, v_st, v_c, f_v, 0.0)
    dp_c = -(tau + r * f_seal) / (r * ae)
    q_lk = laws.laminar_gap_flow_m3_s(dp_c, g_leak, mu)
    q = q_lk - ae * xdot
    re = laws.pipe_reynolds_number(q, hose_bore_m, mu, rho)
    dp_line = laws.hose_pressure_loss_pa(q, hose_length_m, hose_bore_m, mu, rho, 0.0, 1.0)
    return {"dp_c": dp_c, "q": q, "dp_line": dp_line, "dp_p": dp_c + 2.0 * dp_line,
            "reynolds": re, "f_seal": f_seal, "p_mech": tau * thd, "p_seal": f_seal * xdot,
            "p_leak": dp_c * q_lk, "p_line": 2.0 * dp_line * q}


def pump_steady(q, dp_p, *, mu, d, cs, cf, cv, t0, wc_pump) -> dict:
    """The pump side of :func:`chain_steady` for line flow ``q`` at pump pressure ``Δp_p``:
    speed :func:`~afo_mj.hydraulics.laws.pump_speed_for_flow_rad_s` (the inverse of the slip
    law), slip :func:`~afo_mj.hydraulics.laws.laminar_gap_flow_m3_s` through ``C_s d``,
    friction :func:`~afo_mj.hydraulics.laws.pump_friction_torque_nm`."""
    q_slip = laws.laminar_gap_flow_m3_s(dp_p, cs * d, mu)
    w_p = laws.pump_speed_for_flow_rad_s(q, dp_p, d, cs, 0.0, mu)
    t_fric = laws.pump_friction_torque_nm(w_p, dp_p, d, cf, cv, t0, wc_pump, mu)
    t_p = d * dp_p + t_fric
    return {"w_p": w_p, "t_p": t_p, "p_pump_vol": dp_p * q_slip, "p_pump_mech": t_fric * w_p,
            "p_hyd_pump": dp_p * q, "p_shaft": t_p * w_p}


@dataclasses.dataclass(frozen=True)
class SupplyFigures:
    """The valve circuits' figures the steady-state supply models use, read from the
    simulator's presets (:data:`afo_mj.devices.valve_afo.VALVE_PRESETS`: ``valve_pressure_control``
    for the servo valve, ``digital`` for the on/off valves) so a design is judged with the
    components the simulator walks."""

    margin_pa: float            # rail above the load pressure (pressure-following supply)
    rail_min_pa: float          # lowest rail
    servo_valve: ServoValveParams   # the servo valve (its centre leakage)
    servo_coil_w: float
    onoff_area_m2: float        # open area of the digital circuit's on/off valve
    onoff_cd: float
    onoff_switch_s: float
    onoff_switch_j: float       # electrical energy per switch
    onoff_hold_w: float         # holding power when energised
    pwm_hz: float
    flow_margin: float          # digital: pump flow / peak demand (the valve preset's 30 %)
    valve_block_kg: float
    accumulator_kg: float       # the pressure-following supply's small accumulator
    onoff_pcr_pa: float = 1.0e4  # the on/off valve's orifice transition pressure

    @classmethod
    def from_presets(cls) -> "SupplyFigures":
        from afo_mj.devices.valve_afo import VALVE_PRESETS
        v, g = VALVE_PRESETS["valve_pressure_control"], VALVE_PRESETS["digital"]
        sw = g.switching_valve
        return cls(margin_pa=v.supply_pressure_margin_pa, rail_min_pa=v.supply_pressure_min_pa,
                   servo_valve=v.servo_valve, servo_coil_w=v.servo_coil_power_w,
                   onoff_area_m2=sw.max_area_m2,
                   onoff_cd=sw.discharge_coefficient, onoff_switch_s=sw.switching_time_s,
                   onoff_switch_j=sw.switching_energy_j, onoff_hold_w=sw.holding_power_w,
                   pwm_hz=g.pwm_frequency_hz, flow_margin=1.3,
                   valve_block_kg=v.valve_block_mass_kg, accumulator_kg=v.accumulator_mass_kg,
                   onoff_pcr_pa=sw.transition_pressure_pa)


def servo_centre_leak_m3_s(rail_pa, sf: SupplyFigures, rho):
    """Centre leakage of the servo valve from the rail ``p_s`` to tank in oil of density
    ``rho``: :meth:`afo_mj.hydraulics.servo_valve.ServoValveParams.centre_leakage_m3_s`, the
    edges' leakage areas (sized from the maker's ``Q_L`` at ``Δp_L``) passing the orifice law
    at half the drop each, as the simulated valve's edges do — ``Q_L √(p_s/Δp_L)`` far above
    the transition pressure in oil of the rating's density.
    """
    return sf.servo_valve.centre_leakage_m3_s(rail_pa, rho)


def supply_steady(arch: str, q, dp_load, *, mu, rho, d, cs, cf, cv, t0, wc_pump,
                  sf: SupplyFigures | None = None, w_set=None) -> dict:
    """The supply side for line flow ``q`` (into port a) at the pressure difference
    ``Δp_L`` the lines need at the pack (``line_steady``'s ``dp_p``), steady state.

    * ``"pump"``: the bidirectional pump itself (:func:`pump_steady`); no valve.
    * ``"valve"`` (servo valve, rail following the load, the ``valve_pressure_control``
      preset's circuit): rail ``p_s = max(|Δp_L| + margin, p_min)``; a 4-way valve meters
      ``|q|`` from the rail whatever the quadrant and throttles ``p_s |q| − Δp_L q``; its centre
      leakage (:func:`servo_centre_leak_m3_s`) also comes from the rail; a unidirectional pump
      delivers ``|q| + leakage`` at ``p_s``; the torque motor draws its coil power.
    * ``"digital"`` (PWM unloading of a constant-speed pump, the ``digital`` preset): the pump
      turns at ``w_set`` (delivering ``d w_set``); while the load takes power the on/off valve
      sends the flow to it for the duty ``D = |q| / (d w_set − slip)`` and to tank (through the
      open valve, the orifice law's drop for ``d w_set``,
      :func:`~afo_mj.hydraulics.laws.orifice_dp_for_flow_pa`) for the rest; each of the ``2 f``
      switches a second holds the pump at the load pressure for half the switching time
      without useful flow (a linear throttle, our estimate); when the load gives power back
      the pump idles unloaded and the release valve throttles all of it. Coil power
      ``P_hold D + E_sw 2 f``.

    Returns the pump quantities of :func:`pump_steady` plus ``p_valve`` (hydraulic power the
    valves turn into heat, W), ``p_valve_el`` (their electrical power, W) and ``p_required``
    (the pump pressure the point needs, Pa: compared with the operating pressure).
    """
    q = np.asarray(q, dtype=float)
    dp = np.asarray(dp_load, dtype=float)
    kw = dict(mu=mu, d=d, cs=cs, cf=cf, cv=cv, t0=t0, wc_pump=wc_pump)
    if arch == "pump":
        out = pump_steady(q, dp, **kw)
        out.update(p_valve=np.zeros_like(out["t_p"]), p_valve_el=np.zeros_like(out["t_p"]),
                   p_required=np.abs(dp) + 0.0 * out["t_p"])
        return out
    if arch == "valve":
        ps = np.maximum(np.abs(dp) + sf.margin_pa, sf.rail_min_pa)
        qp = np.abs(q) + servo_centre_leak_m3_s(ps, sf, rho)
        out = pump_steady(qp, ps, **kw)
        out.update(p_valve=ps * qp - dp * q,
                   p_valve_el=np.full_like(out["t_p"], sf.servo_coil_w),
                   p_required=np.abs(dp) + sf.margin_pa + 0.0 * out["t_p"])
        return out
    if arch != "digital":
        raise ParameterError(f"architecture = {arch!r}; allowed: pump, valve, digital")
    w = np.asarray(w_set, dtype=float) + 0.0 * q
    adp = np.abs(dp)
    q_open = d * w
    q_dlv = np.maximum(laws.pump_flow_m3_s(w, adp, d, cs, 0.0, mu), 1e-30)
    motoring = dp * q > 0.0
    duty = np.where(motoring, np.clip(np.abs(q) / q_dlv, 0.0, 1.0), 0.0)
    switching = (duty > 0.0) & (duty < 1.0)
    d_hold = np.minimum(duty + np.where(switching, sf.onoff_switch_s * sf.pwm_hz, 0.0), 1.0)
    dp_u = laws.orifice_dp_for_flow_pa(q_open, sf.onoff_area_m2, sf.onoff_cd, rho,
                                       sf.onoff_pcr_pa)
    f_on = laws.pump_friction_torque_nm(w, adp, d, cf, cv, t0, wc_pump, mu)
    f_off = laws.pump_friction_torque_nm(w, dp_u, d, cf, cv, t0, wc_pump, mu)
    t_p = d_hold * (d * adp + f_on) + (1.0 - d_hold) * (d * dp_u + f_off)
    vol = d_hold * adp * laws.laminar_gap_flow_m3_s(adp, cs * d, mu) \
        + (1.0 - d_hold) * dp_u * laws.laminar_gap_flow_m3_s(dp_u, cs * d, mu)
    mech = (d_hold * f_on + (1.0 - d_hold) * f_off) * w
    p_hyd = t_p * w - vol - mech
    return {"w_p": w, "t_p": t_p, "p_pump_vol": vol, "p_pump_mech": mech, "p_hyd_pump": p_hyd,
            "p_shaft": t_p * w, "p_valve": p_hyd - dp * q,
            "p_valve_el": sf.onoff_hold_w * duty + np.where(
                switching, sf.onoff_switch_j * 2.0 * sf.pwm_hz, 0.0),
            "p_required": adp + 0.0 * t_p}


def chain_steady(torque_nm, velocity_rad_s, *, r, ae, n_cyl, seal, g_leak, hose_length_m,
                 hose_bore_m, mu, rho, d, cs, cf, cv, t0, wc_pump) -> dict:
    """Steady state of the hydraulic chain for a delivered ankle torque ``τ`` at ankle velocity
    ``θ̇`` (+ dorsiflexion both; all arguments broadcast).

    With the time derivatives of the kernel's states zero:

    * hydraulic torque ``τ_h = τ + r n F_seal(r θ̇)``, chamber difference ``Δp_c = −τ_h/(r A_e)``;
    * line a flow (into the pump's port a) ``q = G_l Δp_c/μ − A_e r θ̇``; hose loss
      ``Δp_h = R_lam q φ(Re)`` on each hose (the return carries ``−q``), so the pump sees
      ``Δp_p = Δp_c + 2 Δp_h``;
    * pump speed ``ω = (q + C_s d Δp_p/μ)/d`` and shaft torque ``T_p`` (module docstring).

    ``seal`` is ``(F_C, g_S, v_St, v_C, f_v)`` per cylinder (the arguments of
    :func:`~afo_mj.hydraulics.laws.seal_friction_n`). Returns
    arrays ``dp_c``, ``q``, ``dp_line`` (one hose), ``dp_p``, ``w_p``, ``t_p``, ``reynolds``,
    the powers (W) ``p_mech`` (τ θ̇, delivered), ``p_seal``, ``p_leak``, ``p_line`` (both
    hoses), ``p_pump_vol``, ``p_pump_mech``, ``p_hyd_pump`` (Δp_p q), ``p_shaft`` (T_p ω).
    Split as :func:`line_steady` then :func:`pump_steady`.
    """
    out = line_steady(torque_nm, velocity_rad_s, r=r, ae=ae, n_cyl=n_cyl, seal=seal,
                      g_leak=g_leak, hose_length_m=hose_length_m, hose_bore_m=hose_bore_m,
                      mu=mu, rho=rho)
    out.update(pump_steady(out["q"], out["dp_p"], mu=mu, d=d, cs=cs, cf=cf, cv=cv, t0=t0,
                           wc_pump=wc_pump))
    return out


# -- thermal ------------------------------------------------------------------------------------
def pack_geometry(pack_mass_kg, a: DesignAssumptions) -> dict:
    """The waist pack as a horizontal cylinder of length twice its diameter holding
    ``m / ρ_mean`` of volume: ``V = π D³/2`` (our simplification of a box-shaped pack, so the
    Churchill–Chu cylinder correlation applies); exposed area ``f (π D L + π D²/2)``.

    Example: 2.2 kg at 800 kg/m³ → 2.75 L, D = 0.121 m, exposed area 0.057 m².
    """
    v = np.asarray(pack_mass_kg, dtype=float) / a.pack_mean_density_kg_m3
    dia = (2.0 * v / math.pi) ** (1.0 / 3.0)
    area = a.pack_exposed_fraction * (math.pi * dia * 2.0 * dia + math.pi * dia ** 2 / 2.0)
    return {"volume_m3": v, "diameter_m": dia, "exposed_area_m2": area}


def radiation_h_w_m2_k(surface_k, ambient_k, emissivity: float):
    """Radiative coefficient ``h_r = ε σ (T_s² + T_∞²)(T_s + T_∞)``, exact for
    ``q = ε σ (T_s⁴ − T_∞⁴) = h_r (T_s − T_∞)`` (Incropera eq. 1.9). Example: ε = 0.85,
    310/298 K → 5.6 W/(m² K)."""
    ts = np.asarray(surface_k, dtype=float)
    ta = np.asarray(ambient_k, dtype=float)
    return emissivity * STEFAN_BOLTZMANN_W_M2_K4 * (ts * ts + ta * ta) * (ts + ta)


def pack_thermal_resistance_k_w(heat_w, diameter_m, area_m2, ambient_k, a: DesignAssumptions,
                                iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Steady surface temperature and pack-to-ambient resistance for a mean heat ``Q`` (W).

    ``T_s = T_∞ + Q R``, ``R = 1/((h_c + h_r) A)``: natural convection from
    :func:`afo_mj.hydraulics.thermal.natural_convection_h_cylinder` (Churchill–Chu) and
    radiation :func:`radiation_h_w_m2_k`, both evaluated at ``T_s`` (fixed-point iteration,
    which converges in a few sweeps since ``h`` grows slowly with ``T_s``). Returns
    ``(T_s, R)``.
    """
    q = np.maximum(np.asarray(heat_w, dtype=float), 0.0)
    ts = np.asarray(ambient_k, dtype=float) + 1.0 + 0.0 * q
    r = None
    for _ in range(iterations):
        h = natural_convection_h_cylinder(diameter_m, ts, ambient_k) \
            + radiation_h_w_m2_k(ts, ambient_k, a.pack_emissivity)
        r = 1.0 / (h * area_m2)
        ts = ambient_k + q * r
    return ts, r

