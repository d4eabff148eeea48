"""Valve-controlled and digital-valve ankle actuators: one orthosis side, compiled.

Two circuits on the same components as the pump-controlled HAFO
(:mod:`pump_kernel`), both fed by a motor-driven **unidirectional**
pump that draws from a pressurised reservoir (gauge ``p_t``, the "tank"):

**Servo circuit** (``CIRCUIT = 0``; the valve-controlled circuit the seed compares with the
pump-controlled one, ch. 4, and the supply of the PHAFO, ch. 7)::

    pump ─┬─ relief ─→ tank          supply rail p_s (manifold + gas accumulator)
          ├─ unloading valve ─→ tank        │
          └─ check valve ─→ p_s ── 4/3 servo valve ── port A ─ hose ─ chamber A
                                              └── tank    port B ─ hose ─ chamber B

The servo valve meters flow by throttling: ``P→A, B→T`` for a positive spool, ``P→B, A→T``
for a negative one. Supply variants (``SUPPLY``): a fixed-displacement pump at constant speed
with its surplus over the relief valve (``0``, with or without accumulator), the same with a
pilot-operated unloading valve that dumps the pump to tank at low pressure once the
accumulator is charged (``1``), motor speed controlled so that the rail follows the load's
demand or holds a set rail pressure (``2``, proportional pressure / flow-rate control), and a
pressure-compensated variable-displacement pump at constant speed (``3``).

**Digital circuit** (``CIRCUIT = 1``; seed ch. 5): the pump runs at constant speed and a fast
on/off valve, switched by PWM, unloads its flow to tank; while it is shut the flow passes the
check valve into the plantarflexion line (port A); a second on/off valve of the same kind
(the release valve) vents port A to tank when the torque must fall. Port B is open to tank.
A duty cycle ``D`` of the unloading valve shut delivers about ``D`` of the pump flow. The
valves travel at a limited rate (finite switching time), and while they travel they throttle:
that is the switching loss; their coils draw holding power and an energy per switch.

Equations (SI, pressures gauge unless "abs"): as in the HAFO kernel for the driver, motor,
pump (Wilson form, displacement ``ε d`` with ``ε`` the compensator's fraction), hoses,
cylinders, seals, relief valve and oil (entrained-air bulk modulus, seed eq. 2.5); and

* orifices (:func:`afo_mj.hydraulics.orifice.orifice_flow_m3_s`):
  ``Q = C_d A √(2/ρ) Δp/(Δp² + p_cr²)^¼``;
* servo valve (:mod:`afo_mj.hydraulics.servo_valve`), spool ``x ∈ [−1, 1]`` of full stroke,
  first-order at its bandwidth ``τ ẋ = u − x``; edge areas ``A(x) = w x_max ramp(x − lap) +
  A_leak`` (``w`` the area gradient, ``ramp`` C¹-rounded over the first 2 % of the opening);
* gas accumulator (:mod:`afo_mj.hydraulics.accumulator`), polytropic:
  ``V_f = V_0 (1 − (p_0/p)^{1/n})`` so ``dV_f/dp = V_0 p_0^{1/n} / (n p^{1+1/n})`` above the
  precharge ``p_0`` (abs), blended in over a small band; the rail capacitance is the
  manifold's oil plus this;
* unloading valve (:mod:`afo_mj.hydraulics.unloading_valve`): position
  ``τ ẋ = s_up (1 − x) − s_down x`` with the library's drives ``σ_open(p_s)`` (1 above
  cut-out) and ``σ_close(p_s)`` (1 below cut-in) and, in between, snap action:
  ``s_up = σ_o + (1 − σ_o)(1 − σ_c) L(x)``, ``s_down = σ_c + (1 − σ_c)(1 − σ_o)(1 − L(x))``,
  ``L`` a smoothstep from 2 % to 12 % of the travel. The library valve holds whatever
  position it has between the thresholds; in a circuit, where opening drops the pump line
  and the check valve then holds the pilot (the rail) just below cut-out, that leaves it
  cracked open, throttling the whole pump flow at rail pressure. Real unloading valves snap
  (a differential-area pilot: once lifted, the poppet's pressure area grows), which ``L``
  models: a valve that has cracked open completes its travel;
* on/off valves (:mod:`afo_mj.hydraulics.onoff_valve`): ``ẋ = clip((u − x)/τ_s, ±1/T_sw)``
  (clip rounded), ``u`` the PWM signal's on-fraction over the step (so the duty is exact at
  any step length);
* check valve pump → rail: ``Q = G ramp_c1(p_p − p_s − p_crack)``;
* make-up check valves tank → ports (anti-cavitation), as in the HAFO;
* pressure-compensated pump (variable displacement): ``ε = clip((p_c − p_s)/b, ε_min, 1)``
  (quasi-static compensator, corners rounded).

The coupled step (linearly implicit prediction, Newton-corrected backward Euler, adaptive
sub-steps, right-point energy ledger; see the HAFO kernel's docstring) is the same method on
this 10-state system. Losses are named in :data:`LOSS_NAMES`; the tank's store is
``−∫ p_t Q_from_tank dt``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from afo_mj.control.assistance import (
    N_PH as _N_PH, PH_PHASE as _PH_PHASE, phase_update as _phase_update,
    table_lookup as _table_lookup)
from kernel_reference import pump_kernel as _pa
from kernel_reference.pump_kernel import (
    _bulk_modulus, _ramp_c1, _relief_flow, _seal_force, _smoothstep01, _soft_clip,
    chamber_rates,
    battery_ocv, solve_linear, viscosity_pa_s)

# ---- state ---------------------------------------------------------------------------------
Y_I, Y_W, Y_PP, Y_PS, Y_XV, Y_XU, Y_PVA, Y_PVB, Y_PCA, Y_PCB = range(10)
N_Y = 10
STATE_NAMES = ("current_a", "motor_speed_rad_s", "pump_pa", "supply_pa", "valve_position",
               "unloading_valve_position", "port_a_pa", "port_b_pa", "chamber_a_pa",
               "chamber_b_pa")
_Y_TYP = np.array([1.0, 10.0, 1e5, 1e5, 1e-2, 1e-2, 1e5, 1e5, 1e5, 1e5])

# ---- packed parameters: the HAFO kernel's row, then this circuit's -------------------------
_P_EXTRA = (
    "CIRCUIT", "SUPPLY",
    "ACC_ON", "ACC_V0", "ACC_P0", "ACC_N", "ACC_BAND",
    "UL_ON", "UL_CUT_OUT", "UL_CUT_IN", "UL_AMAX", "UL_ALEAK", "UL_TAU", "UL_BAND", "UL_HYST",
    "UL_CD", "UL_PCR",
    "SV_AFULL", "SV_LAP", "SV_ALEAK", "SV_TAU", "SV_CD", "SV_PCR", "SV_COIL_W",
    "SW_AMAX", "SW_ALEAK", "SW_TSW", "SW_TAUS", "SW_ESW", "SW_HOLD", "SW_CD", "SW_PCR",
    "PWM_F", "RV_AMAX",
    "CV_G", "CV_CRACK", "CV_BAND", "V_MAN",
    "W_SET", "K_W_P", "K_W_I", "WINT_LIM",
    "PS_FOLLOW", "PS_SET", "PS_MARGIN", "PS_MIN", "K_PS_P", "K_PS_I", "PSINT_LIM", "W_MAX",
    "VD_P_COMP", "VD_BAND", "VD_EMIN",
    "K_V", "K_VI", "VINT_LIM", "TAU_MAX", "CMD",
)
_P_NAMES = _pa._P_NAMES + _P_EXTRA
for _k, _n in enumerate(_P_NAMES):
    globals()["P_" + _n] = _k
N_P = len(_P_NAMES)

CIRCUIT_SERVO, CIRCUIT_DIGITAL = 0.0, 1.0
SUPPLY_CONSTANT_SPEED, SUPPLY_UNLOADING, SUPPLY_PRESSURE_CONTROL, SUPPLY_VARIABLE = (
    0.0, 1.0, 2.0, 3.0)
CMD_PROFILE, CMD_IMPEDANCE = 0.0, 1.0
MODE_TORQUE = _pa.MODE_TORQUE
#: ``P[MODE]`` for open-loop bench tests: the command is the valve command ``u ∈ [−1, 1]``
#: (servo: spool; digital: ``u > 0`` the fraction of each PWM period the unloading valve is
#: shut, ``u < 0`` the release valve's duty)
MODE_VALVE_COMMAND = 2.0

# ---- per-side work/ledger vector -----------------------------------------------------------
_W_NAMES = (
    "V_CMD", "V_BUS", "MU", "THETA", "THETA_DOT", "TAU_CMD", "UV", "UU", "P_COIL", "DUTY",
    "A0", "A1", "A2", "A3", "A4", "A5", "A6", "A7", "A8", "A9",
    "B0", "B1", "B2", "B3", "B4", "B5", "B6", "B7", "B8", "B9", "TAU0", "G",
    "TAU", "P_MECH", "INT", "WINT", "PSINT", "TAU_MEAS", "SOC", "TEMP_K", "I_BAT",
    "E_CHEM", "E_MECH", "E_BATTERY", "E_DRIVER", "E_COPPER", "E_MOTOR_FRICTION",
    "E_PUMP_VOL", "E_PUMP_MECH", "E_UNLOAD", "E_CHECK", "E_RELIEF", "E_THROTTLE", "E_MAKEUP",
    "E_LINE", "E_SEAL", "E_LEAK", "E_COIL",
    "E_RESERVOIR", "E_STORE_L", "E_STORE_ROT", "E_STORE_OIL",
    "P_MAX", "PS_MAX", "HEAT_TO_OIL", "E_HYD", "I_PEAK", "CLIP_STEPS",
    "TAU_END", "COUPLE_SQ", "NEWTON_ITERS", "NEWTON_FAIL", "E_CHEM_DRAWN", "E_ABS_FLOW",
    "SUBSTEPPED", "SUBSTEPS", "Q_DELIVERED", "Q_PUMP",
)
for _k, _n in enumerate(_W_NAMES):
    globals()["W_" + _n] = _k
N_W = len(_W_NAMES)

#: Loss names of the servo circuit, in chain order (battery → ankle), with their W_ index.
LOSS_NAMES = ("battery_internal", "driver", "motor_copper", "motor_friction", "pump_volumetric",
              "pump_mechanical", "unloading", "check_valve", "relief",
              "servo_valve_throttling", "makeup_valves", "line", "seal_friction", "leakage",
              "valve_actuators")
#: The same ledger rows named for the digital circuit (its unloading valve is the PWM
#: switching valve; the metering is done by the release valve and the open port edges).
LOSS_NAMES_DIGITAL = ("battery_internal", "driver", "motor_copper", "motor_friction",
                      "pump_volumetric", "pump_mechanical", "switching_valve", "check_valve",
                      "relief", "release_valve_and_ports", "makeup_valves", "line",
                      "seal_friction", "leakage", "valve_actuators")
LOSS_INDEX = tuple(globals()["W_" + n] for n in (
    "E_BATTERY", "E_DRIVER", "E_COPPER", "E_MOTOR_FRICTION", "E_PUMP_VOL", "E_PUMP_MECH",
    "E_UNLOAD", "E_CHECK", "E_RELIEF", "E_THROTTLE", "E_MAKEUP", "E_LINE", "E_SEAL", "E_LEAK",
    "E_COIL"))

(F_PBUS, F_DRIVER, F_COPPER, F_MFRIC, F_PVOL, F_PMECH, F_UNLOAD, F_CHECK, F_RELIEF,
 F_THROTTLE, F_MAKEUP, F_LINE, F_SEAL, F_LEAK, F_COIL, F_RES_Q, F_TAU, F_HYD, F_HEAT_OIL,
 F_VOLT, F_QCYL, F_QPUMP) = range(22)
F_CAP0 = 22          # capacitances of the pressure nodes PP, PS, PVA, PVB, PCA, PCB
N_F = 28
_PRESSURE_STATES = (Y_PP, Y_PS, Y_PVA, Y_PVB, Y_PCA, Y_PCB)
#: Rows of the per-side scratch array.
N_SCRATCH = 3 * N_Y + 12


@numba.njit(cache=True)
def _orifice(dp, area, cd, rho, pcr):
    """Regularised turbulent orifice (:func:`afo_mj.hydraulics.orifice.orifice_flow_m3_s`)."""
    return cd * area * math.sqrt(2.0 / rho) * dp / (dp * dp + pcr * pcr) ** 0.25


@numba.njit(cache=True)
def _smooth_ramp(x, b):
    """``max(x, 0)`` rounded over ``0 … b`` (C¹, exact outside): 0 for ``x ≤ 0``,
    ``2x²/b − x³/b²`` on ``[0, b]``, ``x`` beyond (never negative, never above ``x``)."""
    if x <= 0.0:
        return 0.0
    if x >= b:
        return x
    return x * x * (2.0 / b - x / (b * b))


@numba.njit(cache=True)
def accumulator_capacitance(p_gauge, P):
    """``dV_f/dp`` of the gas accumulator (m³/Pa) at gauge ``p``: polytropic above the
    precharge, blended in over ``ACC_BAND`` (smoothstep), zero below (empty)."""
    if P[P_ACC_ON] == 0.0:
        return 0.0
    p = p_gauge + P[P_P_ATM]
    p0 = P[P_ACC_P0]
    s = _smoothstep01((p - p0) / P[P_ACC_BAND] + 0.5)
    if s == 0.0:
        return 0.0
    n = P[P_ACC_N]
    return s * P[P_ACC_V0] * p0 ** (1.0 / n) / (n * p ** (1.0 + 1.0 / n))


@numba.njit(cache=True)
def displacement_fraction(ps, P):
    """Pressure compensator of a variable-displacement pump: ``ε = clip((p_c − p_s)/b,
    ε_min, 1)`` (corners rounded), 1 for a fixed-displacement pump."""
    if P[P_SUPPLY] != SUPPLY_VARIABLE:
        return 1.0
    e = (P[P_VD_P_COMP] - ps) / P[P_VD_BAND]
    return _soft_clip(e, P[P_VD_EMIN], 1.0, 0.02)


@numba.njit(cache=True)
def _onoff_rate(x, u, P):
    """On/off valve travel: ``clip((u − x)/τ_s, ±1/T_sw)`` with rounded corners."""
    lim = 1.0 / P[P_SW_TSW]
    return _soft_clip((u - x) / P[P_SW_TAUS], -lim, lim, 0.05 * lim)


@numba.njit(cache=True)
def _onoff_area(x, P):
    xc = min(max(x, 0.0), 1.0)
    return P[P_SW_ALEAK] + (P[P_SW_AMAX] - P[P_SW_ALEAK]) * xc


@numba.njit(cache=True)
def rhs(y, theta, theta_dot, W, P, dy, F):
    """``dy/dt`` of one side and its power flows ``F`` (module docstring); the held inputs
    (motor voltage, bus voltage, viscosity, valve commands, coil power) are read from ``W``."""
    cur, w = y[Y_I], y[Y_W]
    pp, ps, xv, xu = y[Y_PP], y[Y_PS], y[Y_XV], y[Y_XU]
    pva, pvb, pca, pcb = y[Y_PVA], y[Y_PVB], y[Y_PCA], y[Y_PCB]
    mu = W[W_MU]
    rho = P[P_RHO]
    pt = P[P_P_RES]
    digital = P[P_CIRCUIT] == CIRCUIT_DIGITAL
    # driver + motor
    volt = W[W_V_CMD]
    emf = P[P_K] * w
    if P[P_CUR_LIM_ON] > 0.0:
        band = P[P_R] * P[P_I_LIM]
        volt = _soft_clip(volt, emf - band, emf + band, 0.05)
    vmax = P[P_DUTY] * W[W_V_BUS]
    volt = _soft_clip(volt, -vmax, vmax, 0.05)
    di = (volt - P[P_R] * cur - emf) / P[P_L]
    tf_m = P[P_TC_M] * math.tanh(w / P[P_WC_M]) + P[P_BV_M] * w
    # pump (unidirectional, inlet at the tank)
    eps = displacement_fraction(ps, P)
    d = eps * P[P_D]
    dpp = pp - pt
    q_leak_p = (P[P_CS] * P[P_D] + P[P_PUMP_G_EXTRA]) * dpp / mu
    q_pump = d * w - q_leak_p
    sgn = math.tanh(w / P[P_WC_P])
    abs_dp = math.sqrt(dpp * dpp + 1e8)
    t_pfric = (P[P_CF] * d * abs_dp + P[P_T0]) * sgn + P[P_CV] * P[P_D] * mu * w
    t_pump = d * dpp + t_pfric
    dw = (P[P_K] * cur - tf_m - t_pump) / P[P_J]
    # pump node: relief and unloading (or PWM switching) valve to tank, check valve to the rail
    q_rel = _relief_flow(dpp, P)
    if digital:
        area_u = _onoff_area(xu, P)
        q_ul = _orifice(dpp, area_u, P[P_SW_CD], rho, P[P_SW_PCR])
        dxu = _onoff_rate(xu, W[W_UU], P)
    else:
        if P[P_UL_ON] != 0.0:
            pil = ps + P[P_P_ATM]
            band = P[P_UL_BAND]
            up = _smoothstep01((pil - P[P_UL_CUT_OUT] + band) / band)
            if P[P_UL_HYST] != 0.0:
                down = _smoothstep01((P[P_UL_CUT_IN] + band - pil) / band)
            else:
                down = 1.0 - up
            # snap action: between the thresholds a valve that has cracked open (past 2 to
            # 12 % of its travel) goes on to its end (see the module docstring)
            latch = _smoothstep01((xu - 0.02) / 0.1)
            s_up = up + (1.0 - up) * (1.0 - down) * latch
            s_dn = down + (1.0 - down) * (1.0 - up) * (1.0 - latch)
            dxu = (s_up * (1.0 - xu) - s_dn * xu) / P[P_UL_TAU]
        else:
            dxu = -xu / P[P_UL_TAU]
        xc = min(max(xu, 0.0), 1.0)
        area_u = P[P_UL_ALEAK] + (P[P_UL_AMAX] - P[P_UL_ALEAK]) * xc
        q_ul = _orifice(dpp, area_u, P[P_UL_CD], rho, P[P_UL_PCR])
    dcv = pp - ps
    q_cv = P[P_CV_G] * _ramp_c1(dcv - P[P_CV_CRACK], P[P_CV_BAND])
    # valve: servo 4/3 edges, or the digital circuit's release valve and open port edges
    af = P[P_SV_AFULL]
    cd, pcr = P[P_SV_CD], P[P_SV_PCR]
    if digital:
        dxv = _onoff_rate(xv, W[W_UV], P)
        q_pa = _orifice(ps - pva, af, cd, rho, pcr)
        xr = min(max(xv, 0.0), 1.0)
        a_rel = P[P_SW_ALEAK] + (P[P_RV_AMAX] - P[P_SW_ALEAK]) * xr
        q_at = _orifice(pva - pt, a_rel, P[P_SW_CD], rho, P[P_SW_PCR])
        q_pb = 0.0
        q_bt = _orifice(pvb - pt, af, cd, rho, pcr)
    else:
        dxv = (W[W_UV] - xv) / P[P_SV_TAU]
        lap = P[P_SV_LAP]
        a_pos = af * _smooth_ramp(xv - lap, 0.02) + P[P_SV_ALEAK]
        a_neg = af * _smooth_ramp(-xv - lap, 0.02) + P[P_SV_ALEAK]
        q_pa = _orifice(ps - pva, a_pos, cd, rho, pcr)
        q_at = _orifice(pva - pt, a_neg, cd, rho, pcr)
        q_pb = _orifice(ps - pvb, a_neg, cd, rho, pcr)
        q_bt = _orifice(pvb - pt, a_pos, cd, rho, pcr)
    # make-up check valves: tank into a port below the tank pressure
    eb = P[P_MAKEUP_BAND]
    xa = pt - pva
    xb = pt - pvb
    q_ma = P[P_MAKEUP_G] * _ramp_c1(xa, eb)
    q_mb = P[P_MAKEUP_G] * _ramp_c1(xb, eb)
    # hoses, cylinders
    r_h = P[P_HOSE_K] * mu
    q_ha = (pva - pca) / r_h
    q_hb = (pvb - pcb) / r_h
    r = P[P_R_PULLEY]
    ae = P[P_A_E]
    xdot = r * theta_dot
    va = P[P_V_DEAD] + ae * (0.5 * P[P_STROKE] - r * theta)
    vb = P[P_V_DEAD] + ae * (0.5 * P[P_STROKE] + r * theta)
    if va < P[P_V_DEAD]:
        va = P[P_V_DEAD]
    if vb < P[P_V_DEAD]:
        vb = P[P_V_DEAD]
    q_lk = P[P_G_LEAK] * (pca - pcb) / mu
    # capacitances
    vh2 = 0.5 * P[P_V_HOSE]
    cw = vh2 * P[P_KWALL_INV]
    c_pp = P[P_V_PORT] / _bulk_modulus(pp, P)
    c_ps = P[P_V_MAN] / _bulk_modulus(ps, P) + accumulator_capacitance(ps, P)
    c_va = (P[P_V_PORT] + vh2) / _bulk_modulus(pva, P) + cw
    c_vb = (P[P_V_PORT] + vh2) / _bulk_modulus(pvb, P) + cw
    c_ca = (va + vh2) / _bulk_modulus(pca, P) + cw
    c_cb = (vb + vh2) / _bulk_modulus(pcb, P) + cw
    dpca, dpcb, xdp = chamber_rates(q_ha - q_lk + ae * xdot, q_hb + q_lk - ae * xdot, c_ca,
                                    c_cb, xdot, ae, P)
    f_seal = P[P_N_CYL] * _seal_force(xdp, pca - pcb, P)
    tau = -r * ae * (pca - pcb) - r * f_seal
    dy[Y_I] = di
    dy[Y_W] = dw
    dy[Y_PP] = (q_pump - q_rel - q_ul - q_cv) / c_pp
    dy[Y_PS] = (q_cv - q_pa - q_pb) / c_ps
    dy[Y_XV] = dxv
    dy[Y_XU] = dxu
    dy[Y_PVA] = (q_pa - q_at - q_ha + q_ma) / c_va
    dy[Y_PVB] = (q_pb - q_bt - q_hb + q_mb) / c_vb
    dy[Y_PCA] = dpca
    dy[Y_PCB] = dpcb
    # power flows (W)
    F[F_VOLT] = volt
    F[F_COIL] = W[W_P_COIL]
    F[F_PBUS] = volt * cur + P[P_R_ON] * cur * cur + P[P_P_Q] + W[W_P_COIL]
    F[F_DRIVER] = P[P_R_ON] * cur * cur + P[P_P_Q]
    F[F_COPPER] = P[P_R] * cur * cur
    F[F_MFRIC] = tf_m * w
    F[F_PVOL] = dpp * q_leak_p
    F[F_PMECH] = t_pfric * w
    F[F_UNLOAD] = dpp * q_ul
    F[F_CHECK] = dcv * q_cv
    F[F_RELIEF] = dpp * q_rel
    F[F_THROTTLE] = ((ps - pva) * q_pa + (pva - pt) * q_at + (ps - pvb) * q_pb
                     + (pvb - pt) * q_bt)
    F[F_MAKEUP] = xa * q_ma + xb * q_mb
    F[F_LINE] = (pva - pca) * q_ha + (pvb - pcb) * q_hb
    F[F_SEAL] = r * f_seal * theta_dot if xdp == xdot else f_seal * xdp
    F[F_LEAK] = (pca - pcb) * q_lk
    F[F_RES_Q] = q_pump + q_ma + q_mb - q_rel - q_ul - q_at - q_bt
    F[F_TAU] = tau
    F[F_HYD] = dpp * q_pump
    F[F_QCYL] = -ae * xdot
    F[F_QPUMP] = q_pump
    F[F_CAP0] = c_pp
    F[F_CAP0 + 1] = c_ps
    F[F_CAP0 + 2] = c_va
    F[F_CAP0 + 3] = c_vb
    F[F_CAP0 + 4] = c_ca
    F[F_CAP0 + 5] = c_cb
    F[F_HEAT_OIL] = (F[F_PVOL] + F[F_PMECH] + F[F_UNLOAD] + F[F_CHECK] + F[F_RELIEF]
                     + F[F_THROTTLE] + F[F_MAKEUP] + F[F_LINE] + F[F_SEAL] + F[F_LEAK])


# scratch rows
_S_F0, _S_FF0, _S_YP, _S_FP, _S_FFP, _S_DTAU, _S_YOLD, _S_YSTART, _S_YBEST, _S_STEP = range(
    1, 11)
_S_M = 11                    # N_Y rows: working matrix
_S_MCOPY = _S_M + N_Y        # N_Y rows: the step's own I − hJ
_S_R = _S_MCOPY + N_Y        # N_Y rows: right-hand sides (2 columns)


@numba.njit(cache=True)
def _jacobian(y, theta, theta_dot, h, P, W, S, M):
    """``M = I − h ∂f/∂y`` by forward differences; returns nothing (``f`` in row _S_F0)."""
    f0 = S[_S_F0, :N_Y]
    F0 = S[_S_FF0]
    yp = S[_S_YP, :N_Y]
    fp = S[_S_FP, :N_Y]
    Fp = S[_S_FFP]
    rhs(y, theta, theta_dot, W, P, f0, F0)
    for j in range(N_Y):
        for k in range(N_Y):
            yp[k] = y[k]
        d = 1e-7 * max(abs(y[j]), _Y_TYP[j])
        yp[j] = y[j] + d
        rhs(yp, theta, theta_dot, W, P, fp, Fp)
        for k in range(N_Y):
            M[k, j] = -h * (fp[k] - f0[k]) / d
        M[j, j] += 1.0
        S[_S_DTAU, j] = (Fp[F_TAU] - F0[F_TAU]) / d


@numba.njit(cache=True)
def linearise(y, P, W, S):
    """Fill ``W[A*], W[B*], W[TAU0], W[G]`` for the step ``h = S[0, 0]`` (the prediction
    ``y_{n+1} = y_n + a + b Δθ̇``, ``τ_{n+1} = τ0 + G Δθ̇``)."""
    h = S[0, 0]
    theta, thd = W[W_THETA], W[W_THETA_DOT]
    M = S[_S_M:_S_M + N_Y, :N_Y]
    Mc = S[_S_MCOPY:_S_MCOPY + N_Y, :N_Y]
    R = S[_S_R:_S_R + N_Y, :2]
    _jacobian(y, theta, thd, h, P, W, S, M)
    f0 = S[_S_F0, :N_Y]
    tau0 = S[_S_FF0, F_TAU]
    fp = S[_S_FP, :N_Y]
    Fp = S[_S_FFP]
    dv = 1e-7 * max(abs(thd), 1.0)
    rhs(y, theta, thd + dv, W, P, fp, Fp)
    dtau_dv = (Fp[F_TAU] - tau0) / dv
    for k in range(N_Y):
        R[k, 0] = h * f0[k]
        R[k, 1] = h * (fp[k] - f0[k]) / dv
    for j in range(N_Y):
        for k in range(N_Y):
            Mc[j, k] = M[j, k]
    solve_linear(M, R, N_Y, 2)
    g = dtau_dv
    t0 = tau0
    for k in range(N_Y):
        W[W_A0 + k] = R[k, 0]
        W[W_B0 + k] = R[k, 1]
        t0 += S[_S_DTAU, k] * R[k, 0]
        g += S[_S_DTAU, k] * R[k, 1]
    W[W_TAU0] = t0
    W[W_G] = g


@numba.njit(cache=True)
def pwm_on_fraction(t, h, duty, f):
    """Fraction of ``[t, t + h]`` during which a PWM signal of ``duty`` at ``f`` Hz is on
    (on for the first ``duty`` of each period; :func:`afo_mj.hydraulics.onoff_valve.
    pwm_command`)."""
    if duty <= 0.0:
        return 0.0
    if duty >= 1.0:
        return 1.0
    return (_pwm_on_time(t + h, duty, f) - _pwm_on_time(t, duty, f)) / h


@numba.njit(cache=True)
def _pwm_on_time(t, duty, f):
    """On-time of the PWM signal over ``[0, t]``."""
    k = math.floor(t * f)
    return (k * duty + min(t * f - k, duty)) / f


@numba.njit(cache=True)
def controller(y, P, W, tau_cmd, t, h):
    """Low-level control: torque loop on the valve, motor speed for the supply.

    Torque → chamber pressure difference ``Δp_d = −τ_cmd/(r A_e)`` (transducers on both
    chambers). Valve command ``u = u_ff + k_v e + k_vi ∫e`` (anti-windup clamp), ``e = Δp_d −
    Δp``, with the flow feedforward ``u_ff = Q_ff / (C_d A_full √(2 Δp_edge/ρ))``,
    ``Q_ff = −A_e r θ̇`` the flow that keeps the chamber pressures while the ankle moves and
    ``Δp_edge`` half the rail-to-tank drop (the two lands share it). Servo: ``u`` is the spool
    command. Digital: ``u > 0`` shuts the unloading valve for a fraction ``u`` of each PWM
    period (feedforward ``Q_ff / (d ω_set)``), ``u < 0`` opens the release valve for ``−u``.

    Motor: a PI speed loop with pump-torque feedforward ``v = K ω_s + R d (p_p − p_t)/K +
    k_ω e_ω + k_ωi ∫e_ω``. ``ω_s`` is the set speed, or (supply mode 2) the flow feedforward
    plus a PI law on the rail pressure error, the rail set point following the load
    (``p_t + |Δp_d| + margin``, at least ``PS_MIN``) or fixed (``PS_SET``). Writes the held
    inputs into ``W``."""
    r = P[P_R_PULLEY]
    ae = P[P_A_E]
    pt = P[P_P_RES]
    if P[P_MODE] != MODE_VALVE_COMMAND:
        tau_cmd = min(max(tau_cmd, -P[P_TAU_MAX]), P[P_TAU_MAX])
    dp_meas = y[Y_PCA] - y[Y_PCB]
    W[W_TAU_MEAS] = -r * ae * dp_meas
    W[W_TAU_CMD] = tau_cmd
    dp_des = -tau_cmd / (r * ae)
    err = dp_des - dp_meas
    integ = W[W_INT] + err * h
    lim = P[P_VINT_LIM]
    integ = min(max(integ, -lim), lim)
    W[W_INT] = integ
    q_ff = -ae * r * W[W_THETA_DOT]
    ps = y[Y_PS]
    digital = P[P_CIRCUIT] == CIRCUIT_DIGITAL
    if digital:
        q_p = P[P_D] * P[P_W_SET]
        u_ff = q_ff / q_p if q_ff > 0.0 else q_ff / max(
            P[P_SW_CD] * P[P_RV_AMAX] * math.sqrt(2.0 * max(y[Y_PCA] - pt, 2e5) / P[P_RHO]),
            1e-12)
    else:
        dpe = max(0.5 * (ps - pt), 2e5)
        u_ff = q_ff / (P[P_SV_CD] * P[P_SV_AFULL] * math.sqrt(2.0 * dpe / P[P_RHO]))
    if P[P_MODE] == MODE_VALVE_COMMAND:
        # open loop (bench): the "torque" input is the valve command u itself
        u = tau_cmd
        W[W_TAU_CMD] = 0.0
    else:
        u = u_ff + P[P_K_V] * err + P[P_K_VI] * integ
    u = min(max(u, -1.0), 1.0)
    if digital:
        f = P[P_PWM_F]
        if u >= 0.0:
            # unloading valve: open (on) for 1 − u of each period; release valve shut
            W[W_UU] = pwm_on_fraction(t, h, 1.0 - u, f)
            W[W_UV] = 0.0
            duty_u, duty_v = 1.0 - u, 0.0
        else:
            W[W_UU] = 1.0
            W[W_UV] = pwm_on_fraction(t, h, -u, f)
            duty_u, duty_v = 1.0, -u
        sw = 0.0
        if 0.0 < duty_u < 1.0:
            sw += 2.0 * f
        if 0.0 < duty_v < 1.0:
            sw += 2.0 * f
        # the unloading valve is normally open (powered to shut: a dead device stays
        # unloaded), the release valve normally closed
        W[W_P_COIL] = P[P_SW_HOLD] * (1.0 - W[W_UU] + W[W_UV]) + P[P_SW_ESW] * sw
        W[W_DUTY] = u
    else:
        W[W_UV] = u
        W[W_UU] = 0.0
        W[W_P_COIL] = P[P_SV_COIL_W]
        W[W_DUTY] = u
    # supply: motor speed set point
    w_set = P[P_W_SET]
    if P[P_SUPPLY] == SUPPLY_PRESSURE_CONTROL:
        if P[P_PS_FOLLOW] != 0.0:
            p_d = max(pt + abs(dp_des) + P[P_PS_MARGIN], P[P_PS_MIN])
        else:
            p_d = P[P_PS_SET]
        e_p = p_d - ps
        pint = W[W_PSINT] + e_p * h
        plim = P[P_PSINT_LIM]
        pint = min(max(pint, -plim), plim)
        W[W_PSINT] = pint
        w_set = abs(q_ff) / P[P_D] + P[P_K_PS_P] * e_p + P[P_K_PS_I] * pint
        w_set = min(max(w_set, 0.0), P[P_W_MAX])
    e_w = w_set - y[Y_W]
    wint = W[W_WINT] + e_w * h
    wlim = P[P_WINT_LIM]
    wint = min(max(wint, -wlim), wlim)
    W[W_WINT] = wint
    d = displacement_fraction(ps, P) * P[P_D]
    i_ff = d * (y[Y_PP] - pt) / P[P_K]
    W[W_V_CMD] = (P[P_K] * w_set + P[P_R] * i_ff + P[P_K_W_P] * e_w + P[P_K_W_I] * wint)


@numba.njit(cache=True)
def begin_step(Y, P, W, S, theta, theta_dot, tau_cmd, out, t):
    """First half of the coupled step for every side (see the HAFO kernel's
    :func:`pump_kernel.begin_step`)."""
    for s in range(Y.shape[0]):
        Ws = W[s]
        Ps = P[s]
        h = S[s, 0, 0]
        Ws[W_THETA] = theta[s]
        Ws[W_THETA_DOT] = theta_dot[s]
        Ws[W_MU] = viscosity_pa_s(Ws[W_TEMP_K], Ps)
        v_oc = battery_ocv(Ws[W_SOC], Ps)
        Ws[W_V_BUS] = max(v_oc - Ps[P_BAT_R] * Ws[W_I_BAT], 0.0)
        controller(Y[s], Ps, Ws, tau_cmd[s], t, h)
        linearise(Y[s], Ps, Ws, S[s])
        g = Ws[W_G]
        if g > 0.0:
            Ws[W_G] = 0.0
            out[s, 0] = Ws[W_TAU0]
            out[s, 1] = 0.0
        else:
            out[s, 0] = Ws[W_TAU0] - g * theta_dot[s]
            out[s, 1] = -g


NEWTON_TOL = _pa.NEWTON_TOL
MIN_SUBSTEP_FRACTION = _pa.MIN_SUBSTEP_FRACTION


@numba.njit(cache=True)
def _newton(y, yold, h, theta, theta_dot, P, W, S, first_matrix):
    """Backward-Euler Newton solve (as the HAFO kernel's ``_newton``)."""
    f1 = S[_S_F0, :N_Y]
    F1 = S[_S_FF0]
    Mw = S[_S_M:_S_M + N_Y, :N_Y]
    Mc = S[_S_MCOPY:_S_MCOPY + N_Y, :N_Y]
    rv = S[_S_R:_S_R + N_Y, :1]
    ybest = S[_S_YBEST, :N_Y]
    step = S[_S_STEP, :N_Y]
    err_prev = 1e300
    chord = first_matrix
    for it in range(24):
        rhs(y, theta, theta_dot, W, P, f1, F1)
        err = 0.0
        for k in range(N_Y):
            r_ = y[k] - yold[k] - h * f1[k]
            rv[k, 0] = -r_
            e = abs(r_) / _Y_TYP[k]
            if e > err:
                err = e
        if err < NEWTON_TOL:
            return True
        if err > 1e4 * err_prev or (it >= 8 and err > err_prev):
            # diverging, or cycling after 8 iterations: damped Newton (HAFO kernel)
            for k in range(N_Y):
                step[k] *= 0.5
                y[k] = ybest[k] + step[k]
            continue
        if chord and it > 0 and err > 0.1 * err_prev:
            chord = False
        err_prev = err
        W[W_NEWTON_ITERS] += 1.0
        if chord:
            for j in range(N_Y):
                for k in range(N_Y):
                    Mw[j, k] = Mc[j, k]
        else:
            _jacobian(y, theta, theta_dot, h, P, W, S, Mw)   # rows F0/FF0 = f at y again
        solve_linear(Mw, rv, N_Y, 1)
        for k in range(N_Y):
            ybest[k] = y[k]
            step[k] = rv[k, 0]
            y[k] += rv[k, 0]
        for k in range(N_Y):
            if not math.isfinite(y[k]):
                return False
    return False


@numba.njit(cache=True)
def finish_step(y, P, W, theta_dot_new, S):
    """Second half: Newton-corrected end point, adaptive sub-steps where Newton fails (as the
    HAFO kernel's :func:`pump_kernel.finish_step`); returns the
    torque MuJoCo integrated."""
    h = S[0, 0]
    thd0 = W[W_THETA_DOT]
    dthd = theta_dot_new - thd0
    theta = W[W_THETA]
    yold = S[_S_YOLD, :N_Y]
    ystart = S[_S_YSTART, :N_Y]
    for k in range(N_Y):
        yold[k] = y[k]
        ystart[k] = y[k]
        y[k] += W[W_A0 + k] + W[W_B0 + k] * dthd
    tau = W[W_TAU0] + W[W_G] * dthd
    F1 = S[_S_FF0]
    if _newton(y, yold, h, theta, theta_dot_new, P, W, S, True):
        _close_substep(y, yold, h, theta_dot_new, P, W, S)
    else:
        W[W_SUBSTEPPED] += 1.0
        for k in range(N_Y):
            y[k] = ystart[k]
        pos = 0.0
        frac = 0.25
        while pos < 1.0 - 1e-12:
            if frac > 1.0 - pos:
                frac = 1.0 - pos
            for k in range(N_Y):
                yold[k] = y[k]
            thd = thd0 + (pos + frac) * dthd
            ok = _newton(y, yold, frac * h, theta, thd, P, W, S, False)
            if not ok and frac > MIN_SUBSTEP_FRACTION:
                for k in range(N_Y):
                    y[k] = yold[k]
                frac *= 0.5
                continue
            if not ok:
                W[W_NEWTON_FAIL] += 1.0
                for k in range(N_Y):
                    if not math.isfinite(y[k]):
                        y[k] = yold[k]
                rhs(y, theta, thd, W, P, S[_S_F0, :N_Y], F1)
            W[W_SUBSTEPS] += 1.0
            _close_substep(y, yold, frac * h, thd, P, W, S)
            pos += frac
            if ok:
                frac *= 2.0
    W[W_TAU] = tau
    W[W_TAU_END] = F1[F_TAU]
    W[W_COUPLE_SQ] += (tau - F1[F_TAU]) ** 2
    W[W_P_MECH] = F1[F_TAU] * theta_dot_new
    return tau


@numba.njit(cache=True)
def _close_substep(y, yold, h, theta_dot, P, W, S):
    """Accept the (sub-)step ``yold → y`` (power flows at ``y`` in row _S_FF0): pressure
    floor, battery, right-point ledger, thermal, extrema."""
    F1 = S[_S_FF0]
    floor = P[P_P_FLOOR] - P[P_P_ATM]
    clipped = False
    for k in _PRESSURE_STATES:
        if y[k] < floor:
            y[k] = floor
            clipped = True
    if clipped:
        W[W_CLIP_STEPS] += 1.0
        rhs(y, W[W_THETA], theta_dot, W, P, S[_S_F0, :N_Y], F1)
    p_bus = F1[F_PBUS]
    soc = W[W_SOC]
    v_oc = battery_ocv(soc, P)
    rb = P[P_BAT_R]
    pmax = v_oc * v_oc / (4.0 * rb)
    if p_bus > pmax:
        p_bus = pmax
    disc = v_oc * v_oc - 4.0 * rb * p_bus
    if disc < 0.0:
        disc = 0.0
    i_bat = 2.0 * p_bus / (v_oc + math.sqrt(disc))
    W[W_I_BAT] = i_bat
    W[W_SOC] = soc - h * i_bat / P[P_BAT_CAP_C]
    W[W_E_CHEM] += h * v_oc * i_bat
    if i_bat > 0.0:
        W[W_E_CHEM_DRAWN] += h * v_oc * i_bat
    W[W_E_ABS_FLOW] += h * (abs(v_oc * i_bat) + abs(F1[F_TAU] * theta_dot))
    W[W_E_BATTERY] += h * rb * i_bat * i_bat
    W[W_E_MECH] += h * F1[F_TAU] * theta_dot
    W[W_E_DRIVER] += h * F1[F_DRIVER]
    W[W_E_COPPER] += h * F1[F_COPPER]
    W[W_E_MOTOR_FRICTION] += h * F1[F_MFRIC]
    W[W_E_PUMP_VOL] += h * F1[F_PVOL]
    W[W_E_PUMP_MECH] += h * F1[F_PMECH]
    W[W_E_UNLOAD] += h * F1[F_UNLOAD]
    W[W_E_CHECK] += h * F1[F_CHECK]
    W[W_E_RELIEF] += h * F1[F_RELIEF]
    W[W_E_THROTTLE] += h * F1[F_THROTTLE]
    W[W_E_MAKEUP] += h * F1[F_MAKEUP]
    W[W_E_LINE] += h * F1[F_LINE]
    W[W_E_SEAL] += h * F1[F_SEAL]
    W[W_E_LEAK] += h * F1[F_LEAK]
    W[W_E_COIL] += h * F1[F_COIL]
    W[W_E_HYD] += h * F1[F_HYD]
    W[W_Q_DELIVERED] += h * F1[F_QCYL]
    W[W_Q_PUMP] += h * F1[F_QPUMP]
    W[W_E_RESERVOIR] -= h * P[P_P_RES] * F1[F_RES_Q]
    W[W_E_STORE_L] += P[P_L] * y[Y_I] * (y[Y_I] - yold[Y_I])
    W[W_E_STORE_ROT] += P[P_J] * y[Y_W] * (y[Y_W] - yold[Y_W])
    e_oil = 0.0
    for j in range(6):
        k = _PRESSURE_STATES[j]
        e_oil += F1[F_CAP0 + j] * y[k] * (y[k] - yold[k])
    W[W_E_STORE_OIL] += e_oil
    temp = W[W_TEMP_K]
    W[W_TEMP_K] = temp + h * (F1[F_HEAT_OIL] - (temp - P[P_T_AMB]) / P[P_R_TH]) / P[P_C_TH]
    W[W_HEAT_TO_OIL] += h * F1[F_HEAT_OIL]
    pm = max(y[Y_PP], y[Y_PS], y[Y_PVA], y[Y_PVB], y[Y_PCA], y[Y_PCB])
    if pm > W[W_P_MAX]:
        W[W_P_MAX] = pm
    if y[Y_PS] > W[W_PS_MAX]:
        W[W_PS_MAX] = y[Y_PS]
    if abs(y[Y_I]) > W[W_I_PEAK]:
        W[W_I_PEAK] = abs(y[Y_I])


@numba.njit(cache=True)
def finish_all(Y, P, W, S, theta_dot_new, tau_out):
    ok = True
    for s in range(Y.shape[0]):
        tau_out[s] = finish_step(Y[s], P[s], W[s], theta_dot_new[s], S[s])
        for k in range(N_Y):
            if not math.isfinite(Y[s, k]):
                ok = False
    return ok


# ---- impedance emulation (stiffness emulator): the package's law ----------------------------
from afo_mj.control.impedance import IMP_COLS, impedance_torque  # noqa: E402,F401


# ---- the whole coupled step in two compiled calls (as the HAFO kernel) ----------------------
V_THETA, V_THETA_DOT, V_TAU_CMD, V_THETA_DOT_NEW, V_TAU = range(5)
N_V = 5
O_FORCE, O_DAMPING, O_DELIVERED, O_COMMANDED, O_PHASE = range(5)
N_O = 5
(M_Y, M_P, M_W, M_S, M_PH, M_PROFILE, M_V, M_OUT, M_O, M_LIM, M_END, M_NS,
 M_NPROF) = range(13)
N_META = 13
LOG_FIELDS = ("time_s", "commanded_torque_nm", "delivered_torque_nm", "measured_torque_nm",
              "phase", "motor_command_v", "motor_current_a", "motor_speed_rad_s",
              "pump_pa", "supply_pa", "valve_position", "unloading_valve_position",
              "chamber_a_pa", "chamber_b_pa", "bus_voltage_v", "battery_current_a",
              "mechanical_power_w", "oil_temperature_k", "ankle_velocity_rad_s",
              "valve_command", "ankle_angle_rad")


def device_layout(sides: int, profile_points: int, side_index) -> np.ndarray:
    """``meta`` for a device worn on ``sides`` sides (the HAFO kernel's buffer layout with
    this kernel's sizes)."""
    return _pa.device_layout(sides, profile_points, side_index, N_Y, N_P, N_W, N_SCRATCH,
                             N_F)


@numba.njit(cache=True)
def device_views(buf, meta):
    ns = meta[M_NS]
    Y = buf[meta[M_Y]:meta[M_Y] + ns * N_Y].reshape((ns, N_Y))
    P = buf[meta[M_P]:meta[M_P] + ns * N_P].reshape((ns, N_P))
    W = buf[meta[M_W]:meta[M_W] + ns * N_W].reshape((ns, N_W))
    S = buf[meta[M_S]:meta[M_S] + ns * N_SCRATCH * N_F].reshape((ns, N_SCRATCH, N_F))
    ph = buf[meta[M_PH]:meta[M_PH] + ns * _N_PH].reshape((ns, _N_PH))
    prof = buf[meta[M_PROFILE]:meta[M_PROFILE] + meta[M_NPROF]]
    V = buf[meta[M_V]:meta[M_V] + N_V * ns].reshape((N_V, ns))
    out = buf[meta[M_OUT]:meta[M_OUT] + ns * 2].reshape((ns, 2))
    O = buf[meta[M_O]:meta[M_O] + N_O * 2].reshape((N_O, 2))
    return Y, P, W, S, ph, prof, V, out, O


@numba.njit(cache=True)
def device_begin(t, angle2, velocity2, stance2, buf, meta):
    """Phase estimate, commanded torque (assistance profile or impedance emulation,
    ``P[CMD]``), then :func:`begin_step`, for every worn side."""
    Y, P, W, S, phase_state, profile, V, out, O = device_views(buf, meta)
    lo = buf[meta[M_LIM]]
    hi = buf[meta[M_LIM] + 1]
    ns = meta[M_NS]
    th = V[V_THETA]
    thd = V[V_THETA_DOT]
    cmd = V[V_TAU_CMD]
    for k in range(ns):
        s = meta[N_META + k]
        th[k] = angle2[s]
        thd[k] = velocity2[s]
        ph = _phase_update(phase_state[k], t, stance2[s] != 0, lo, hi)
        if P[k, P_CMD] == CMD_IMPEDANCE:
            cmd[k] = impedance_torque(profile, ph, th[k], thd[k])
        else:
            cmd[k] = _table_lookup(profile, ph)
        O[O_PHASE, s] = ph
    begin_step(Y, P, W, S, th, thd, cmd, out, t)
    for k in range(ns):
        s = meta[N_META + k]
        O[O_FORCE, s] = out[k, 0]
        O[O_DAMPING, s] = out[k, 1]
        O[O_COMMANDED, s] = W[k, W_TAU_CMD]


@numba.njit(cache=True)
def device_end(velocity2, buf, meta, log, k, t):
    """Second half for every worn side and row ``k`` of the device log (fields
    :data:`LOG_FIELDS`). Returns 0 on a non-finite state, 2 when a log row was written, else 1."""
    Y, P, W, S, phase_state, profile, V, out, O = device_views(buf, meta)
    ns = meta[M_NS]
    vnew = V[V_THETA_DOT_NEW]
    tau = V[V_TAU]
    for j in range(ns):
        vnew[j] = velocity2[meta[N_META + j]]
    ok = finish_all(Y, P, W, S, vnew, tau)
    if not ok:
        return 0
    for j in range(ns):
        O[O_DELIVERED, meta[N_META + j]] = tau[j]
    if k >= log.shape[0]:
        return 1
    for j in range(ns):
        Wj = W[j]
        Yj = Y[j]
        log[k, 0, j] = t
        log[k, 1, j] = Wj[W_TAU_CMD]
        log[k, 2, j] = Wj[W_TAU]
        log[k, 3, j] = Wj[W_TAU_MEAS]
        log[k, 4, j] = phase_state[j, _PH_PHASE]
        log[k, 5, j] = Wj[W_V_CMD]
        log[k, 6, j] = Yj[Y_I]
        log[k, 7, j] = Yj[Y_W]
        log[k, 8, j] = Yj[Y_PP]
        log[k, 9, j] = Yj[Y_PS]
        log[k, 10, j] = Yj[Y_XV]
        log[k, 11, j] = Yj[Y_XU]
        log[k, 12, j] = Yj[Y_PCA]
        log[k, 13, j] = Yj[Y_PCB]
        log[k, 14, j] = Wj[W_V_BUS]
        log[k, 15, j] = Wj[W_I_BAT]
        log[k, 16, j] = Wj[W_P_MECH]
        log[k, 17, j] = Wj[W_TEMP_K]
        log[k, 18, j] = vnew[j]
        log[k, 19, j] = Wj[W_DUTY]
        log[k, 20, j] = Wj[W_THETA]
    return 2
