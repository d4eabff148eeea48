"""Fixed- and variable-displacement pumps with a viscous/Coulomb/leakage loss model.

Loss model (Wilson 1950; McCandlish & Dorey 1984, *The mathematical modelling of hydrostatic
pumps and motors*, Proc. IMechE B 198:165), for a pump between ports a and b with
``Δp = p_a − p_b`` and displacement ``D`` per revolution (``d = ε D / 2π`` per radian, ``ε`` the
displacement fraction, 1 for a fixed pump):

* delivered flow into port a: ``Q = d ω − C_s D Δp / (2π μ)`` (slip/leakage ∝ Δp/μ)
* shaft torque: ``T = d Δp + C_f D |Δp|/(2π) tanh(ω/ω_c) + C_v D μ ω/(2π) + T_0 tanh(ω/ω_c)``
  (Coulomb part ∝ Δp·D, viscous part ∝ μ·ω, a constant drag ``T_0``; ``|Δp|`` rounded to
  ``√(Δp² + (10 kPa)²)``, which keeps the Coulomb kink at equal port pressures out of an
  implicit integrator's Jacobian).

The equations are the laws :func:`~afo_mj.hydraulics.laws.pump_flow_m3_s`,
:func:`~afo_mj.hydraulics.laws.laminar_gap_flow_m3_s` and
:func:`~afo_mj.hydraulics.laws.pump_friction_torque_nm`, which the circuits and the design tool
evaluate too.

These hold in all four quadrants (pumping and motoring, either direction) and give

    T ω − Δp Q = (friction torque) ω + Δp Q_leak ≥ 0

exactly, the heat of the pump. Volumetric efficiency ``η_v = Q/(d ω)`` and mechanical
efficiency ``η_m = d Δp / T`` (pumping quadrant) fall with Δp (leakage, Coulomb), η_v falls as
μ or speed falls, η_m falls as μ·ω rises.

The presets' coefficients are chosen so the rated-point efficiencies match typical small gear
and axial-piston units (stated at each preset).
"""

from __future__ import annotations

import dataclasses

from .params import Parameters, effect, param


@dataclasses.dataclass(frozen=True)
class PumpParams(Parameters):
    """A bidirectional positive-displacement pump/motor."""

    kind: str = "gear"
    displacement_m3_rev: float = param(0.2e-6, unit="m^3/rev", lo=0.0, hi=1e-3, lo_open=True,
                                       doc="geometric displacement per revolution D")
    slip_coefficient: float = param(1.2e-7, unit="-", lo=0.0, hi=1e-4,
                                    doc="C_s: leakage Q = C_s D Δp / (2π μ)")
    coulomb_coefficient: float = param(0.05, unit="-", lo=0.0, hi=1.0,
                                       doc="C_f: friction torque C_f D |Δp| / 2π")
    viscous_coefficient: float = param(1.8e4, unit="-", lo=0.0, hi=1e8,
                                       doc="C_v: viscous torque C_v D μ ω / 2π")
    drag_torque_nm: float = param(0.002, unit="N m", lo=0.0, hi=100.0,
                                  doc="T_0: constant drag torque")
    smoothing_speed_rad_s: float = param(1.0, unit="rad/s", lo=1e-6, hi=1e3,
                                         doc="ω_c of tanh(ω/ω_c) for friction sign")
    max_speed_rad_s: float = param(1200.0, unit="rad/s", lo=0.0, hi=1e5, lo_open=True)
    rotor_inertia_kg_m2: float = param(2e-7, unit="kg m^2", lo=0.0, hi=1.0)
    variable_displacement_enabled: bool = effect(
        False, doc="displacement fraction ε in [-1, 1] is an input (variable-displacement pump)")
    leakage_enabled: bool = effect(True, doc="slip flow ∝ Δp/μ")
    coulomb_friction_enabled: bool = effect(True, doc="friction torque ∝ Δp D")
    viscous_friction_enabled: bool = effect(True, doc="friction torque ∝ μ ω")

    def check(self) -> None:
        if self.kind not in ("gear", "axial_piston"):
            self.fail("kind", "allowed: gear, axial_piston")


#: Small external gear pump, 0.2 cm³/rev: η_v ≈ 0.93, η_m ≈ 0.92 at 10 MPa, 4000 rpm, μ = 0.04 Pa s
#: (VG 46 at 40 °C): slip 7 %, Coulomb 5 %, viscous 3 %, drag 0.6 % of the ideal torque.
GEAR_PUMP_SMALL = PumpParams()
#: Miniature axial-piston pump, 0.4 cm³/rev: η_v ≈ 0.96, η_m ≈ 0.95 at 10 MPa, 3000 rpm,
#: μ = 0.04 Pa s: slip 4 %, Coulomb 3 %, viscous 2 %, drag 0.6 % of the ideal torque.
AXIAL_PISTON_PUMP_SMALL = PumpParams(kind="axial_piston", displacement_m3_rev=0.4e-6,
                                     slip_coefficient=5.0e-8, coulomb_coefficient=0.03,
                                     viscous_coefficient=1.6e4, drag_torque_nm=0.004,
                                     rotor_inertia_kg_m2=1e-6)
