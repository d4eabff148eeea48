"""Numpy evaluations of single hydraulic components: the test suite's reference.

These classes evaluate one component on arrays (flows, forces, torques, power flows, stored
energy) from its parameter dataclass (:mod:`afo_mj.hydraulics`), each term a call to the law
the generated circuits call (:mod:`afo_mj.hydraulics.laws`). They are not package code: the
package has one class per component, the circuits' (:mod:`afo_mj.circuits.components`,
:mod:`afo_mj.circuits.valves`), which emits the component's lines into the generated stepper.
Here they are the hand-wired second implementation the tests hold the generated devices against
(tests/test_valve_device.py, tests/test_hafo_device.py, tests/kernel_reference/) and the way the
tests check the laws against textbook figures (tests/test_valves.py, tests/test_storage_thermal.py,
tests/test_actuator_pump_motor.py, tests/test_fluid_conduit.py).
"""

from __future__ import annotations

import math

import numpy as np

from afo_mj.hydraulics import laws
from afo_mj.hydraulics.laws import orifice_flow_m3_s
from afo_mj.hydraulics.accumulator import (GAS_LAW_MIN_VOLUME_FRACTION, GasAccumulatorParams,
                                           SpringAccumulatorParams)
from afo_mj.hydraulics.battery import BatteryParams
from afo_mj.hydraulics.check_valve import CheckValveParams
from afo_mj.hydraulics.conduit import HoseParams
from afo_mj.hydraulics.cylinder import CylinderParams
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA
from afo_mj.hydraulics.motor import DriverParams, MotorParams
from afo_mj.hydraulics.onoff_valve import OnOffValveParams
from afo_mj.hydraulics.orifice import OrificeParams
from afo_mj.hydraulics.params import Parameters
from afo_mj.hydraulics.power import PowerFlow
from afo_mj.hydraulics.pump import PumpParams
from afo_mj.hydraulics.relief_valve import ReliefValveParams
from afo_mj.hydraulics.seal import OringSeal
from afo_mj.hydraulics.servo_valve import ServoValveParams
from afo_mj.hydraulics.unloading_valve import UnloadingValveParams


def throttle_power(p_in_pa, p_out_pa, flow_m3_s) -> PowerFlow:
    """Power flows of a pure throttle carrying ``flow_m3_s`` from ``p_in`` to ``p_out``.

    Whichever side is upstream for the present flow direction is the input (the
    :class:`PowerFlow` convention): ``in = p_up |Q|``, ``out = p_down |Q|``,
    ``heat = (p_in − p_out) Q ≥ 0`` (``Q`` has the sign of ``p_in − p_out``), ``stored = 0``.
    For forward flow (``p_in > p_out``) this is ``in = p_in Q``, ``out = p_out Q``.
    """
    p_in = np.asarray(p_in_pa, dtype=float)
    p_out = np.asarray(p_out_pa, dtype=float)
    q = np.asarray(flow_m3_s, dtype=float)
    aq = np.abs(q)
    heat = (p_in - p_out) * q
    return PowerFlow(in_w=np.maximum(p_in, p_out) * aq, out_w=np.minimum(p_in, p_out) * aq,
                     heat_w=heat, stored_w=np.zeros_like(heat))


def smooth_max0(s, width: float):
    """``max(s, 0)`` with its corner rounded by a parabola over ``|s| < width`` (C¹).

    ``0`` for ``s ≤ −width``, ``(s + width)²/(4 width)`` between, ``s`` for ``s ≥ width``;
    ``width = 0`` gives the exact ``max(s, 0)``. (Quadratic corner smoothing, our choice.)
    This is the law :func:`afo_mj.hydraulics.laws.ramp_c1` shifted:
    ``smooth_max0(s, w) = ramp_c1(s + w, 2w)``.
    """
    w = max(float(width), 0.0)
    return laws.ramp_c1(np.asarray(s, dtype=float) + w, 2.0 * w)


def smooth_ramp01(s, width: float):
    """``clip(s, 0, 1)`` with both corners rounded over ``±width`` (``width < 0.5``; C¹).

    Exactly 0 for ``s ≤ −width``, exactly ``s`` on ``[width, 1 − width]``, exactly 1 for
    ``s ≥ 1 + width``; odd-symmetric about ``s = 1/2``. The law
    :func:`afo_mj.hydraulics.laws.poppet_opening_fraction` with start 0 and width 1.
    """
    return laws.poppet_opening_fraction(np.asarray(s, dtype=float), 0.0, 1.0,
                                        max(float(width), 0.0))


# --- from afo_mj.hydraulics.orifice
class Orifice:
    """Flow and power of one :class:`OrificeParams` restrictor."""

    def __init__(self, params: OrificeParams = OrificeParams()):
        self.params = params

    def flow_m3_s(self, p_in_pa, p_out_pa, density_kg_m3):
        """Flow from ``in`` to ``out`` (negative when reversed), :func:`orifice_flow_m3_s`."""
        p = self.params
        return orifice_flow_m3_s(np.asarray(p_in_pa, dtype=float) - p_out_pa, p.area_m2,
                                 p.discharge_coefficient, density_kg_m3,
                                 p.transition_pressure_pa)

    def power(self, p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow:
        """All of ``Δp Q`` is heat: see :func:`throttle_power`."""
        return throttle_power(p_in_pa, p_out_pa, self.flow_m3_s(p_in_pa, p_out_pa, density_kg_m3))


# --- from afo_mj.hydraulics.check_valve
class PoppetValve:
    """Shared static poppet law: opening ramp in ``Δp``, area, flow, power.

    Subclasses set ``self.params`` and the ramp start ``self._dp_start`` and width
    ``self._dp_width`` (Pa), ``self._leak_area`` (m²).
    """

    params: Parameters
    _dp_start: float
    _dp_width: float
    _leak_area: float

    def opening(self, dp_pa):
        """Poppet opening fraction ``s ∈ [0, 1]`` at pressure drop ``dp_pa = p_in − p_out``.

        ``s = ramp((Δp − Δp_start)/Δp_width)`` with rounded corners (see module docstring):
        the law :func:`afo_mj.hydraulics.laws.poppet_opening_fraction`.
        """
        return laws.poppet_opening_fraction(np.asarray(dp_pa, dtype=float), self._dp_start,
                                            self._dp_width, self.params.opening_smoothing)

    def area_m2(self, dp_pa):
        """Flow area ``A_leak + (A_max − A_leak) s(Δp)``
        (:func:`afo_mj.hydraulics.laws.valve_opening_area_m2`)."""
        return laws.valve_opening_area_m2(self.opening(dp_pa), self.params.max_area_m2,
                                          self._leak_area)

    def flow_m3_s(self, p_in_pa, p_out_pa, density_kg_m3):
        """Flow from ``in`` to ``out`` (negative = reverse flow, through the leakage only)."""
        p = self.params
        dp = np.asarray(p_in_pa, dtype=float) - p_out_pa
        return orifice_flow_m3_s(dp, self.area_m2(dp), p.discharge_coefficient, density_kg_m3,
                                 p.transition_pressure_pa)

    def power(self, p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow:
        """Throttling power: ``in = p_up |Q|``, ``out = p_down |Q|``, ``heat = Δp Q ≥ 0``
        (:func:`~afo_mj.hydraulics.orifice.throttle_power`)."""
        return throttle_power(p_in_pa, p_out_pa, self.flow_m3_s(p_in_pa, p_out_pa, density_kg_m3))


# --- from afo_mj.hydraulics.check_valve
class CheckValve(PoppetValve):
    """Opening, area, flow and power of one :class:`CheckValveParams` valve.

    Methods: :meth:`opening`, :meth:`area_m2`, :meth:`flow_m3_s`, :meth:`power` (see
    :class:`PoppetValve`); all vectorised.
    """

    def __init__(self, params: CheckValveParams = CheckValveParams()):
        self.params = params
        self._dp_start = params.cracking_pressure_pa
        self._dp_width = params.full_open_dp_pa
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0


# --- from afo_mj.hydraulics.relief_valve
class ReliefValve(PoppetValve):
    """Opening, area, flow and power of one :class:`ReliefValveParams` valve.

    Methods: ``opening(dp_pa)``, ``area_m2(dp_pa)``, ``flow_m3_s(p_in_pa, p_out_pa,
    density_kg_m3)``, ``power(p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow`` (see
    :class:`~afo_mj.hydraulics.check_valve.PoppetValve`); all vectorised.
    """

    def __init__(self, params: ReliefValveParams = ReliefValveParams()):
        self.params = params
        self._dp_start = params.cracking_dp_pa
        self._dp_width = params.override_dp_pa
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0

    def opening(self, dp_pa):
        """Opening fraction ``smoothstep01((Δp − Δp_crack)/Δp_override)`` (module docstring)."""
        return laws.smoothstep01((np.asarray(dp_pa, dtype=float) - self._dp_start)
                                 / self._dp_width)

    def area_m2(self, dp_pa):
        """Flow area, the law :func:`~afo_mj.hydraulics.laws.relief_valve_area_m2`."""
        return laws.relief_valve_area_m2(np.asarray(dp_pa, dtype=float), self._dp_start,
                                         self._dp_width, self.params.max_area_m2,
                                         self._leak_area)


# --- from afo_mj.hydraulics.unloading_valve
class UnloadingValve:
    """Position dynamics, flow and power of one :class:`UnloadingValveParams` valve."""

    def __init__(self, params: UnloadingValveParams = UnloadingValveParams()):
        self.params = params
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0

    def open_drive(self, pilot_pressure_pa):
        """``σ_open ∈ [0, 1]``: 1 at or above cut-out, 0 below ``cut_out − band``
        (:func:`~afo_mj.hydraulics.laws.unloading_open_drive`)."""
        p = self.params
        return laws.unloading_open_drive(np.asarray(pilot_pressure_pa, dtype=float),
                                         p.cut_out_pressure_pa, p.switching_band_pa)

    def close_drive(self, pilot_pressure_pa):
        """``σ_close ∈ [0, 1]``: 1 at or below cut-in, 0 above ``cut_in + band`` (without
        hysteresis: ``1 − σ_open``; :func:`~afo_mj.hydraulics.laws.unloading_close_drive`)."""
        p = self.params
        if not p.hysteresis_enabled:
            return 1.0 - self.open_drive(pilot_pressure_pa)
        return laws.unloading_close_drive(np.asarray(pilot_pressure_pa, dtype=float),
                                          p.cut_in_pressure_pa, p.switching_band_pa)

    def position_rate(self, x, pilot_pressure_pa):
        """``dx/dt = [σ_open (1 − x) − σ_close x] / τ`` (1/s): toward 1 above cut-out, toward 0
        below cut-in, exactly 0 in the hysteresis band (the valve holds its position); the law
        :func:`~afo_mj.hydraulics.laws.unloading_valve_rate_1_s`."""
        p = self.params
        return laws.unloading_valve_rate_1_s(np.asarray(x, dtype=float),
                                             np.asarray(pilot_pressure_pa, dtype=float),
                                             p.cut_out_pressure_pa, p.cut_in_pressure_pa,
                                             p.switching_band_pa, p.time_constant_s,
                                             float(p.hysteresis_enabled))

    def area_m2(self, x):
        """Flow area ``A_leak + (A_max − A_leak) clip(x, 0, 1)``
        (:func:`~afo_mj.hydraulics.laws.valve_opening_area_m2`)."""
        return laws.valve_opening_area_m2(np.asarray(x, dtype=float), self.params.max_area_m2,
                                          self._leak_area)

    def flow_m3_s(self, x, p_in_pa, p_out_pa, density_kg_m3):
        """Flow from ``in`` (pump line) to ``out`` (tank) at valve position ``x``."""
        p = self.params
        dp = np.asarray(p_in_pa, dtype=float) - p_out_pa
        return orifice_flow_m3_s(dp, self.area_m2(x), p.discharge_coefficient, density_kg_m3,
                                 p.transition_pressure_pa)

    def power(self, x, p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow:
        """Throttling power (:func:`~afo_mj.hydraulics.orifice.throttle_power`)."""
        return throttle_power(p_in_pa, p_out_pa,
                              self.flow_m3_s(x, p_in_pa, p_out_pa, density_kg_m3))


# --- from afo_mj.hydraulics.onoff_valve
class OnOffValve:
    """Position dynamics, flow, hydraulic and actuator power of one :class:`OnOffValveParams`."""

    def __init__(self, params: OnOffValveParams = OnOffValveParams()):
        self.params = params
        self._leak_area = params.leakage_area_m2 if params.leakage_enabled else 0.0

    def position_rate(self, x, command_on):
        """``dx/dt = clip((clip(u, 0, 1) − x)/τ_s, −1/T_sw, 1/T_sw)`` (1/s): the law
        :func:`~afo_mj.hydraulics.laws.onoff_valve_rate_1_s` with sharp corners."""
        p = self.params
        return laws.onoff_valve_rate_1_s(np.asarray(x, dtype=float),
                                         np.asarray(command_on, dtype=float),
                                         p.approach_time_constant_s, p.switching_time_s, 0.0)

    def area_m2(self, x):
        """Flow area ``A_leak + (A_max − A_leak) clip(x, 0, 1)``
        (:func:`~afo_mj.hydraulics.laws.valve_opening_area_m2`)."""
        return laws.valve_opening_area_m2(np.asarray(x, dtype=float), self.params.max_area_m2,
                                          self._leak_area)

    def flow_m3_s(self, x, p_in_pa, p_out_pa, density_kg_m3):
        """Flow from ``in`` to ``out`` at valve position ``x``."""
        p = self.params
        dp = np.asarray(p_in_pa, dtype=float) - p_out_pa
        return orifice_flow_m3_s(dp, self.area_m2(x), p.discharge_coefficient, density_kg_m3,
                                 p.transition_pressure_pa)

    def power(self, x, p_in_pa, p_out_pa, density_kg_m3) -> PowerFlow:
        """Hydraulic throttling power (:func:`~afo_mj.hydraulics.orifice.throttle_power`)."""
        return throttle_power(p_in_pa, p_out_pa,
                              self.flow_m3_s(x, p_in_pa, p_out_pa, density_kg_m3))

    def actuator_power_w(self, command_on, switching_rate_hz):
        """Electrical power of the actuator: ``P_hold clip(u, 0, 1) + E_sw n_sw`` (W), with
        ``switching_rate_hz`` the switching events per second (2 f for a PWM at f)."""
        p = self.params
        return (p.holding_power_w * np.clip(np.asarray(command_on, dtype=float), 0.0, 1.0)
                + p.switching_energy_j * np.asarray(switching_rate_hz, dtype=float))

    def pwm_actuator_power_w(self, duty_cycle, frequency_hz):
        """Period-average actuator power of a PWM: ``P_hold D + 2 f E_sw`` (W); a duty of 0 or
        1 does not switch."""
        d = np.clip(np.asarray(duty_cycle, dtype=float), 0.0, 1.0)
        switching = np.where((d > 0.0) & (d < 1.0), 2.0 * np.asarray(frequency_hz, dtype=float),
                             0.0)
        return self.actuator_power_w(d, switching)

    def transition_heat_j(self, dp_pa, density_kg_m3):
        """Throttling heat of one complete linear-ramp transition at constant ``Δp`` (J),
        neglecting leakage, ``τ_s`` and the regularisation: the area ramps linearly over
        ``T_sw`` so the heat is half that of the open valve over the same time,
        ``½ Δp Q_open T_sw`` (our arithmetic)."""
        p = self.params
        dp = np.asarray(dp_pa, dtype=float)
        q_open = orifice_flow_m3_s(dp, p.max_area_m2, p.discharge_coefficient, density_kg_m3,
                                   p.transition_pressure_pa)
        return 0.5 * dp * q_open * p.switching_time_s


# --- from afo_mj.hydraulics.conduit
class Hose:
    """Pressure loss, capacitance and inertance of one :class:`HoseParams` line."""

    def __init__(self, params: HoseParams):
        self.params = params
        self.area_m2 = math.pi * params.bore_m ** 2 / 4.0
        self.volume_m3 = self.area_m2 * params.length_m
        self.relative_roughness = params.roughness_m / params.bore_m

    def reynolds(self, flow_m3_s, kinematic_viscosity_m2_s):
        """``Re = |v| D / ν`` with ``v = Q / A`` (:func:`~afo_mj.hydraulics.laws.
        pipe_reynolds_number` with ``μ/ρ = ν``)."""
        return laws.pipe_reynolds_number(np.asarray(flow_m3_s, dtype=float), self.params.bore_m,
                                         kinematic_viscosity_m2_s, 1.0)

    def pressure_loss_pa(self, flow_m3_s, density_kg_m3, kinematic_viscosity_m2_s):
        """Δp from inlet to outlet for flow ``Q`` (same sign as Q): ``Δp = R_lam Q φ(Re)``
        (:func:`~afo_mj.hydraulics.laws.hose_pressure_loss_pa`)."""
        hp = self.params
        mu = np.asarray(density_kg_m3, dtype=float) * kinematic_viscosity_m2_s
        return laws.hose_pressure_loss_pa(np.asarray(flow_m3_s, dtype=float), hp.length_m,
                                          hp.bore_m, mu, density_kg_m3, self.relative_roughness,
                                          float(hp.turbulence_enabled))

    def flow_m3_s(self, dp_pa, density_kg_m3, kinematic_viscosity_m2_s):
        """Flow for a pressure drop ``Δp`` from inlet to outlet: the inverse of
        :meth:`pressure_loss_pa` (:func:`~afo_mj.hydraulics.laws.hose_flow_m3_s`)."""
        hp = self.params
        mu = np.asarray(density_kg_m3, dtype=float) * kinematic_viscosity_m2_s
        return laws.hose_flow_m3_s(np.asarray(dp_pa, dtype=float), hp.length_m, hp.bore_m, mu,
                                   density_kg_m3, self.relative_roughness,
                                   float(hp.turbulence_enabled))

    def capacitance_m3_pa(self, fluid_bulk_modulus_pa):
        """Lumped hydraulic capacitance ``C = V (1/B + 1/K_wall)`` (wall term if enabled;
        :func:`~afo_mj.hydraulics.laws.node_capacitance_m3_pa`)."""
        return laws.node_capacitance_m3_pa(self.volume_m3,
                                           np.asarray(fluid_bulk_modulus_pa, dtype=float),
                                           self.volume_m3, self.wall_compliance_inv_pa)

    @property
    def wall_compliance_inv_pa(self) -> float:
        """``1/K_wall`` with the wall compliance enabled, else 0 (a rigid wall)."""
        p = self.params
        return 1.0 / p.wall_bulk_modulus_pa if p.wall_compliance_enabled else 0.0

    @property
    def inertance_kg_m4(self) -> float:
        """``I = ρ L / A`` per unit density: multiply by density (kg/m³) to get Pa s²/m³."""
        return self.params.length_m / self.area_m2

    def power(self, p_in_pa, p_out_pa, flow_m3_s) -> PowerFlow:
        """Hydraulic power through the line; the pressure drop is dissipated as heat.

        ``in = p_in Q``, ``out = p_out Q``, ``heat = (p_in - p_out) Q`` (>= 0 for a resistive
        line; with inertance the difference also holds the column's kinetic power, passed as
        stored).
        """
        p_in = np.asarray(p_in_pa, dtype=float)
        p_out = np.asarray(p_out_pa, dtype=float)
        return PowerFlow(p_in * flow_m3_s, p_out * flow_m3_s, (p_in - p_out) * flow_m3_s, 0.0)


# --- from afo_mj.hydraulics.cylinder
class Cylinder:
    """Volumes, forces, leakage and power of one :class:`CylinderParams` cylinder."""

    def __init__(self, params: CylinderParams):
        p = self.params = params
        # the geometry is the parameters' own (CylinderParams.area_a_m2 etc.), which the tests
        # hold against hand figures (tests/test_actuator_pump_motor.py)
        self.area_a_m2, self.area_b_m2 = p.area_a_m2, p.area_b_m2
        self.piston_seal = OringSeal(p.piston_seal, p.bore_m)
        self.rod_seal = OringSeal(p.rod_seal, max(p.rod_diameter_m, 1e-6))
        # seals sliding on the rod or cable: both caps of a piston-cable cylinder, the rod's
        # cap of a double-acting one; the vented side of a single-acting one is not counted
        self.n_rod_seals = {"piston_cable": 2, "double_acting": 1}.get(p.kind, 0)
        self.leakage_conductance_m3 = p.leakage_conductance_m3

    def chamber_volumes_m3(self, position_m):
        """``(V_a, V_b)`` at piston position ``x``."""
        x = np.asarray(position_m, dtype=float)
        return (self.params.dead_volume_a_m3 + self.area_a_m2 * x,
                self.params.dead_volume_b_m3 + self.area_b_m2 * (self.params.stroke_m - x))

    def hydraulic_force_n(self, p_a_pa, p_b_pa):
        """``F_h = p_a A_a − p_b A_b − p_atm (A_a − A_b)`` (positive extends)."""
        return (self.area_a_m2 * (np.asarray(p_a_pa) - ATMOSPHERIC_PRESSURE_PA)
                - self.area_b_m2 * (np.asarray(p_b_pa) - ATMOSPHERIC_PRESSURE_PA))

    def friction_force_n(self, velocity_m_s, p_a_pa, p_b_pa):
        """Total seal friction (sign of velocity): piston seal sees ``p_a − p_b``, each rod or
        cable seal its chamber's gauge pressure."""
        if not self.params.seal_friction_enabled:
            return np.zeros_like(np.asarray(velocity_m_s, dtype=float))
        f = self.piston_seal.friction_force_n(velocity_m_s, np.asarray(p_a_pa) - p_b_pa)
        if self.n_rod_seals == 2:
            f = f + self.rod_seal.friction_force_n(velocity_m_s, np.asarray(p_a_pa)
                                                   - ATMOSPHERIC_PRESSURE_PA)
            f = f + self.rod_seal.friction_force_n(velocity_m_s, np.asarray(p_b_pa)
                                                   - ATMOSPHERIC_PRESSURE_PA)
        elif self.n_rod_seals == 1:
            f = f + self.rod_seal.friction_force_n(velocity_m_s, np.asarray(p_b_pa)
                                                   - ATMOSPHERIC_PRESSURE_PA)
        return f

    def internal_leakage_m3_s(self, p_a_pa, p_b_pa, dynamic_viscosity_pa_s):
        """Laminar annular-gap flow from chamber a to b (0 for single-acting or if disabled)."""
        dp = np.asarray(p_a_pa, dtype=float) - p_b_pa
        if not self.params.internal_leakage_enabled or self.params.kind == "single_acting":
            return np.zeros_like(dp)
        return laws.laminar_gap_flow_m3_s(dp, self.leakage_conductance_m3, dynamic_viscosity_pa_s)

    def end_stop_force_n(self, position_m, velocity_m_s):
        """Contact force of the end stops (pushes the piston back into 0 … stroke): the law
        :func:`~afo_mj.hydraulics.laws.end_stop_force_n`."""
        x = np.asarray(position_m, dtype=float)
        v = np.asarray(velocity_m_s, dtype=float)
        if not self.params.end_stops_enabled:
            return np.zeros_like(x)
        p = self.params
        return laws.end_stop_force_n(x, v, p.stroke_m, p.end_stop_stiffness_n_m,
                                     p.end_stop_damping_n_s_m)

    def end_stop_energy_j(self, position_m):
        """Elastic energy stored in the end stops, ``½ k pen²``
        (:func:`~afo_mj.hydraulics.laws.end_stop_energy_j`)."""
        x = np.asarray(position_m, dtype=float)
        if not self.params.end_stops_enabled:
            return np.zeros_like(x)
        return laws.end_stop_energy_j(x, self.params.stroke_m, self.params.end_stop_stiffness_n_m)

    def power(self, p_a_pa, p_b_pa, velocity_m_s, leakage_m3_s) -> PowerFlow:
        """Hydraulic → mechanical conversion with gauge pressures.

        ``in = F_h v + (p_a − p_b) Q_leak`` (displacement power plus the power carried by the
        leakage flow), ``out = (F_h − F_fric) v``, ``heat = F_fric v + (p_a − p_b) Q_leak``.
        """
        v = np.asarray(velocity_m_s, dtype=float)
        fh = self.hydraulic_force_n(p_a_pa, p_b_pa)
        ff = self.friction_force_n(v, p_a_pa, p_b_pa)
        leak = (np.asarray(p_a_pa) - p_b_pa) * leakage_m3_s
        return PowerFlow(fh * v + leak, (fh - ff) * v, ff * v + leak, 0.0)


# --- from afo_mj.hydraulics.pump
class Pump:
    """Flow, torque, efficiencies and power of one :class:`PumpParams` pump."""

    def __init__(self, params: PumpParams):
        p = self.params = params
        self.d_m3_rad = p.displacement_m3_rev / (2.0 * math.pi)
        self._cs = p.slip_coefficient if p.leakage_enabled else 0.0
        self._cf = p.coulomb_coefficient if p.coulomb_friction_enabled else 0.0
        self._cv = p.viscous_coefficient if p.viscous_friction_enabled else 0.0

    def _fraction(self, displacement_fraction):
        if self.params.variable_displacement_enabled:
            return np.clip(displacement_fraction, -1.0, 1.0)
        return 1.0

    def leakage_m3_s(self, dp_pa, dynamic_viscosity_pa_s):
        """Slip flow from a to b, ``C_s D Δp / (2π μ)``: laminar leakage through the
        conductance ``C_s d`` (:func:`~afo_mj.hydraulics.laws.laminar_gap_flow_m3_s`)."""
        return laws.laminar_gap_flow_m3_s(np.asarray(dp_pa, dtype=float),
                                          self._cs * self.d_m3_rad, dynamic_viscosity_pa_s)

    def flow_m3_s(self, speed_rad_s, dp_pa, dynamic_viscosity_pa_s, displacement_fraction=1.0):
        """Flow delivered into port a (drawn from b): ``ε d ω − Q_leak``
        (:func:`~afo_mj.hydraulics.laws.pump_flow_m3_s`; the slip ``C_s d`` is that of the
        full displacement, so it enters as the law's extra conductance)."""
        eps = self._fraction(displacement_fraction)
        return laws.pump_flow_m3_s(np.asarray(speed_rad_s, dtype=float),
                                   np.asarray(dp_pa, dtype=float), eps * self.d_m3_rad, 0.0,
                                   self._cs * self.d_m3_rad, dynamic_viscosity_pa_s)

    def friction_torque_nm(self, speed_rad_s, dp_pa, dynamic_viscosity_pa_s):
        """Loss torque (sign of ω): Coulomb ∝ |Δp| D (``|Δp|`` rounded over 10 kPa), viscous
        ∝ μ ω, constant drag (:func:`~afo_mj.hydraulics.laws.pump_friction_torque_nm`)."""
        p = self.params
        return laws.pump_friction_torque_nm(np.asarray(speed_rad_s, dtype=float),
                                            np.asarray(dp_pa, dtype=float), self.d_m3_rad,
                                            self._cf, self._cv, p.drag_torque_nm,
                                            p.smoothing_speed_rad_s, dynamic_viscosity_pa_s)

    def shaft_torque_nm(self, speed_rad_s, dp_pa, dynamic_viscosity_pa_s,
                        displacement_fraction=1.0):
        """Torque the drive must supply: ``ε d Δp + T_friction``."""
        eps = self._fraction(displacement_fraction)
        return eps * self.d_m3_rad * np.asarray(dp_pa, dtype=float) + \
            self.friction_torque_nm(speed_rad_s, dp_pa, dynamic_viscosity_pa_s)

    def efficiencies(self, speed_rad_s, dp_pa, dynamic_viscosity_pa_s, displacement_fraction=1.0):
        """``(η_v, η_m, η_total)`` in the pumping quadrant (ω > 0, Δp > 0)."""
        eps = self._fraction(displacement_fraction)
        q_ideal = eps * self.d_m3_rad * np.asarray(speed_rad_s, dtype=float)
        q = self.flow_m3_s(speed_rad_s, dp_pa, dynamic_viscosity_pa_s, displacement_fraction)
        t = self.shaft_torque_nm(speed_rad_s, dp_pa, dynamic_viscosity_pa_s, displacement_fraction)
        eta_v = q / q_ideal
        eta_m = eps * self.d_m3_rad * np.asarray(dp_pa, dtype=float) / t
        return eta_v, eta_m, eta_v * eta_m

    def power(self, speed_rad_s, dp_pa, dynamic_viscosity_pa_s,
              displacement_fraction=1.0) -> PowerFlow:
        """``in = T ω`` (shaft), ``out = Δp Q`` (hydraulic), ``heat = T_f ω + Δp Q_leak``."""
        w = np.asarray(speed_rad_s, dtype=float)
        dp = np.asarray(dp_pa, dtype=float)
        t = self.shaft_torque_nm(w, dp, dynamic_viscosity_pa_s, displacement_fraction)
        q = self.flow_m3_s(w, dp, dynamic_viscosity_pa_s, displacement_fraction)
        heat = (self.friction_torque_nm(w, dp, dynamic_viscosity_pa_s) * w
                + dp * self.leakage_m3_s(dp, dynamic_viscosity_pa_s))
        return PowerFlow(t * w, dp * q, heat, 0.0)


# --- from afo_mj.hydraulics.motor
class BrushlessMotor:
    """Electrical and mechanical equations of a :class:`MotorParams` motor and its driver."""

    def __init__(self, motor: MotorParams, driver: DriverParams = DriverParams()):
        self.params = motor
        self.driver = driver

    def applied_voltage_v(self, command_v, speed_rad_s, bus_voltage_v):
        """Voltage the driver applies: command clipped to the current-limit band
        ``K ω ± R I_max`` and the duty range ``± d V_bus``, both with 0.05 V rounded corners
        (:func:`~afo_mj.hydraulics.laws.driver_voltage_v`)."""
        d, m = self.driver, self.params
        return laws.driver_voltage_v(np.asarray(command_v, dtype=float),
                                     m.torque_constant_nm_a * np.asarray(speed_rad_s, dtype=float),
                                     m.resistance_ohm, d.current_limit_a,
                                     float(d.current_limit_enabled), d.max_duty,
                                     np.asarray(bus_voltage_v, dtype=float))

    def friction_torque_nm(self, speed_rad_s):
        """``T_f = T_c tanh(ω/ω_c) + b ω`` (:func:`~afo_mj.hydraulics.laws.
        motor_friction_torque_nm`), 0 with friction disabled."""
        m = self.params
        w = np.asarray(speed_rad_s, dtype=float)
        if not m.friction_enabled:
            return np.zeros_like(w)
        return laws.motor_friction_torque_nm(w, m.coulomb_torque_nm,
                                             m.viscous_coefficient_nm_s_rad,
                                             m.smoothing_speed_rad_s)

    def current_rate_a_s(self, voltage_v, current_a, speed_rad_s):
        """``di/dt = (v − R i − K ω) / L``."""
        m = self.params
        return (voltage_v - m.resistance_ohm * current_a
                - m.torque_constant_nm_a * speed_rad_s) / m.inductance_h

    def electromagnetic_torque_nm(self, current_a):
        return self.params.torque_constant_nm_a * np.asarray(current_a, dtype=float)

    def bus_power_w(self, voltage_v, current_a):
        """Power drawn from the bus: ``v i + R_on i² + P_q``."""
        i = np.asarray(current_a, dtype=float)
        return voltage_v * i + self.driver.on_resistance_ohm * i * i + self.driver.quiescent_power_w

    def power(self, voltage_v, current_a, speed_rad_s, current_rate_a_s) -> PowerFlow:
        """Motor alone: ``in = v i``; ``out = (K i − T_f) ω`` (to the shaft, inertia torque
        included in ``out`` of the rotor balance); ``heat = R i² + T_f ω``;
        ``stored = L i di/dt``."""
        m = self.params
        i = np.asarray(current_a, dtype=float)
        w = np.asarray(speed_rad_s, dtype=float)
        tf = self.friction_torque_nm(w)
        return PowerFlow(voltage_v * i, (m.torque_constant_nm_a * i - tf) * w,
                         m.resistance_ohm * i * i + tf * w,
                         m.inductance_h * i * current_rate_a_s)

    def driver_power(self, voltage_v, current_a) -> PowerFlow:
        """Driver: ``in = P_bus``, ``out = v i``, ``heat = R_on i² + P_q``."""
        i = np.asarray(current_a, dtype=float)
        heat = self.driver.on_resistance_ohm * i * i + self.driver.quiescent_power_w
        return PowerFlow(voltage_v * i + heat, voltage_v * i, heat, 0.0)


# --- from afo_mj.hydraulics.accumulator
class _Accumulator:
    """Shared flags and power report; subclasses define pressure and energy."""

    capacity_m3: float
    stop_stiffness_pa_m3: float

    def over_capacity(self, fluid_volume_m3):
        """True where ``Vf`` exceeds the usable capacity :attr:`capacity_m3`."""
        return np.asarray(fluid_volume_m3, dtype=float) > self.capacity_m3

    def below_empty(self, fluid_volume_m3):
        """True where ``Vf < 0`` (separator or piston on its empty stop)."""
        return np.asarray(fluid_volume_m3, dtype=float) < 0.0

    def _vent_pressure_pa(self) -> float:
        return 0.0

    def power(self, fluid_volume_m3, flow_in_m3_s) -> PowerFlow:
        """Power flows for fluid entering at ``flow_in_m3_s`` (negative when discharging).

        ``in = p Q``, ``out = p_vent Q`` (air pushed through the spring-side vent; 0 for the
        sealed gas kind), ``heat = 0`` (the polytropic law is reversible), ``stored = in − out``
        = ``d(stored_energy_j)/dt``.

        Example (gas defaults, empty, 1 cm³/s in): ``in_w = stored_w = 1.5e6·1e-6 = 1.5`` W.
        """
        p = self.pressure_pa(fluid_volume_m3)
        q = np.asarray(flow_in_m3_s, dtype=float)
        p_in = p * q
        p_out = self._vent_pressure_pa() * q
        return PowerFlow(in_w=p_in, out_w=p_out, heat_w=np.zeros_like(p_in),
                         stored_w=p_in - p_out)


# --- from afo_mj.hydraulics.accumulator
class GasAccumulator(_Accumulator):
    """Polytropic gas-charged accumulator (see the module docstring for the limit rules)."""

    def __init__(self, params: GasAccumulatorParams = GasAccumulatorParams()):
        self.params = p = params
        v0, p0, n = p.gas_volume_m3, p.precharge_pressure_pa, p.polytropic_index
        #: ``B_stop / V_port``: pressure slope at the empty stop, Pa/m³.
        self.stop_stiffness_pa_m3 = p.stop_bulk_modulus_pa / p.port_volume_m3
        #: Residual gas volume where the gas law hands over to its tangent.
        self.knee_gas_volume_m3 = GAS_LAW_MIN_VOLUME_FRACTION * v0
        self.knee_fluid_volume_m3 = v0 - self.knee_gas_volume_m3
        self.knee_pressure_pa = float(laws.gas_accumulator_pressure_pa(
            self.knee_fluid_volume_m3, v0, p0, n))
        self.knee_stiffness_pa_m3 = n * self.knee_pressure_pa / self.knee_gas_volume_m3
        self.knee_energy_j = float(self._gas_energy(self.knee_gas_volume_m3))
        #: Usable fluid volume between precharge and maximum pressure,
        #: ``V0 (1 − (p0/p_max)^(1/n))``.
        self.capacity_m3 = float(laws.gas_accumulator_oil_volume_m3(p.max_pressure_pa, v0, p0, n))

    def gas_volume_m3(self, fluid_volume_m3):
        """``V_g = V0 − Vf`` clipped to ``[knee volume, V0]`` (where the gas law holds)."""
        p = self.params
        vf = np.asarray(fluid_volume_m3, dtype=float)
        return np.clip(p.gas_volume_m3 - vf, self.knee_gas_volume_m3, p.gas_volume_m3)

    def _gas_energy(self, gas_volume_m3):
        # E = p0 V0 (r^(n-1) - 1)/(n - 1), r = V0/Vg (laws.polytropic_gas_energy_j)
        p = self.params
        return laws.polytropic_gas_energy_j(np.asarray(gas_volume_m3, dtype=float),
                                            p.gas_volume_m3, p.precharge_pressure_pa,
                                            p.polytropic_index)

    def pressure_pa(self, fluid_volume_m3):
        """Absolute port pressure at stored volume ``Vf``.

        ``p = p0 (V0/(V0 − Vf))^n`` for ``0 <= Vf <= V0 − V_knee`` (``p V_g^n`` constant);
        ``p = p0 + (B_stop/V_port) Vf`` for ``Vf < 0`` (empty stop); the tangent line beyond
        the knee volume ``V_knee = 0.01 V0``.

        Example (defaults V0 = 75 cm³, p0 = 1.5 MPa, n = 1.4): ``pressure_pa(25e-6)`` →
        ``1.5e6·1.5^1.4 = 2.64e6`` Pa.
        """
        p = self.params
        vf = np.asarray(fluid_volume_m3, dtype=float)
        p_gas = laws.gas_accumulator_pressure_pa(np.clip(vf, 0.0, self.knee_fluid_volume_m3),
                                                 p.gas_volume_m3, p.precharge_pressure_pa,
                                                 p.polytropic_index)
        p_empty = p.precharge_pressure_pa + self.stop_stiffness_pa_m3 * vf
        dv = vf - self.knee_fluid_volume_m3
        p_knee = self.knee_pressure_pa + self.knee_stiffness_pa_m3 * dv
        return np.where(vf < 0.0, p_empty, np.where(vf > self.knee_fluid_volume_m3, p_knee, p_gas))

    def stiffness_pa_m3(self, fluid_volume_m3):
        """``dp/dVf``: ``n p / V_g`` on the gas law, the stop or tangent slope beyond it."""
        p = self.params
        vf = np.asarray(fluid_volume_m3, dtype=float)
        vg = self.gas_volume_m3(vf)
        k_gas = p.polytropic_index * self.pressure_pa(np.clip(vf, 0.0, None)) / vg
        return np.where(vf < 0.0, self.stop_stiffness_pa_m3,
                        np.where(vf > self.knee_fluid_volume_m3, self.knee_stiffness_pa_m3, k_gas))

    def fluid_volume_m3(self, pressure_pa):
        """Stored volume at absolute pressure ``p``: the inverse of :meth:`pressure_pa` for
        ``Vf >= 0``, ``Vf = V0 (1 − (p0/p)^(1/n))``, and 0 at or below the precharge.

        Example (defaults): ``fluid_volume_m3(6e6)`` = capacity = ``75e-6 (1 − 0.25^(1/1.4))``
        = 4.71e-5 m³.
        """
        p = self.params
        pr = np.asarray(pressure_pa, dtype=float)
        vf_gas = laws.gas_accumulator_oil_volume_m3(pr, p.gas_volume_m3, p.precharge_pressure_pa,
                                                    p.polytropic_index)
        vf_knee = self.knee_fluid_volume_m3 \
            + (pr - self.knee_pressure_pa) / self.knee_stiffness_pa_m3
        return np.where(pr > self.knee_pressure_pa, vf_knee, vf_gas)

    def stored_energy_j(self, fluid_volume_m3):
        """Gas compression energy from the precharge state, ``∫_0^Vf p dVf = ∫_{Vg}^{V0} p dV``.

        ``(p V_g − p0 V0)/(n − 1)`` for ``n ≠ 1``, ``p0 V0 ln(V0/V_g)`` for ``n = 1``; in the
        limit regions the integral of the continued pressure law (``p0 Vf + ½ s Vf²`` below
        empty, negative there).

        Example (defaults, ``Vf = 25`` cm³): ``(2.64e6·50e-6 − 1.5e6·75e-6)/0.4`` = 49.5 J.
        """
        vf = np.asarray(fluid_volume_m3, dtype=float)
        p0 = self.params.precharge_pressure_pa
        e_gas = self._gas_energy(self.gas_volume_m3(vf))
        e_empty = p0 * vf + 0.5 * self.stop_stiffness_pa_m3 * vf * vf
        dv = vf - self.knee_fluid_volume_m3
        e_knee = self.knee_energy_j + self.knee_pressure_pa * dv \
            + 0.5 * self.knee_stiffness_pa_m3 * dv * dv
        return np.where(vf < 0.0, e_empty, np.where(dv > 0.0, e_knee, e_gas))


# --- from afo_mj.hydraulics.accumulator
class SpringAccumulator(_Accumulator):
    """Spring-loaded piston accumulator (see the module docstring for the stop rules)."""

    def __init__(self, params: SpringAccumulatorParams = SpringAccumulatorParams()):
        self.params = p = params
        #: ``B_stop / V_port``: pressure slope on either stop, Pa/m³.
        self.stop_stiffness_pa_m3 = p.stop_bulk_modulus_pa / p.port_volume_m3
        #: Usable volume ``A · stroke``.
        self.capacity_m3 = p.piston_area_m2 * p.stroke_m

    def _vent_pressure_pa(self) -> float:
        return self.params.vent_pressure_pa

    def piston_position_m(self, fluid_volume_m3):
        """``x = Vf / A`` clipped to ``[0, stroke]``."""
        p = self.params
        return np.clip(np.asarray(fluid_volume_m3, dtype=float) / p.piston_area_m2, 0.0, p.stroke_m)

    def pressure_pa(self, fluid_volume_m3):
        """``p = p_vent + (F0 + k x)/A``, ``x = Vf/A`` on ``0 <= Vf <= A·stroke``; beyond either
        end the stop stiffness ``B_stop/V_port`` continues from the end pressure.

        Example (defaults, half stroke ``Vf = 9.82`` cm³): ``101325 + (200 + 1e4·0.02)/4.909e-4``
        = 9.16e5 Pa.
        """
        return laws.spring_accumulator_pressure_pa(np.asarray(fluid_volume_m3, dtype=float),
                                                   *self._law_args())

    def stiffness_pa_m3(self, fluid_volume_m3):
        """``dp/dVf``: ``k/A²`` in the stroke, ``B_stop/V_port`` on the stops (the inverse of
        :func:`~afo_mj.hydraulics.laws.spring_accumulator_capacitance_m3_pa` at the pressure
        of ``Vf``)."""
        return 1.0 / laws.spring_accumulator_capacitance_m3_pa(self.pressure_pa(fluid_volume_m3),
                                                               *self._law_args())

    def _law_args(self) -> tuple:
        p = self.params
        return (p.piston_area_m2, p.spring_rate_n_m, p.preload_n, p.stroke_m,
                p.vent_pressure_pa, self.stop_stiffness_pa_m3)

    def fluid_volume_m3(self, pressure_pa):
        """Inverse of :meth:`pressure_pa` for ``Vf >= 0``: ``A ((p − p_vent) A − F0)/k`` in the
        stroke, 0 below the cracking pressure, the top-stop line above the full pressure."""
        return laws.spring_accumulator_oil_volume_m3(np.asarray(pressure_pa, dtype=float),
                                                     *self._law_args())

    def stored_energy_j(self, fluid_volume_m3):
        """Spring energy ``F0 x + ½ k x²`` (``= ∫_0^Vf (p − p_vent) dVf``); on the stops the
        integral of the stop law is added (liquid compression), so it stays the integral of
        ``p − p_vent``.

        Example (defaults, full stroke): ``200·0.04 + ½·1e4·0.04²`` = 16 J.
        """
        return laws.spring_accumulator_energy_j(np.asarray(fluid_volume_m3, dtype=float),
                                                *self._law_args())


# --- from afo_mj.hydraulics.servo_valve
class ServoValve:
    """Spool dynamics, edge areas, port flows and power of one :class:`ServoValveParams` valve."""

    def __init__(self, params: ServoValveParams = ServoValveParams()):
        p = self.params = params
        self.omega_n_rad_s = 2.0 * math.pi * p.natural_frequency_hz
        # the edges' sizing is the parameters' own (ServoValveParams.area_gradient_m, ...)
        self.overlap_m = p.effective_overlap_m
        #: area gradient w (m²/m): port width of each metering edge
        self.area_gradient_m = p.area_gradient_m
        #: leakage area of each edge (m²), 0 with leakage disabled
        self.leakage_area_m2 = p.leakage_area_m2

    def spool_target_m(self, command):
        """``x_ref = clip(u, −1, 1) · x_max``."""
        return np.clip(np.asarray(command, dtype=float), -1.0, 1.0) * self.params.spool_max_m

    def spool_derivatives(self, x_m, v_m_s, command):
        """``(dx/dt, dv/dt)`` of the spool: ``ẋ = v``, ``v̇ = ω_n² (x_ref − x) − 2 ζ ω_n v``."""
        x = np.asarray(x_m, dtype=float)
        v = np.asarray(v_m_s, dtype=float)
        w = self.omega_n_rad_s
        dv = w * w * (self.spool_target_m(command) - x) - 2.0 * self.params.damping_ratio * w * v
        return v + 0.0 * x, dv

    def edge_areas_m2(self, x_m):
        """``(A_PA, A_AT, A_PB, A_BT)`` (m²) at spool position ``x_m`` (clipped to ±x_max)."""
        p = self.params
        x = np.asarray(x_m, dtype=float)
        args = (p.spool_max_m, self.overlap_m, self.area_gradient_m, p.opening_smoothing_m,
                self.leakage_area_m2)
        a_pos = laws.spool_edge_area_m2(x, *args)
        a_neg = laws.spool_edge_area_m2(-x, *args)
        return a_pos, a_neg, a_neg, a_pos

    def edge_flows_m3_s(self, x_m, p_p_pa, p_t_pa, p_a_pa, p_b_pa, density_kg_m3):
        """``(Q_PA, Q_AT, Q_PB, Q_BT)``: flow through each edge in its named direction."""
        p = self.params
        a_pa, a_at, a_pb, a_bt = self.edge_areas_m2(x_m)
        pp, pt, pa, pb = (np.asarray(v, dtype=float) for v in (p_p_pa, p_t_pa, p_a_pa, p_b_pa))
        cd, pcr = p.discharge_coefficient, p.transition_pressure_pa
        return (orifice_flow_m3_s(pp - pa, a_pa, cd, density_kg_m3, pcr),
                orifice_flow_m3_s(pa - pt, a_at, cd, density_kg_m3, pcr),
                orifice_flow_m3_s(pp - pb, a_pb, cd, density_kg_m3, pcr),
                orifice_flow_m3_s(pb - pt, a_bt, cd, density_kg_m3, pcr))

    def flows_m3_s(self, x_m, p_p_pa, p_t_pa, p_a_pa, p_b_pa, density_kg_m3):
        """``(Q_A, Q_B, Q_P, Q_T)``: net flow out of the valve into line A and into line B,
        flow drawn from the supply P, flow returned to tank T."""
        q_pa, q_at, q_pb, q_bt = self.edge_flows_m3_s(x_m, p_p_pa, p_t_pa, p_a_pa, p_b_pa,
                                                      density_kg_m3)
        return q_pa - q_at, q_pb - q_bt, q_pa + q_pb, q_at + q_bt

    def power(self, x_m, p_p_pa, p_t_pa, p_a_pa, p_b_pa, density_kg_m3) -> PowerFlow:
        """Throttling power summed over the four edges (see module docstring)."""
        pp, pt, pa, pb = (np.asarray(v, dtype=float) for v in (p_p_pa, p_t_pa, p_a_pa, p_b_pa))
        flows = self.edge_flows_m3_s(x_m, pp, pt, pa, pb, density_kg_m3)
        ends = ((pp, pa), (pa, pt), (pp, pb), (pb, pt))
        p_in = p_out = heat = 0.0
        for q, (up, down) in zip(flows, ends):
            aq = np.abs(q)
            p_in = p_in + np.maximum(up, down) * aq
            p_out = p_out + np.minimum(up, down) * aq
            heat = heat + (up - down) * q
        return PowerFlow(in_w=p_in, out_w=p_out, heat_w=heat, stored_w=np.zeros_like(heat))


# --- from afo_mj.hydraulics.battery
class Battery:
    """Rint equivalent circuit of a :class:`BatteryParams` pack (vectorised over SOC/current)."""

    def __init__(self, params: BatteryParams = BatteryParams()):
        self.params = p = params
        #: Charge in coulombs.
        self.capacity_c = 3600.0 * p.capacity_ah
        # the table's figures are the parameters' own (BatteryParams.energy_wh, ...), which
        # tests/test_storage_thermal.py holds against the trapezoid integral of the table
        self.energy_wh = p.energy_wh
        self.nominal_voltage_v = p.nominal_voltage_v
        self.specific_energy_wh_kg = p.specific_energy_wh_kg

    def open_circuit_voltage_v(self, soc):
        """:meth:`BatteryParams.open_circuit_voltage_v`."""
        return self.params.open_circuit_voltage_v(soc)

    def terminal_voltage_v(self, soc, current_a):
        """``V_term = V_oc − R I`` (``I > 0`` discharging).

        Example (defaults): ``terminal_voltage_v(0.5, 10)`` → ``22.5 − 1.2 = 21.3`` V.
        """
        return self.open_circuit_voltage_v(soc) - self.params.internal_resistance_ohm * \
            np.asarray(current_a, dtype=float)

    def max_power_w(self, soc):
        """Largest terminal power the pack can deliver, ``V_oc² / (4R)`` (at ``I = V_oc/(2R)``,
        half the open-circuit voltage across the load; matched-load theorem).

        Example (defaults, SOC 0.5): ``22.5²/0.48`` = 1055 W.
        """
        v = self.open_circuit_voltage_v(soc)
        return v * v / (4.0 * self.params.internal_resistance_ohm)

    def power_limited(self, soc, power_w):
        """True where ``power_w`` exceeds :meth:`max_power_w` (the current is then clipped)."""
        return np.asarray(power_w, dtype=float) > self.max_power_w(soc)

    def current_for_power_a(self, soc, power_w):
        """Pack current that delivers terminal power ``P = V_term I`` (negative ``P`` charges).

        Root of ``R I² − V_oc I + P = 0`` on the stable branch,
        ``I = (V_oc − sqrt(V_oc² − 4 R P)) / (2R) = 2P / (V_oc + sqrt(V_oc² − 4 R P))``
        (the second form, used here, has no cancellation at small ``P``). ``P`` is first clipped
        to :meth:`max_power_w`, so the result is finite: ``V_oc/(2R)`` at and beyond the limit
        (see :meth:`power_limited`). The law :func:`afo_mj.hydraulics.laws.battery_current_a`.

        Example (defaults, SOC 0.5, 200 W): ``2·200/(22.5 + sqrt(22.5² − 96))`` = 9.36 A.
        """
        return laws.battery_current_a(np.asarray(power_w, dtype=float),
                                      self.open_circuit_voltage_v(soc),
                                      self.params.internal_resistance_ohm)

    def over_current(self, current_a):
        """True where ``|I|`` exceeds ``max_current_a``."""
        return np.abs(np.asarray(current_a, dtype=float)) > self.params.max_current_a

    def soc_rate_per_s(self, current_a):
        """``dSOC/dt = −I / (3600 C_Ah)`` (coulomb counting).

        Example (defaults): 10 A → ``−10/9000 = −1.11e-3`` 1/s.
        """
        return -np.asarray(current_a, dtype=float) / self.capacity_c

    def stored_energy_j(self, soc):
        """:meth:`BatteryParams.stored_energy_j`."""
        return self.params.stored_energy_j(soc)

    def power(self, soc, current_a) -> PowerFlow:
        """Power flows at ``(SOC, I)``: ``in = 0``, ``out = V_term I``, ``heat = R I²``,
        ``stored = −V_oc I`` (see the module docstring).

        Example (defaults, SOC 0.5, 10 A): out 213 W, heat 12 W, stored −225 W.
        """
        i = np.asarray(current_a, dtype=float)
        v_oc = self.open_circuit_voltage_v(soc)
        r = self.params.internal_resistance_ohm
        out = (v_oc - r * i) * i
        return PowerFlow(in_w=np.zeros_like(out), out_w=out, heat_w=r * i * i, stored_w=-v_oc * i)
