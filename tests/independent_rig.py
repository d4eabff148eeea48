"""An independent lab ankle rig: a second simulator written from textbook equations.

It shares no physics code with afo_mj (no kernels, no ``afo_mj.hydraulics``, no
``afo_mj.circuits``): every equation below is written out here, integrated by scipy's stiff
solver (``solve_ivp(method="Radau")``), and sampled at 1 kHz with the noise of ordinary lab
sensors. Its records (afo_mj measured-data v1, written with
:func:`afo_mj.calibration.measured_data.write_measured`, the only afo_mj import) are the blind
test of ``afo-mj calibrate``: the calibration does not know which effects were switched on.

The rig
-------
A DC motor (terminal voltage ``V``, resistance ``R``, optional inductance ``L``, torque
constant = back-EMF constant ``k`` in SI units, viscous + Coulomb friction, rotor + pump
inertia ``J_m``) drives a fixed-displacement bidirectional pump (displacement ``d`` per rad,
laminar slip leakage) from port B to port A for positive speed. Two hoses (laminar resistance,
optionally line inertance and wall compliance; half of each hose's oil lumped at each end) lead
to the two chambers of a double-acting piston-cable cylinder (bore, cable, stroke, dead
volumes) whose cable wraps a pulley (radius ``r``) on the ankle axis. The foot (inertia
``J_f``) sits on the bench load: a torsion spring ``k_L`` and damper ``c_L``. Charge check
valves feed each pump port from a low-pressure reservoir at the charge pressure ``p_c``. Oil
bulk modulus with entrained air (pressure dependent), piston + cable seal friction.

Conventions (those of afo_mj's HAFO, ``afo_mj/experiments/hafo_bench.py`` and
``docs/circuits.md``): angle, velocity and torque positive in dorsiflexion; positive motor
voltage turns the pump forward, raising port A, which pulls the piston toward chamber B
(``x`` grows, chamber A grows) and gives a *plantarflexion* (negative) torque:
``x = −r θ`` for a rigid cable, ``τ = −r (A (p_a − p_b) − F_seal)``. Pressures are gauge [Pa].
``piston_position_m`` is ``x`` from mid-stroke.

Switchable effects (all off by default; ``effects={"name": value}`` switches one on with that
parameter, ``True`` with the default of :data:`EFFECTS`, ``False``/``None`` leaves it off):
see :data:`EFFECTS`.

Energy bookkeeping: the integrated power terms (electrical input, reservoir input, every loss,
the oil compression power) are extra states, so :func:`energy_balance` closes to the solver
tolerance when the equations are power-consistent.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable, Mapping

import numpy as np
from scipy.integrate import solve_ivp

from afo_mj.calibration.measured_data import write_measured

#: atmospheric pressure [Pa] (absolute pressure = gauge + this)
P_ATM = 101325.0
#: sample rate of the records [Hz]
SAMPLE_RATE_HZ = 1000.0


# ----------------------------------------------------------------------------- parameters


@dataclasses.dataclass(frozen=True)
class RigParams:
    """Nominal parameters of the lab rig (SI units)."""

    # motor (DC, brushed or a current-controlled BLDC seen as one)
    resistance_ohm: float = 0.6
    inductance_h: float = 1.0e-4          # 0 → current algebraic
    motor_k: float = 0.055                # N·m/A = V·s/rad
    motor_inertia_kg_m2: float = 2.0e-5   # rotor + pump
    motor_viscous_nm_s: float = 2.0e-5
    motor_coulomb_nm: float = 5.0e-3
    motor_coulomb_speed_rad_s: float = 1.0
    # pump
    displacement_m3_rad: float = 0.2e-6 / (2 * math.pi)
    pump_leak_m3_s_pa: float = 8.0e-14
    port_volume_m3: float = 2.0e-6
    # hoses
    hose_length_m: float = 1.0
    hose_bore_m: float = 3.0e-3
    oil_density_kg_m3: float = 860.0
    oil_viscosity_pa_s: float = 0.0275
    # oil
    oil_bulk_modulus_pa: float = 1.6e9
    air_fraction: float = 0.005           # entrained air volume / liquid volume at 1 atm
    polytropic_index: float = 1.4
    # cylinder + pulley
    bore_m: float = 14.0e-3
    cable_m: float = 2.0e-3
    stroke_m: float = 0.045
    dead_volume_m3: float = 2.0e-6
    pulley_radius_m: float = 0.04
    piston_mass_kg: float = 0.05
    seal_coulomb_n: float = 15.0
    seal_viscous_n_s_m: float = 200.0
    seal_smoothing_m_s: float = 1.0e-3
    # foot + bench load
    foot_inertia_kg_m2: float = 0.05
    load_stiffness_nm_rad: float = 100.0
    load_damping_nm_s_rad: float = 2.0
    # charge circuit
    charge_pressure_pa: float = 5.0e5
    check_conductance_m3_s_pa: float = 1.0e-9
    check_smoothing_pa: float = 1.0e3
    # sensors
    encoder_bits: int = 12
    encoder_range_rad: float = 2 * math.pi
    pressure_noise_pa: float = 2.0e4
    torque_noise_nm: float = 0.3
    current_noise_a: float = 0.05
    speed_noise_rad_s: float = 0.5
    piston_noise_m: float = 1.0e-5

    @property
    def area_m2(self) -> float:
        """Annular piston area of a piston-cable cylinder, ``A = π/4 (D² − d_c²)``."""
        return math.pi / 4 * (self.bore_m ** 2 - self.cable_m ** 2)

    @property
    def hose_area_m2(self) -> float:
        return math.pi / 4 * self.hose_bore_m ** 2

    @property
    def hose_volume_m3(self) -> float:
        return self.hose_area_m2 * self.hose_length_m

    @property
    def encoder_lsb_rad(self) -> float:
        return self.encoder_range_rad / 2 ** self.encoder_bits


@dataclasses.dataclass(frozen=True)
class Effect:
    """One switchable effect: its parameter's meaning, unit and default value."""

    name: str
    parameter: str
    unit: str
    default: float
    description: str


#: The switchable effects (all off unless named in ``effects``), with the default parameter.
EFFECTS: Mapping[str, Effect] = {e.name: e for e in (
    Effect("stribeck", "static_over_coulomb", "1", 2.0,
           "Stribeck seal friction: breakaway force = this × Coulomb, Stribeck speed 2 mm/s"),
    Effect("pressure_friction", "seal_n_per_pa", "N/Pa", 1.5e-6,
           "seal friction grows with (p_a + p_b)"),
    Effect("piston_leakage", "conductance_m3_s_pa", "m³/(s·Pa)", 5.0e-14,
           "laminar internal leakage across the piston, Q = C (p_a − p_b)"),
    Effect("pump_leakage", "extra_conductance_m3_s_pa", "m³/(s·Pa)", 1.0e-13,
           "extra pump slip (worn pump), added to the nominal slip"),
    Effect("hose_compliance", "wall_modulus_pa", "Pa", 1.5e9,
           "hose wall compliance: volumetric wall modulus K_w, C = V_hose / K_w"),
    Effect("line_inertance", "inertance_scale", "1", 1.0,
           "oil inertance of each hose, I = scale · ρ l / A_hose"),
    Effect("check_cracking", "cracking_pa", "Pa", 0.5e5,
           "check valves crack only at p_c − p > this"),
    Effect("current_limit", "limit_a", "A", 3.0,
           "driver current limit (proportional current-limit loop, 20 V/A)"),
    Effect("cable_compliance", "stiffness_n_m", "N/m", 2.0e6,
           "series cable stiffness between piston (mass 50 g) and pulley, damping ratio 0.1"),
    Effect("sensor_delay", "delay_s", "s", 3.0e-3,
           "transport delay of every measured channel (acquisition latency)"),
    Effect("torque_sensor_resonance", "natural_frequency_hz", "Hz", 80.0,
           "torque sensor + mounting as a 2nd-order resonator, damping ratio 0.05"),
)}

STRIBECK_SPEED_M_S = 2.0e-3
CURRENT_LIMIT_GAIN_V_A = 20.0
CABLE_DAMPING_RATIO = 0.1
TORQUE_SENSOR_DAMPING_RATIO = 0.05


def resolve_effects(effects: Mapping[str, object] | None) -> dict[str, float]:
    """``{name: value}`` of the effects switched on (``True`` → default, ``False``/``None``
    → off). Unknown names raise ``ValueError``."""
    out = {}
    for name, v in (effects or {}).items():
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}")
        if v is None or v is False:
            continue
        out[name] = EFFECTS[name].default if v is True else float(v)
    return out


# ----------------------------------------------------------------------------- equations


def effective_bulk_modulus(p_gauge: float, b_liquid: float, air: float, n: float) -> float:
    """Effective bulk modulus of oil with entrained air [Pa].

    ``B_e = (1 + α (p0/p)^{1/n}) / (1/B_l + α p0^{1/n} / (n p^{(n+1)/n}))`` with ``p``
    absolute, ``α`` the air/liquid volume ratio at ``p0`` = 1 atm, ``n`` the polytropic
    index: the liquid and the gas (``p V_g^n`` = const) compress in series.
    Merritt, *Hydraulic Control Systems* (1967) §2.3 (effective bulk modulus with entrained
    air); Manring, *Hydraulic Control Systems* (2005) §2.2; Gholizadeh, Burton & Schoenau
    (2011) review, eq. (8)."""
    p = max(p_gauge + P_ATM, 1.0e3)
    if air <= 0.0:
        return b_liquid
    g = air * (P_ATM / p) ** (1.0 / n)
    return (1.0 + g) / (1.0 / b_liquid + g / (n * p))


def laminar_hose_resistance(mu: float, length: float, bore: float) -> float:
    """Hagen–Poiseuille resistance of a hose, ``R = 128 μ l / (π D⁴)`` [Pa·s/m³].
    Merritt §4.3; Manring §3.3 (laminar flow in a circular pipe)."""
    return 128.0 * mu * length / (math.pi * bore ** 4)


def line_inertance(rho: float, length: float, area: float) -> float:
    """Fluid inertance of a line, ``I = ρ l / A`` [Pa·s²/m³] (``Δp = I dQ/dt``).
    Merritt §4.6 (lumped transmission line); Manring §3.6."""
    return rho * length / area


def smooth_sign(v: float, eps: float) -> float:
    """``tanh(v/eps)``: a smooth signum for Coulomb friction (Armstrong-Hélouvry 1994)."""
    return math.tanh(v / eps)


def smooth_positive(x: float, eps: float) -> float:
    """``max(x, 0)`` smoothed (C¹) and passive: ``x³/(x² + eps²)`` for ``x > 0``, else 0 (a
    check valve's flow per unit conductance: no back-flow, opening over ``~eps``)."""
    return x * x * x / (x * x + eps * eps) if x > 0.0 else 0.0


def seal_friction(v: float, p_a: float, p_b: float, prm: RigParams,
                  fx: Mapping[str, float]) -> float:
    """Piston + cable seal friction [N], opposing the piston velocity ``v``.

    ``F = (F_c + k_p (p_a + p_b)) tanh(v/ε) + (F_s − F_c) e^{−(v/v_s)²} tanh(v/ε) + b v``:
    Coulomb + viscous (Merritt §5.4), pressure-dependent Coulomb part for lip seals
    (Müller & Nau, *Fluid Sealing Technology*, 1998, ch. 9), Stribeck curve
    (Armstrong-Hélouvry, Dupont & Canudas de Wit, Automatica 30 (1994) eq. 4)."""
    s = smooth_sign(v, prm.seal_smoothing_m_s)
    fc = prm.seal_coulomb_n
    if "pressure_friction" in fx:
        fc += fx["pressure_friction"] * max(p_a + p_b, 0.0)
    f = fc * s + prm.seal_viscous_n_s_m * v
    if "stribeck" in fx:
        f += (fx["stribeck"] - 1.0) * fc * math.exp(-(v / STRIBECK_SPEED_M_S) ** 2) * s
    return f


# ----------------------------------------------------------------------------- the rig


class Rig:
    """The rig's ODE for one parameter set, effect set and input.

    ``locked``: the foot is held at θ = 0 (the ankle locked; with a rigid cable the piston is
    held). ``hoses_closed``: shut-off valves between the pump ports and the hoses.
    """

    def __init__(self, params: RigParams | None = None, effects=None,
                 voltage: Callable[[float], float] | None = None, *, locked: bool = False,
                 hoses_closed: bool = False):
        self.p = params or RigParams()
        self.fx = resolve_effects(effects)
        self.voltage = voltage or (lambda t: 0.0)
        self.locked = locked
        self.hoses_closed = hoses_closed
        #: the voltage held over the segment being integrated (:meth:`simulate` with a hold
        #: period), else ``None`` (the voltage is read from ``voltage(t)``)
        self._held_v: float | None = None
        p, fx = self.p, self.fx
        self.A = p.area_m2
        self.R_h = laminar_hose_resistance(p.oil_viscosity_pa_s, p.hose_length_m, p.hose_bore_m)
        self.I_h = (fx["line_inertance"] * line_inertance(
            p.oil_density_kg_m3, p.hose_length_m, p.hose_area_m2)
            if "line_inertance" in fx else 0.0)
        half = p.hose_volume_m3 / 2
        self.C_wall = half / fx["hose_compliance"] if "hose_compliance" in fx else 0.0
        self.V_port = p.port_volume_m3 + (0.0 if hoses_closed else half)
        self.V_ch0 = p.dead_volume_m3 + half
        self.C_pump = p.pump_leak_m3_s_pa + fx.get("pump_leakage", 0.0)
        self.C_pist = fx.get("piston_leakage", 0.0)
        self.cable = "cable_compliance" in fx
        if self.cable:
            self.k_c = fx["cable_compliance"]
            self.c_c = 2 * CABLE_DAMPING_RATIO * math.sqrt(self.k_c * p.piston_mass_kg)
            self.J_foot = p.foot_inertia_kg_m2
        else:
            self.J_foot = p.foot_inertia_kg_m2 + p.piston_mass_kg * p.pulley_radius_m ** 2
        self.resonance = "torque_sensor_resonance" in fx
        if self.resonance:
            self.w_n = 2 * math.pi * fx["torque_sensor_resonance"]
        # state layout
        names = ["p_pa", "p_pb", "p_a", "p_b", "omega_m", "theta", "omega_f"]
        if p.inductance_h > 0:
            names.append("i")
        if self.I_h > 0 and not hoses_closed:
            names += ["q_a", "q_b"]
        if self.cable:
            names += ["x_p", "v_p"]
        if self.resonance:
            names += ["tau_s", "dtau_s"]
        self.energy_names = ["E_in", "E_res", "L_R", "L_motor", "L_pump", "L_hose", "L_check",
                             "L_seal", "L_piston", "L_damper", "L_cable", "S_oil"]
        names += self.energy_names
        self.names = names
        self.ix = {n: k for k, n in enumerate(names)}

    # ---------------------------------------------------------------- initial state, tolerances
    def initial_state(self, **override) -> np.ndarray:
        y = np.zeros(len(self.names))
        for n in ("p_pa", "p_pb", "p_a", "p_b"):
            y[self.ix[n]] = self.p.charge_pressure_pa
        for k, v in override.items():
            y[self.ix[k]] = v
        return y

    def atol(self) -> np.ndarray:
        scale = {"p_pa": 1e-2, "p_pb": 1e-2, "p_a": 1e-2, "p_b": 1e-2, "omega_m": 1e-6,
                 "theta": 1e-10, "omega_f": 1e-9, "i": 1e-7, "q_a": 1e-14, "q_b": 1e-14,
                 "x_p": 1e-11, "v_p": 1e-10, "tau_s": 1e-7, "dtau_s": 1e-5}
        return np.array([scale.get(n, 1e-10) for n in self.names])

    # ---------------------------------------------------------------- the right-hand side
    def algebraic(self, t: float, y: np.ndarray) -> dict:
        """Everything the derivatives and the sensors need at (t, y)."""
        p, fx, ix = self.p, self.fx, self.ix
        v_cmd = self.voltage(t) if self._held_v is None else self._held_v
        p_pa, p_pb, p_a, p_b = y[ix["p_pa"]], y[ix["p_pb"]], y[ix["p_a"]], y[ix["p_b"]]
        w = y[ix["omega_m"]]
        theta, wf = y[ix["theta"]], y[ix["omega_f"]]
        k, R = p.motor_k, p.resistance_ohm
        lim = fx.get("current_limit")
        g = CURRENT_LIMIT_GAIN_V_A
        # DC motor armature: L di/dt = V − R i − k ω (Krishnan, Electric Motor Drives, §3.2);
        # the current limit is a proportional loop on the excess current, V = V_cmd − g(|i|−i_max)₊
        if p.inductance_h > 0:
            i = y[ix["i"]]
            v = v_cmd
            if lim is not None and abs(i) > lim:
                v = v_cmd - g * (abs(i) - lim) * math.copysign(1.0, i)
        else:
            i = (v_cmd - k * w) / R
            v = v_cmd
            if lim is not None and abs(i) > lim:
                s = math.copysign(1.0, i)
                i = (v_cmd - k * w + g * lim * s) / (R + g)
                v = v_cmd - g * (abs(i) - lim) * s
        # motor friction: viscous + smooth Coulomb (Armstrong-Hélouvry 1994)
        t_fric = p.motor_viscous_nm_s * w + p.motor_coulomb_nm * smooth_sign(
            w, p.motor_coulomb_speed_rad_s)
        # ideal fixed-displacement pump: Q = d ω, T = d Δp (Merritt §7.2; Manring §6.2);
        # laminar slip Q_l = C_s Δp (Wilson's pump model, Manring §6.3)
        dp_port = p_pa - p_pb
        q_pump = p.displacement_m3_rad * w
        q_pl = self.C_pump * dp_port
        t_pump = p.displacement_m3_rad * dp_port
        # hoses: laminar resistance (+ inertance): I dq/dt = Δp − R q (Merritt §4.3, 4.6)
        if self.hoses_closed:
            q_a = q_b = 0.0
        elif self.I_h > 0:
            q_a, q_b = y[ix["q_a"]], y[ix["q_b"]]
        else:
            q_a, q_b = (p_pa - p_a) / self.R_h, (p_pb - p_b) / self.R_h
        # charge check valves from the reservoir: q = G (p_c − p_crack − p)₊ (Manring §4.5)
        crack = fx.get("check_cracking", 0.0)
        pc = p.charge_pressure_pa
        q_ca = p.check_conductance_m3_s_pa * smooth_positive(pc - crack - p_pa,
                                                             p.check_smoothing_pa)
        q_cb = p.check_conductance_m3_s_pa * smooth_positive(pc - crack - p_pb,
                                                             p.check_smoothing_pa)
        # piston kinematics (rigid cable: x = −r θ)
        r = p.pulley_radius_m
        if self.cable:
            x, vp = y[ix["x_p"]], y[ix["v_p"]]
        else:
            x, vp = -r * theta, -r * wf
        f_seal = seal_friction(vp, p_a, p_b, p, fx)
        q_lp = self.C_pist * (p_a - p_b)          # laminar gap leakage (Merritt §3.2)
        f_net = self.A * (p_a - p_b) - f_seal
        if self.cable:
            delta, ddelta = x + r * theta, vp + r * wf
            f_cable = self.k_c * delta + self.c_c * ddelta
            tau = -r * f_cable
        else:
            delta = ddelta = f_cable = 0.0
            tau = -r * f_net
        return dict(v_cmd=v_cmd, v=v, i=i, w=w, t_fric=t_fric, dp_port=dp_port, q_pump=q_pump,
                    q_pl=q_pl, t_pump=t_pump, q_a=q_a, q_b=q_b, q_ca=q_ca, q_cb=q_cb, x=x,
                    vp=vp, f_seal=f_seal, q_lp=q_lp, f_net=f_net, delta=delta, ddelta=ddelta,
                    f_cable=f_cable, tau=tau, theta=theta, wf=wf, p_pa=p_pa, p_pb=p_pb,
                    p_a=p_a, p_b=p_b)

    def node_capacitance(self, p_gauge: float, volume: float, wall: float) -> float:
        """Hydraulic capacitance ``C = V / B_e(p) + C_wall`` [m³/Pa] of a node: the pressure
        build-up equation ``C dp/dt = ΣQ − dV/dt`` (Merritt §3.3 eq. 3-44; Manring §2.3)."""
        p = self.p
        return volume / effective_bulk_modulus(p_gauge, p.oil_bulk_modulus_pa, p.air_fraction,
                                               p.polytropic_index) + wall

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        p, ix, a = self.p, self.ix, self.algebraic(t, y)
        dy = np.zeros_like(y)
        A, s = self.A, p.stroke_m
        # pump ports: C ṗ = ±Q_pump ∓ Q_slip − q_hose + q_check
        c_pa = self.node_capacitance(a["p_pa"], self.V_port, self.C_wall)
        c_pb = self.node_capacitance(a["p_pb"], self.V_port, self.C_wall)
        dp_pa = (a["q_pump"] - a["q_pl"] - a["q_a"] + a["q_ca"]) / c_pa
        dp_pb = (-a["q_pump"] + a["q_pl"] - a["q_b"] + a["q_cb"]) / c_pb
        # chambers: V_a = V_0 + A (s/2 + x), V_b = V_0 + A (s/2 − x)
        c_a = self.node_capacitance(a["p_a"], self.V_ch0 + A * (s / 2 + a["x"]), self.C_wall)
        c_b = self.node_capacitance(a["p_b"], self.V_ch0 + A * (s / 2 - a["x"]), self.C_wall)
        dp_a = (a["q_a"] - a["q_lp"] - A * a["vp"]) / c_a
        dp_b = (a["q_b"] + a["q_lp"] + A * a["vp"]) / c_b
        dy[ix["p_pa"]], dy[ix["p_pb"]], dy[ix["p_a"]], dy[ix["p_b"]] = dp_pa, dp_pb, dp_a, dp_b
        # motor shaft: J ω̇ = k i − T_f − T_pump
        dy[ix["omega_m"]] = (p.motor_k * a["i"] - a["t_fric"] - a["t_pump"]) / \
            p.motor_inertia_kg_m2
        if "i" in ix:
            dy[ix["i"]] = (a["v"] - p.resistance_ohm * a["i"] - p.motor_k * a["w"]) / \
                p.inductance_h
        if "q_a" in ix:
            dy[ix["q_a"]] = (a["p_pa"] - a["p_a"] - self.R_h * a["q_a"]) / self.I_h
            dy[ix["q_b"]] = (a["p_pb"] - a["p_b"] - self.R_h * a["q_b"]) / self.I_h
        if self.cable:     # piston mass on the cable spring: m ẍ = F_net − F_cable
            dy[ix["x_p"]] = a["vp"]
            dy[ix["v_p"]] = (a["f_net"] - a["f_cable"]) / p.piston_mass_kg
        # foot on the bench load: J θ̈ = τ − k_L θ − c_L θ̇
        if not self.locked:
            dy[ix["theta"]] = a["wf"]
            dy[ix["omega_f"]] = (a["tau"] - p.load_stiffness_nm_rad * a["theta"]
                                 - p.load_damping_nm_s_rad * a["wf"]) / self.J_foot
        if self.resonance:   # τ̈_s = ω_n² (τ − τ_s) − 2 ζ ω_n τ̇_s (Doebelin, Measurement
            # Systems, §3.4: second-order instrument)
            wn, z = self.w_n, TORQUE_SENSOR_DAMPING_RATIO
            dy[ix["tau_s"]] = y[ix["dtau_s"]]
            dy[ix["dtau_s"]] = wn * wn * (a["tau"] - y[ix["tau_s"]]) - 2 * z * wn * y[ix["dtau_s"]]
        # energy ledger (power of each term)
        pc = p.charge_pressure_pa
        dy[ix["E_in"]] = a["v"] * a["i"]
        dy[ix["E_res"]] = pc * (a["q_ca"] + a["q_cb"])
        dy[ix["L_R"]] = p.resistance_ohm * a["i"] ** 2
        dy[ix["L_motor"]] = a["t_fric"] * a["w"]
        dy[ix["L_pump"]] = self.C_pump * a["dp_port"] ** 2
        dy[ix["L_hose"]] = self.R_h * (a["q_a"] ** 2 + a["q_b"] ** 2)
        dy[ix["L_check"]] = (pc - a["p_pa"]) * a["q_ca"] + (pc - a["p_pb"]) * a["q_cb"]
        dy[ix["L_seal"]] = a["f_seal"] * a["vp"]
        dy[ix["L_piston"]] = self.C_pist * (a["p_a"] - a["p_b"]) ** 2
        dy[ix["L_damper"]] = p.load_damping_nm_s_rad * a["wf"] ** 2
        dy[ix["L_cable"]] = (self.c_c * a["ddelta"] ** 2) if self.cable else 0.0
        dy[ix["S_oil"]] = (a["p_pa"] * c_pa * dp_pa + a["p_pb"] * c_pb * dp_pb
                           + a["p_a"] * c_a * dp_a + a["p_b"] * c_b * dp_b)
        return dy

    def mechanical_stored(self, y: np.ndarray) -> float:
        """Kinetic + elastic + magnetic + line-inertance energy [J] of state ``y``."""
        p, ix = self.p, self.ix
        e = 0.5 * p.motor_inertia_kg_m2 * y[ix["omega_m"]] ** 2
        e += 0.5 * self.J_foot * y[ix["omega_f"]] ** 2
        e += 0.5 * p.load_stiffness_nm_rad * y[ix["theta"]] ** 2
        if "i" in ix:
            e += 0.5 * p.inductance_h * y[ix["i"]] ** 2
        if "q_a" in ix:
            e += 0.5 * self.I_h * (y[ix["q_a"]] ** 2 + y[ix["q_b"]] ** 2)
        if self.cable:
            e += 0.5 * p.piston_mass_kg * y[ix["v_p"]] ** 2
            delta = y[ix["x_p"]] + p.pulley_radius_m * y[ix["theta"]]
            e += 0.5 * self.k_c * delta ** 2
        return e

    def simulate(self, duration_s: float, *, rtol: float = 1e-7, y0=None,
                 sample_rate_hz: float = SAMPLE_RATE_HZ, method: str = "Radau",
                 hold_period_s: float | None = None):
        """Integrate over ``[0, duration_s]``; return ``(t, Y)`` sampled at ``sample_rate_hz``
        (``Y`` shape (n_states, n_samples)).

        ``hold_period_s``: the voltage is a digital command held between updates at
        ``k · hold_period_s``: each hold interval is integrated on its own with the voltage
        frozen at ``voltage(k · hold_period_s)`` and the state carried over (the right-hand side
        is smooth within an interval; a jump inside a solver step would cost it its order)."""
        y0 = self.initial_state() if y0 is None else np.asarray(y0, dtype=float)
        n = int(round(duration_s * sample_rate_hz)) + 1
        t = np.arange(n) / sample_rate_hz
        if hold_period_s is not None:
            return t, self._simulate_held(t, y0, rtol, hold_period_s, method)
        with np.errstate(over="ignore"):    # scipy's numerical-Jacobian step factors
            sol = solve_ivp(self.rhs, (0.0, t[-1]), y0, method=method, t_eval=t, rtol=rtol,
                            atol=self.atol(), max_step=5e-3)
        if not sol.success:
            raise RuntimeError(f"independent rig: solver failed: {sol.message}")
        return sol.t, sol.y

    def _simulate_held(self, t: np.ndarray, y0: np.ndarray, rtol: float, period: float,
                       method: str) -> np.ndarray:
        """:meth:`simulate` for a command held over ``period``: one solve per hold interval."""
        Y = np.empty((len(y0), len(t)))
        Y[:, 0] = y0
        y = y0
        n_seg = int(math.ceil(t[-1] / period - 1e-9))
        atol = self.atol()
        try:
            for k in range(n_seg):
                a, b = k * period, min((k + 1) * period, t[-1])
                self._held_v = float(self.voltage(a))
                inside = np.flatnonzero((t > a + 1e-12) & (t <= b + 1e-12))
                with np.errstate(over="ignore"):
                    sol = solve_ivp(self.rhs, (a, b), y, method=method, rtol=rtol, atol=atol,
                                    max_step=5e-3, dense_output=inside.size > 0)
                if not sol.success:
                    raise RuntimeError(f"independent rig: solver failed: {sol.message}")
                y = sol.y[:, -1]
                if inside.size:
                    Y[:, inside] = sol.sol(np.minimum(t[inside], b))
        finally:
            self._held_v = None
        return Y


def energy_balance(rig: Rig, Y: np.ndarray) -> dict[str, float]:
    """Energy terms [J] from the start to the end of ``Y``: ``inputs`` (electrical + charge
    reservoir), ``losses`` (resistive, motor friction, pump slip, hose throttling, check-valve
    throttling, seal friction, piston leakage, load damper, cable damping), ``stored`` (oil
    compression + kinetic + elastic + magnetic + inertance) and ``residual``."""
    ix = rig.ix
    d = {n: float(Y[ix[n], -1] - Y[ix[n], 0]) for n in rig.energy_names}
    inputs = d["E_in"] + d["E_res"]
    losses = sum(v for n, v in d.items() if n.startswith("L_"))
    stored = d["S_oil"] + rig.mechanical_stored(Y[:, -1]) - rig.mechanical_stored(Y[:, 0])
    return dict(d, inputs=inputs, losses=losses, stored=stored,
                residual=inputs - losses - stored)


# ----------------------------------------------------------------------------- inputs


def default_voltage_profile(duration_s: float = 20.0, amplitude_v: float = 4.0,
                            ramp_s: float = 2.0e-3) -> Callable[[float], float]:
    """Voltage steps (±amplitude, then half amplitude, 0.5 s each, 2 ms ramps) over the first
    40 % of the record, then a linear chirp 0.5 → 15 Hz of 0.75 × amplitude."""
    t_steps = 0.4 * duration_s
    levels = [0.0, 1.0, -1.0, 0.5, -0.5, 0.0]
    dwell = 0.5
    f0, f1 = 0.5, 15.0
    t_chirp = max(duration_s - t_steps, 1e-9)

    def level(t):
        k = int(t // dwell)
        return amplitude_v * levels[(k + 1) % len(levels)] if k >= 0 else 0.0

    def u(t: float) -> float:
        if t < 0.1:
            return 0.0
        if t < t_steps:
            tt = t - 0.1
            k = int(tt // dwell)
            frac = tt - k * dwell
            new = level(tt)
            old = level(tt - dwell) if k > 0 else 0.0
            if frac < ramp_s:
                return old + (new - old) * frac / ramp_s
            return new
        tc = t - t_steps
        phase = 2 * math.pi * (f0 * tc + 0.5 * (f1 - f0) / t_chirp * tc * tc)
        env = min(tc / 0.05, 1.0)
        return 0.75 * amplitude_v * env * math.sin(phase)

    return u


def stepped_voltage_profile(duration_s: float = 20.0, amplitude_v: float = 4.0,
                            update_s: float = 2.0e-3) -> Callable[[float], float]:
    """A digital voltage command: :func:`default_voltage_profile` without its ramps, as a
    controller computes it at each update ``k · update_s`` and a DAC (or a PWM driver's duty
    register) holds it until the next one (zero-order hold, Franklin, Powell & Workman,
    *Digital Control of Dynamic Systems*, 3rd ed., §4.3.2: ``u(t) = u(kT)`` for
    ``kT ≤ t < (k+1)T``). Steps are sharp."""
    if not update_s > 0.0:
        raise ValueError(f"update_s = {update_s!r}; allowed: > 0")
    base = default_voltage_profile(duration_s, amplitude_v, ramp_s=0.0)

    def u(t: float) -> float:
        return base(math.floor(t / update_s + 1e-9) * update_s)

    return u


# ----------------------------------------------------------------------------- sensors


CHANNEL_UNITS = {"motor_voltage_v": "V", "ankle_angle_rad": "rad", "ankle_torque_nm": "N·m",
                 "pressure_a_pa": "Pa", "pressure_b_pa": "Pa", "motor_current_a": "A",
                 "motor_speed_rad_s": "rad/s", "piston_position_m": "m"}


def true_channels(rig: Rig, t: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
    """The rig's true (noise-free, undelayed) channel values at the samples."""
    cols = {k: np.empty(len(t)) for k in CHANNEL_UNITS}
    for j, tj in enumerate(t):
        a = rig.algebraic(float(tj), Y[:, j])
        cols["motor_voltage_v"][j] = a["v_cmd"]
        cols["ankle_angle_rad"][j] = a["theta"]
        cols["ankle_torque_nm"][j] = Y[rig.ix["tau_s"], j] if rig.resonance else a["tau"]
        cols["pressure_a_pa"][j] = a["p_pa"]
        cols["pressure_b_pa"][j] = a["p_pb"]
        cols["motor_current_a"][j] = a["i"]
        cols["motor_speed_rad_s"][j] = a["w"]
        cols["piston_position_m"][j] = a["x"]
    return cols


def noise_sigmas(params: RigParams) -> dict[str, float]:
    """Sensor noise σ per channel (the encoder's quantisation as LSB/√12)."""
    return {"ankle_angle_rad": params.encoder_lsb_rad / math.sqrt(12.0),
            "ankle_torque_nm": params.torque_noise_nm,
            "pressure_a_pa": params.pressure_noise_pa,
            "pressure_b_pa": params.pressure_noise_pa,
            "motor_current_a": params.current_noise_a,
            "motor_speed_rad_s": params.speed_noise_rad_s,
            "piston_position_m": params.piston_noise_m}


def measure(rig: Rig, t: np.ndarray, Y: np.ndarray, seed: int) -> dict[str, np.ndarray]:
    """Sensor models: acquisition delay (effect), 12-bit absolute encoder quantisation of the
    angle (round to the LSB, IEEE 1241 quantisation), Gaussian noise on the pressure
    transducers, torque cell, current and speed sensors and the piston position (seeded RNG).
    The input voltage is recorded as commanded (no noise)."""
    true = true_channels(rig, t, Y)
    delay = rig.fx.get("sensor_delay", 0.0)
    out = {"time_s": t.copy(), "motor_voltage_v": true["motor_voltage_v"]}
    rng = np.random.default_rng(seed)
    sig = noise_sigmas(rig.p)
    for name in CHANNEL_UNITS:
        if name == "motor_voltage_v":
            continue
        x = true[name]
        if delay > 0:
            x = np.interp(t - delay, t, x, left=x[0])
        if name == "ankle_angle_rad":
            lsb = rig.p.encoder_lsb_rad
            x = np.round(x / lsb) * lsb
        else:
            x = x + rng.normal(0.0, sig[name], size=len(t))
        out[name] = x
    return out


# ----------------------------------------------------------------------------- records


def simulate_record(duration_s: float, effects=None, seed: int = 0, *,
                    params: RigParams | None = None, voltage=None, rtol: float = 1e-7,
                    amplitude_v: float = 4.0, command_update_s: float | None = None):
    """Simulate and measure; return ``(rig, channels)``. ``command_update_s``: a stepped
    digital command (:func:`stepped_voltage_profile`) updated at this period instead of the
    continuous default profile (ignored when ``voltage`` is given)."""
    period = None
    if voltage is None and command_update_s is not None:
        voltage = stepped_voltage_profile(duration_s, amplitude_v, command_update_s)
        period = command_update_s
    voltage = voltage or default_voltage_profile(duration_s, amplitude_v)
    rig = Rig(params, effects, voltage)
    t, Y = rig.simulate(duration_s, rtol=rtol, hold_period_s=period)
    return rig, measure(rig, t, Y, seed)


def write_record(path, duration_s: float = 20.0, effects=None, seed: int = 0, *,
                 params: RigParams | None = None, voltage=None, rtol: float = 1e-7,
                 amplitude_v: float = 4.0, command_update_s: float | None = None,
                 hold: str | None = None):
    """Simulate the rig and write the record (afo_mj measured-data v1: CSV + TOML sidecar).
    Returns the validated :class:`~afo_mj.calibration.measured_data.MeasuredData`.

    The sidecar's ``[hold]`` declares how the voltage was produced between samples: ``hold``
    if given (a caller's own ``voltage``), else ``"zero_order"`` for the stepped command
    (``command_update_s``) and ``"linear"`` for the continuous default profile."""
    rig, ch = simulate_record(duration_s, effects, seed, params=params, voltage=voltage,
                              rtol=rtol, amplitude_v=amplitude_v,
                              command_update_s=command_update_s)
    if hold is None:
        hold = "zero_order" if (voltage is None and command_update_s is not None) else "linear"
    on = ", ".join(f"{k}={v:g}" for k, v in rig.fx.items()) or "none"
    cmd = ("continuous voltage profile" if hold == "linear" and command_update_s is None
           else f"voltage held {hold}" + (f", updated every {command_update_s * 1e3:g} ms"
                                          if command_update_s else ""))
    source = {"preset": "hafo",
              "description": (f"independent lab ankle rig (tests/independent_rig.py, textbook "
                              f"equations, scipy Radau rtol={rtol:g}), not afo_mj's model; "
                              f"{duration_s:g} s, seed {seed}; {cmd}; effects on: {on}"),
              "origin": "afo_mj tests/independent_rig.py"}
    outputs = [k for k in CHANNEL_UNITS if k != "motor_voltage_v"]
    return write_measured(Path(path), ch, inputs=["motor_voltage_v"], outputs=outputs,
                          source=source, noise=noise_sigmas(rig.p),
                          hold={"motor_voltage_v": hold})
