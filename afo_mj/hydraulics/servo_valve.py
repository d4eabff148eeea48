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

from .orifice import (DEFAULT_DISCHARGE_COEFFICIENT, DEFAULT_TRANSITION_PRESSURE_PA,
                      orifice_flow_m3_s)
from .params import Parameters, effect, param

__all__ = ["ServoValveParams"]


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

    # -- the metering edges sized from the rating (module docstring) --------------------------
    @property
    def effective_overlap_m(self) -> float:
        """The lap the edges have: ``overlap_m``, 0 with ``overlap_enabled`` off."""
        return self.overlap_m if self.overlap_enabled else 0.0

    @property
    def area_gradient_m(self) -> float:
        """Area gradient ``w`` (m²/m, the port width of each edge):
        ``w = Q_r / ((x_max − o) q(Δp_r/2, 1 m²))``, so the rated flow passes at full stroke
        through two lands in series. Example (defaults): 4.06 mm."""
        unit = float(orifice_flow_m3_s(0.5 * self.rated_dp_pa, 1.0, self.discharge_coefficient,
                                       self.rated_density_kg_m3, self.transition_pressure_pa))
        return self.rated_flow_m3_s / ((self.spool_max_m - self.effective_overlap_m) * unit)

    @property
    def leakage_area_m2(self) -> float:
        """Leakage area of each edge, ``A_leak = Q_L / (2 q(Δp_L/2, 1 m²))`` (two edges in
        parallel at spool centre, A and B blocked, each seeing half the supply drop); 0 with
        ``leakage_enabled`` off."""
        if not self.leakage_enabled:
            return 0.0
        unit = float(orifice_flow_m3_s(0.5 * self.leakage_supply_dp_pa, 1.0,
                                       self.discharge_coefficient, self.rated_density_kg_m3,
                                       self.transition_pressure_pa))
        return self.leakage_flow_m3_s / (2.0 * unit)

    def centre_leakage_m3_s(self, supply_dp_pa, density_kg_m3):
        """Leakage from P to T at spool centre with A and B blocked: two edges in parallel,
        each the orifice law (:func:`~afo_mj.hydraulics.laws.orifice_flow_m3_s`) of its
        :attr:`leakage_area_m2` at half the supply drop (arrays broadcast). At the rating's
        drop and density it is ``leakage_flow_m3_s``."""
        return 2.0 * orifice_flow_m3_s(0.5 * np.asarray(supply_dp_pa, dtype=float),
                                       self.leakage_area_m2, self.discharge_coefficient,
                                       density_kg_m3, self.transition_pressure_pa)
