"""4/3 proportional servo valve (ports P, T, A, B): spool dynamics and four metering edges.

Spool (the usual reduced-order servo-valve model, Merritt 1967 §5 and maker's application notes,
e.g. Moog's "Servovalve dynamics" technical note: a second-order lag fitted to the 90° phase
frequency of the datasheet Bode plot):

    ẍ = ω_n² (x_ref − x) − 2 ζ ω_n ẋ,     x_ref = clip(u, −1, 1) · x_max

with ``u`` the normalised command, ``ω_n = 2π f_n``, ``ζ`` the damping ratio. Saturation is on the
target only (no end-stop model): a step to full stroke overshoots by the second-order overshoot
(4.6 % at ζ = 0.7); the metering edges see the spool clipped to ``±x_max``.

Metering edges (critical, overlapped or underlapped centre; Merritt 1967 §3.4–3.6): with ``o``
the overlap (``o > 0`` closed-centre dead band, ``o < 0`` underlap) and ``w`` the area gradient
(port width), for ``x`` clipped to ``±x_max``

    A_PA = A_BT = w max( x − o, 0) + A_leak,    A_AT = A_PB = w max(−x − o, 0) + A_leak

(corners optionally rounded over ``± opening_smoothing_m``; the law
:func:`~afo_mj.hydraulics.laws.spool_edge_area_m2`). Each edge passes the regularised orifice
flow (:func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s`):
``Q_PA = q(p_P − p_A, A_PA)``, ``Q_AT = q(p_A − p_T, A_AT)``, ``Q_PB = q(p_P − p_B, A_PB)``,
``Q_BT = q(p_B − p_T, A_BT)``, and

    Q_A = Q_PA − Q_AT,  Q_B = Q_PB − Q_BT,  Q_P = Q_PA + Q_PB,  Q_T = Q_AT + Q_BT
    (so Q_P − Q_T = Q_A + Q_B).

Rating (maker's convention, e.g. Moog datasheets): the **rated flow** is the no-load flow at full
stroke with the **rated valve pressure drop** ``Δp_r`` = 7 MPa **total** across the valve, i.e.
3.5 MPa per metering land (P→A and B→T in series with A and B joined). So
``rated_dp_pa`` here is the total drop, and

    w = Q_r / ((x_max − o) · q(Δp_r / 2, 1 m², C_d, ρ_r, p_cr))

(the rated flow holds at full stroke whatever the overlap). Internal (centre) leakage is the
maker's figure at spool centre and a supply drop ``Δp_L`` (Moog quotes it at 21 MPa), with A and B
blocked: then ``p_A = p_B = (p_P + p_T)/2`` and two edges in parallel each see ``Δp_L/2``, so
each edge's leakage area is

    A_leak = Q_L / (2 q(Δp_L / 2, 1 m², C_d, ρ_r, p_cr)).

(Real spool leakage is laminar clearance flow; a small orifice is the usual lumped stand-in.)

Power: per edge all of ``Δp_e Q_e ≥ 0`` is heat; ``in = Σ p_up,e |Q_e|``, ``out = Σ p_down,e
|Q_e|`` over the four edges, so ``in = out + heat`` and ``heat = p_P Q_P − p_T Q_T − p_A Q_A −
p_B Q_B``.

Example: the default valve (4 L/min at 7 MPa, x_max = 0.3 mm, zero lap) has
``w ≈ 4.06 mm``; with 21 MPa supply, A and B blocked, it leaks 0.2 L/min at centre.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import laws
from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA,
                      orifice_flow_m3_s)
from .params import Parameters, effect, param
from .power import PowerFlow

__all__ = ["ServoValveParams", "ServoValve"]


@dataclasses.dataclass(frozen=True)
class ServoValveParams(Parameters):
    """A 4/3 servo/proportional valve with a second-order spool.

    Defaults: the order of magnitude of a miniature flow-control servo valve (a few L/min at
    7 MPa, a few hundred Hz bandwidth); not a particular product.
    """

    rated_flow_m3_s: float = param(4.0 / 60e3, unit="m^3/s", lo=0.0, hi=1e-2, lo_open=True,
                                   doc="no-load flow at full stroke and rated_dp_pa")
    rated_dp_pa: float = param(7.0e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                               doc="TOTAL valve pressure drop of the rating (two lands in "
                                   "series; 7 MPa = 3.5 MPa per land, maker's convention)")
    rated_density_kg_m3: float = param(870.0, unit="kg/m^3", lo=500.0, hi=2000.0,
                                       doc="oil density of the rating and leakage figures")
    natural_frequency_hz: float = param(200.0, unit="Hz", lo=0.0, hi=1e4, lo_open=True,
                                        doc="spool natural frequency f_n")
    damping_ratio: float = param(0.7, unit="-", lo=0.0, hi=10.0, lo_open=True,
                                 doc="spool damping ratio ζ")
    spool_max_m: float = param(0.3e-3, unit="m", lo=0.0, hi=0.05, lo_open=True,
                               doc="spool stroke at full command")
    overlap_m: float = param(0.0, unit="m", lo=-0.05, hi=0.05,
                             doc="lap: > 0 overlap (closed-centre dead band), < 0 underlap")
    leakage_flow_m3_s: float = param(0.2 / 60e3, unit="m^3/s", lo=0.0, hi=1e-2,
                                     doc="internal leakage P→T at spool centre, A and B "
                                         "blocked, supply drop leakage_supply_dp_pa")
    leakage_supply_dp_pa: float = param(21.0e6, unit="Pa", lo=0.0, hi=1e8, lo_open=True,
                                        doc="p_P − p_T at which leakage_flow_m3_s is stated")
    discharge_coefficient: float = param(DEFAULT_DISCHARGE_COEFFICIENT, unit="-", lo=0.0,
                                         hi=1.0, lo_open=True, doc="C_d of every edge")
    transition_pressure_pa: float = param(DEFAULT_TRANSITION_PRESSURE_PA, unit="Pa", lo=0.0,
                                          hi=1e6, lo_open=True,
                                          doc="p_cr of the regularised orifice law")
    opening_smoothing_m: float = param(0.0, unit="m", lo=0.0, hi=0.05,
                                       doc="corner rounding of each edge opening (0 = sharp)")
    leakage_enabled: bool = effect(True, doc="centre leakage area on every edge")
    overlap_enabled: bool = effect(True, doc="spool lap overlap_m (False: critical centre)")

    def check(self) -> None:
        if abs(self.overlap_m) >= self.spool_max_m:
            self.fail("overlap_m", f"|overlap_m| must be below spool_max_m = {self.spool_max_m}")
        if self.opening_smoothing_m >= 0.5 * (self.spool_max_m - self.overlap_m):
            self.fail("opening_smoothing_m", "must be below half the opening at full stroke "
                      f"(spool_max_m - overlap_m)/2 = {0.5 * (self.spool_max_m - self.overlap_m)}")
        # Edge leakage area must stay below the full-stroke edge area (our arithmetic from the
        # two sizing formulas of the module docstring, with the transition neglected).
        q_leak_at_rated = self.leakage_flow_m3_s / 2.0 * math.sqrt(
            self.rated_dp_pa / self.leakage_supply_dp_pa)
        if q_leak_at_rated >= self.rated_flow_m3_s:
            self.fail("leakage_flow_m3_s", "the centre leakage would exceed the rated flow: "
                      "leakage per edge must be well below rated_flow_m3_s = "
                      f"{self.rated_flow_m3_s}")


class ServoValve:
    """Spool dynamics, edge areas, port flows and power of one :class:`ServoValveParams` valve."""

    def __init__(self, params: ServoValveParams = ServoValveParams()):
        p = self.params = params
        self.omega_n_rad_s = 2.0 * math.pi * p.natural_frequency_hz
        self.overlap_m = p.overlap_m if p.overlap_enabled else 0.0
        unit_q_rated = float(orifice_flow_m3_s(0.5 * p.rated_dp_pa, 1.0, p.discharge_coefficient,
                                               p.rated_density_kg_m3, p.transition_pressure_pa))
        #: area gradient w (m²/m): port width of each metering edge
        self.area_gradient_m = p.rated_flow_m3_s / ((p.spool_max_m - self.overlap_m) * unit_q_rated)
        unit_q_leak = float(orifice_flow_m3_s(0.5 * p.leakage_supply_dp_pa, 1.0,
                                              p.discharge_coefficient, p.rated_density_kg_m3,
                                              p.transition_pressure_pa))
        #: leakage area of each edge (m²), 0 with leakage disabled
        self.leakage_area_m2 = (p.leakage_flow_m3_s / (2.0 * unit_q_leak)
                                if p.leakage_enabled else 0.0)

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
