"""Pump-controlled ankle actuator: the hydraulic chain of one orthosis side, compiled.

battery → PWM driver → brushless motor → bidirectional pump → two hoses → a pair of
antagonistic piston-cable cylinders pulling a cable loop on the ankle pulley (the seed's HAFO,
ch. 6, and the pump-controlled circuit of ch. 4). There is no throttling valve: the motor's
speed sets the flow. Cross-port relief valves protect the pump ports; a flushing (shuttle)
valve ties whichever line is at the lower pressure to a low-pressure spring reservoir, so the
closed circuit is replenished and its low side never cavitates (the usual charge arrangement
of a closed hydrostatic loop).

Equations (all SI, pressures gauge; each from the component module named, written here once
more in compiled form so the per-step cost stays at a few µs; ``tests/test_pump_ankle.py``
checks them against those modules):

* driver + motor (:mod:`afo_mj.hydraulics.motor`): ``L di/dt = v − R i − K ω``; the driver
  clamps ``v`` to ``K ω ± R I_max`` (current limit) and ``± duty_max · V_bus``;
  ``J dω/dt = K i − T_f,motor(ω) − T_pump``.
* pump (:mod:`afo_mj.hydraulics.pump`, Wilson / McCandlish–Dorey):
  ``Q = d ω − C_s D Δp/(2π μ)``, ``T = d Δp + (C_f D|Δp|/2π + T_0) tanh(ω/ω_c) + C_v D μ ω/2π``.
* hoses (:mod:`afo_mj.hydraulics.conduit`): laminar ``Δp = 128 μ L Q/(π D⁴)`` (Reynolds number
  checked by the preset: below 2000 at the rated flow), half the hose volume and wall
  compliance lumped at each end.
* relief (:mod:`afo_mj.hydraulics.relief_valve`): opening a smoothstep ramp from cracking to
  cracking + override, orifice ``Q = C_d A √(2/ρ) Δp/(Δp² + p_cr²)^¼``; one valve each way
  between the pump ports.
* charge valves (loss ``charge_valves``): a flushing valve of conductance ``G_f`` between the
  reservoir (gauge ``p_r``) and the lower line, switched by a ``tanh`` of the line pressure
  difference over ``band``, and a make-up check valve into each line,
  ``Q = G_m · ramp(x)``, ``x = p_r − p``, ramp C¹ over ``b`` (:func:`_ramp_c1`) (opens as the line
  falls below the reservoir: the ankle can outrun the pump without cavitating the suction line).
* cylinders (:mod:`afo_mj.hydraulics.cylinder`, :mod:`afo_mj.hydraulics.seal`): effective area
  ``A_e = n A`` (n cylinders, annular area ``A = π/4 (D² − d_c²)``); line a drives
  plantarflexion. Piston speed ``ẋ = r θ̇``; chamber a volume
  ``V_a = V_dead + A_e (s/2 − r θ)``, clamped at ``V_dead``; internal leakage ``G_l Δp/μ``;
  seal friction per cylinder (piston seal + two cable seals) with the Stribeck form.
* ankle torque (+dorsiflexion): ``τ = −r A_e (p_ca − p_cb) − r n F_seal(r θ̇)``.
* node continuity (Merritt §2.5): ``C(p) dp/dt = Σ Q``, ``C = V/B(p) + V_h/(2 K_wall)`` with the
  entrained-air bulk modulus of seed eq. 2.5 (:func:`afo_mj.hydraulics.fluid.
  effective_bulk_modulus_pa`).

Numerics and coupling to MuJoCo (``afo_mj.gait.walk`` and ``afo_mj.human.test_stand``)
----------------------------------------------------------------------------------------
The state ``y = (i, ω, p_pa, p_pb, p_ca, p_cb)`` is advanced by one linearly implicit
(Rosenbrock–) Euler step per MuJoCo step, with the ankle velocity at the *end* of the step as an
input: ``(I − h J_y) Δy = h f(y_n, θ̇_n) + h J_θ̇ (θ̇_{n+1} − θ̇_n)``. So ``Δy = a + b (θ̇_{n+1} − θ̇_n)``
and the end-of-step torque is affine in the unknown ankle velocity,
``τ_{n+1} = τ_0 + G (θ̇_{n+1} − θ̇_n)`` with ``G = ∂τ/∂y · b + ∂τ/∂θ̇ ≤ 0``.
MuJoCo's Euler and implicitfast integrators treat joint damping implicitly
(``(M + h D) q̈ = f − D q̇_n``, i.e. the damping force is ``−D q̇_{n+1}``), so applying
``τ_0 − G θ̇_n`` as a joint force and ``D = −G`` as extra joint damping makes MuJoCo integrate
exactly the end-of-step torque together with the body: the torque never lags a step and the
hydraulic spring (kHz with stiff oil and small volumes) is integrated L-stably with the foot.
After ``mj_step`` the new ankle velocity closes the step (``y_{n+1} = y_n + a + b Δθ̇``).

The Jacobians are forward differences of the compiled right-hand side (7 extra evaluations,
≈ 1 µs); the 6×6 system is solved by Gaussian elimination with partial pivoting.

Energy ledger (per side, J): the battery's chemical energy ``∫V_oc I`` is the input; every
loss is accumulated by the right-point rule over the step (consistent with backward Euler);
the stores (inductance, rotor, oil) accumulate the discrete work done on them,
``Σ y_{n+1}·M·Δy``. The residual ``in − out − losses − Δstored`` then measures only how far the
linearised step departs from the end-point equations.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# ---- state -----------------------------------------------------------------------------------
Y_I, Y_W, Y_PPA, Y_PPB, Y_PCA, Y_PCB = range(6)
N_Y = 6
STATE_NAMES = ("current_a", "motor_speed_rad_s", "pump_a_pa", "pump_b_pa", "chamber_a_pa",
               "chamber_b_pa")

# ---- packed parameters (one row per side) ------------------------------------------------------
_P_NAMES = (
    "R", "L", "K", "J", "TC_M", "BV_M", "WC_M", "I_LIM", "DUTY", "R_ON", "P_Q", "CUR_LIM_ON",
    "D", "CS", "CF", "CV", "T0", "WC_P",
    "HOSE_K",        # 128 L/(π D⁴): laminar resistance per unit viscosity
    "V_HOSE", "KWALL_INV",
    "A_E", "N_CYL", "R_PULLEY", "V_DEAD", "STROKE", "G_LEAK",
    "SEAL_FC", "SEAL_STRIB", "SEAL_VST", "SEAL_VC", "SEAL_FV",
    "REL_CRACK", "REL_OVER", "REL_AMAX", "REL_ALEAK", "REL_CD", "REL_PCR",
    "FLUSH_G", "P_RES", "FLUSH_BAND", "MAKEUP_G", "MAKEUP_BAND",
    "B_L", "AIR", "N_POLY", "P_ATM", "P_FLOOR", "RHO", "CAV_BAND",
    "V_PORT",
    # battery
    "BAT_R", "BAT_NS", "BAT_CAP_C",
    # thermal
    "C_TH", "R_TH", "T_AMB", "WALTHER_B", "WALTHER_C", "RHO_T_COEF", "T_REF",
    # controller
    "K_PRESSURE", "K_SPEED", "K_INT", "INT_LIM", "MODE",
    # calibration effects (afo_mj.calibration.effect_library), zero = off:
    "SEAL_CP",       # pressure-dependent seal friction, N per Pa of |Δp| per cylinder (m²)
    "SERIES_COMP",   # cable/series compliance as a differential capacitance r²A_e²/k (m³/Pa)
    "PUMP_G_EXTRA",  # extra laminar leakage across the pump ports, Q = G Δp/μ (m³)
)
for _k, _n in enumerate(_P_NAMES):
    globals()["P_" + _n] = _k
N_P = len(_P_NAMES)

# ---- per-side work/ledger vector ---------------------------------------------------------------
_W_NAMES = (
    # inputs held over the step
    "V_CMD", "V_BUS", "MU", "THETA", "THETA_DOT", "TAU_CMD",
    # linearised step: y_{n+1} = y_n + a + b (θ̇_{n+1} − θ̇_n); τ_{n+1} = τ0 + G (…)
    "A0", "A1", "A2", "A3", "A4", "A5", "B0", "B1", "B2", "B3", "B4", "B5", "TAU0", "G",
    # delivered torque and power of the last step
    "TAU", "P_MECH",
    # controller and sensors
    "INT", "TAU_MEAS",
    # battery and thermal states
    "SOC", "TEMP_K", "I_BAT",
    # ledger (J): input, outputs, losses, stores
    "E_CHEM", "E_MECH", "E_BATTERY", "E_DRIVER", "E_COPPER", "E_MOTOR_FRICTION",
    "E_PUMP_VOL", "E_PUMP_MECH", "E_LINE", "E_FLUSH", "E_RELIEF", "E_SEAL", "E_LEAK",
    "E_RESERVOIR", "E_STORE_L", "E_STORE_ROT", "E_STORE_OIL",
    # extrema and diagnostics
    "P_MAX", "HEAT_TO_OIL", "E_HYD", "I_PEAK", "CLIP_STEPS",
    # coupling: end-point torque after the Newton correction, Σ(τ_applied − τ_end)², Newton
    "TAU_END", "COUPLE_SQ", "NEWTON_ITERS", "NEWTON_FAIL", "E_CHEM_DRAWN", "E_ABS_FLOW",
    "SUBSTEPPED", "SUBSTEPS",
)
for _k, _n in enumerate(_W_NAMES):
    globals()["W_" + _n] = _k
N_W = len(_W_NAMES)

#: Loss names in the ledger, in the order of the chain (battery → ankle), with their W_ index.
LOSS_NAMES = ("battery_internal", "driver", "motor_copper", "motor_friction", "pump_volumetric",
              "pump_mechanical", "line", "charge_valves", "relief", "seal_friction", "leakage")
LOSS_INDEX = tuple(globals()["W_" + n] for n in (
    "E_BATTERY", "E_DRIVER", "E_COPPER", "E_MOTOR_FRICTION", "E_PUMP_VOL", "E_PUMP_MECH",
    "E_LINE", "E_FLUSH", "E_RELIEF", "E_SEAL", "E_LEAK"))

# Flow/power outputs of the right-hand side (scratch vector)
(F_PBUS, F_DRIVER, F_COPPER, F_MFRIC, F_PVOL, F_PMECH, F_LINE, F_FLUSH, F_RELIEF, F_SEAL, F_LEAK,
 F_RES_Q, F_TAU, F_HYD, F_CAP_PA, F_CAP_PB, F_CAP_CA, F_CAP_CB, F_HEAT_OIL, F_VOLT) = range(20)
N_F = 20

MODE_TORQUE, MODE_VOLTAGE = 0.0, 1.0
#: Rows of the per-side scratch array (see :func:`linearise`, :func:`finish_step`).
N_SCRATCH = 31


@numba.njit(cache=True)
def _smoothstep01(s):
    if s <= 0.0:
        return 0.0
    if s >= 1.0:
        return 1.0
    return s * s * (3.0 - 2.0 * s)


@numba.njit(cache=True, fastmath=False)
def _bulk_modulus(p_gauge, P):
    """Seed eq. 2.5 (entrained air) at absolute pressure. (The charge pressure keeps every
    node well above the vapour floor; a node that reaches it anyway is clamped there after
    the step and counted, instead of the library's cavitation softening, whose thousandfold
    capacitance change would stall the step's Newton correction.)"""
    p = p_gauge + P[P_P_ATM]
    cav = 1.0
    if p < P[P_P_FLOOR]:
        p = P[P_P_FLOOR]
    a = P[P_AIR]
    if a == 0.0:
        return P[P_B_L] * cav
    n = P[P_N_POLY]
    ratio = (P[P_P_ATM] / p) ** (1.0 / n)
    return cav * P[P_B_L] * (1.0 + a * ratio) / (1.0 + a * ratio * P[P_B_L] / (n * p))


@numba.njit(cache=True)
def _ramp_c1(x, b):
    """``max(x, 0)`` with a quadratic start over ``0 … b``: 0 for ``x ≤ 0``, ``x²/(2b)`` up to
    ``b``, ``x − b/2`` beyond (C¹; a check valve cracking at zero pressure difference)."""
    if x <= 0.0:
        return 0.0
    if x < b:
        return 0.5 * x * x / b
    return x - 0.5 * b


@numba.njit(cache=True)
def _soft_clip(x, lo, hi, r):
    """``min(max(x, lo), hi)`` with hyperbolic corners of radius ``r`` (same units as ``x``):
    exact away from the corners, C¹ at them (so Newton does not cycle on the driver's voltage
    clamps)."""
    a = x - lo
    x = lo + 0.5 * (a + math.sqrt(a * a + r * r)) - 0.5 * r
    b = hi - x
    return hi - 0.5 * (b + math.sqrt(b * b + r * r)) + 0.5 * r


@numba.njit(cache=True)
def _relief_flow(dp, P):
    """Relief valve from the higher to the lower port for ``dp > 0`` (seated otherwise)."""
    if dp <= 0.0:
        return 0.0
    s = _smoothstep01((dp - P[P_REL_CRACK]) / P[P_REL_OVER])
    area = P[P_REL_ALEAK] + (P[P_REL_AMAX] - P[P_REL_ALEAK]) * s
    return (P[P_REL_CD] * area * math.sqrt(2.0 / P[P_RHO]) * dp
            / (dp * dp + P[P_REL_PCR] * P[P_REL_PCR]) ** 0.25)


@numba.njit(cache=True)
def _seal_force(v, dp, P):
    """Friction of one cylinder's seals at piston speed ``v`` (Stribeck form, seal module),
    plus the pressure-dependent part ``c_p |Δp| tanh(v/v_C)`` of
    :meth:`afo_mj.hydraulics.seal.OringSeal.friction_force_n` when ``SEAL_CP`` is set
    (``dp`` the pressure across the piston, ``|Δp|`` rounded over 10 kPa for Newton)."""
    f = P[P_SEAL_FC] * math.tanh(v / P[P_SEAL_VC]) + P[P_SEAL_FV] * v
    if P[P_SEAL_STRIB] != 0.0:
        r = v / P[P_SEAL_VST]
        f += P[P_SEAL_STRIB] * math.exp(-r * r) * r
    if P[P_SEAL_CP] != 0.0:
        f += P[P_SEAL_CP] * math.sqrt(dp * dp + 1e8) * math.tanh(v / P[P_SEAL_VC])
    return f


@numba.njit(cache=True)
def chamber_rates(na, nb, c_ca, c_cb, xdot, ae, P):
    """Chamber pressure rates ``(ṗ_a, ṗ_b)`` and the piston speed ``ẋ_p`` from the chambers'
    net inflows ``na, nb`` (with the piston flow ``±A_e ẋ`` at the rigid-cable speed ``ẋ = r θ̇``)
    and capacitances.

    Rigid cable (``SERIES_COMP = 0``): ``ṗ = n/C`` and ``ẋ_p = ẋ``. A cable/series spring of
    rotational stiffness ``k`` between pulley and pistons (:func:`afo_mj.hydraulics.
    transmission.series_compliance_m3_pa`) stretches by the hydraulic torque
    ``τ_h = −r A_e Δp``: ``θ_p = θ − r A_e Δp/k``, so the pistons move at
    ``ẋ_p = ẋ − (c_s/A_e) Δṗ`` with ``c_s = r² A_e²/k`` and each chamber sees the other through
    the differential capacitance ``c_s``:
    ``(C_a + c_s) ṗ_a − c_s ṗ_b = n_a``, ``−c_s ṗ_a + (C_b + c_s) ṗ_b = n_b`` (massless cable,
    stretch from the hydraulic torque only: the seal friction is a few per cent of it)."""
    cs = P[P_SERIES_COMP]
    if cs == 0.0:
        return na / c_ca, nb / c_cb, xdot
    caa = c_ca + cs
    cbb = c_cb + cs
    det = caa * cbb - cs * cs
    dpa = (cbb * na + cs * nb) / det
    dpb = (cs * na + caa * nb) / det
    return dpa, dpb, xdot - cs / ae * (dpa - dpb)


@numba.njit(cache=True)
def rhs(y, theta, theta_dot, v_cmd, v_bus, mu, P, dy, F):
    """``dy/dt`` of one side and its power flows ``F`` (see the module docstring)."""
    cur, w = y[Y_I], y[Y_W]
    ppa, ppb, pca, pcb = y[Y_PPA], y[Y_PPB], y[Y_PCA], y[Y_PCB]
    # driver: current-limit clamp and duty limit
    volt = v_cmd
    emf = P[P_K] * w
    if P[P_CUR_LIM_ON] > 0.0:
        band = P[P_R] * P[P_I_LIM]
        volt = _soft_clip(volt, emf - band, emf + band, 0.05)
    vmax = P[P_DUTY] * v_bus
    volt = _soft_clip(volt, -vmax, vmax, 0.05)
    di = (volt - P[P_R] * cur - emf) / P[P_L]
    tf_m = P[P_TC_M] * math.tanh(w / P[P_WC_M]) + P[P_BV_M] * w
    # pump
    dpp = ppa - ppb
    q_leak_p = (P[P_CS] * P[P_D] + P[P_PUMP_G_EXTRA]) * dpp / mu
    q_pump = P[P_D] * w - q_leak_p
    sgn = math.tanh(w / P[P_WC_P])
    # |Δp| rounded over 10 kPa: the Coulomb term's kink at equal port pressures would stall
    # the step's Newton correction (and is not physical at that scale anyway)
    abs_dp = math.sqrt(dpp * dpp + 1e8)
    t_pfric = (P[P_CF] * P[P_D] * abs_dp + P[P_T0]) * sgn + P[P_CV] * P[P_D] * mu * w
    t_pump = P[P_D] * dpp + t_pfric
    dw = (P[P_K] * cur - tf_m - t_pump) / P[P_J]
    # hoses
    r_h = P[P_HOSE_K] * mu
    q_ha = (ppa - pca) / r_h
    q_hb = (ppb - pcb) / r_h
    # relief valves, both ways between the pump ports
    q_rel = _relief_flow(dpp, P) - _relief_flow(-dpp, P)
    # flushing valve: reservoir into the lower line
    s_a = 0.5 * (1.0 + math.tanh((ppb - ppa) / P[P_FLUSH_BAND]))
    q_fa = P[P_FLUSH_G] * s_a * (P[P_P_RES] - ppa)
    q_fb = P[P_FLUSH_G] * (1.0 - s_a) * (P[P_P_RES] - ppb)
    # make-up (anti-cavitation) check valves: reservoir into any line below its pressure
    eb = P[P_MAKEUP_BAND]
    xa = P[P_P_RES] - ppa
    xb = P[P_P_RES] - ppb
    q_ma = P[P_MAKEUP_G] * _ramp_c1(xa, eb)
    q_mb = P[P_MAKEUP_G] * _ramp_c1(xb, eb)
    # cylinders on the pulley
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
    # node capacitances
    vh2 = 0.5 * P[P_V_HOSE]
    cw = vh2 * P[P_KWALL_INV]
    c_pa = (P[P_V_PORT] + vh2) / _bulk_modulus(ppa, P) + cw
    c_pb = (P[P_V_PORT] + vh2) / _bulk_modulus(ppb, P) + cw
    c_ca = (va + vh2) / _bulk_modulus(pca, P) + cw
    c_cb = (vb + vh2) / _bulk_modulus(pcb, P) + cw
    net_pa = q_pump - q_ha - q_rel + q_fa + q_ma
    net_pb = -q_pump - q_hb + q_rel + q_fb + q_mb
    net_ca = q_ha - q_lk + ae * xdot
    net_cb = q_hb + q_lk - ae * xdot
    dpca, dpcb, xdp = chamber_rates(net_ca, net_cb, c_ca, c_cb, xdot, ae, P)
    f_seal = P[P_N_CYL] * _seal_force(xdp, pca - pcb, P)
    tau_h = -r * ae * (pca - pcb)
    tau = tau_h - r * f_seal
    dy[Y_I] = di
    dy[Y_W] = dw
    dy[Y_PPA] = net_pa / c_pa
    dy[Y_PPB] = net_pb / c_pb
    dy[Y_PCA] = dpca
    dy[Y_PCB] = dpcb
    # power flows (W)
    F[F_VOLT] = volt
    F[F_PBUS] = volt * cur + P[P_R_ON] * cur * cur + P[P_P_Q]
    F[F_DRIVER] = P[P_R_ON] * cur * cur + P[P_P_Q]
    F[F_COPPER] = P[P_R] * cur * cur
    F[F_MFRIC] = tf_m * w
    F[F_PVOL] = dpp * q_leak_p
    F[F_PMECH] = t_pfric * w
    F[F_LINE] = (ppa - pca) * q_ha + (ppb - pcb) * q_hb
    F[F_FLUSH] = xa * (q_fa + q_ma) + xb * (q_fb + q_mb)
    F[F_RELIEF] = dpp * q_rel
    F[F_SEAL] = r * f_seal * theta_dot if xdp == xdot else f_seal * xdp
    F[F_LEAK] = (pca - pcb) * q_lk
    F[F_RES_Q] = q_fa + q_fb + q_ma + q_mb   # flow drawn from the reservoir (gauge p_r)
    F[F_TAU] = tau
    F[F_HYD] = dpp * q_pump           # hydraulic power leaving the pump
    F[F_CAP_PA] = c_pa
    F[F_CAP_PB] = c_pb
    F[F_CAP_CA] = c_ca
    F[F_CAP_CB] = c_cb
    F[F_HEAT_OIL] = (F[F_PVOL] + F[F_PMECH] + F[F_LINE] + F[F_FLUSH] + F[F_RELIEF]
                     + F[F_SEAL] + F[F_LEAK])


@numba.njit(cache=True)
def _solve6(M, rhs_mat, ncol):
    """Solve ``M X = rhs`` in place (6×6, partial pivoting); ``rhs_mat`` is 6×ncol."""
    solve_linear(M, rhs_mat, 6, ncol)


@numba.njit(cache=True)
def solve_linear(M, rhs_mat, n, ncol):
    """Solve ``M X = rhs`` in place (``n×n``, Gaussian elimination with partial pivoting);
    ``rhs_mat`` is ``n×ncol``."""
    for c in range(n):
        piv = c
        big = abs(M[c, c])
        for r_ in range(c + 1, n):
            if abs(M[r_, c]) > big:
                big = abs(M[r_, c])
                piv = r_
        if piv != c:
            for k in range(n):
                tmp = M[c, k]
                M[c, k] = M[piv, k]
                M[piv, k] = tmp
            for k in range(ncol):
                tmp = rhs_mat[c, k]
                rhs_mat[c, k] = rhs_mat[piv, k]
                rhs_mat[piv, k] = tmp
        inv = 1.0 / M[c, c]
        for r_ in range(c + 1, n):
            fac = M[r_, c] * inv
            if fac != 0.0:
                for k in range(c, n):
                    M[r_, k] -= fac * M[c, k]
                for k in range(ncol):
                    rhs_mat[r_, k] -= fac * rhs_mat[c, k]
    for c in range(n - 1, -1, -1):
        for k in range(ncol):
            s = rhs_mat[c, k]
            for j in range(c + 1, n):
                s -= M[c, j] * rhs_mat[j, k]
            rhs_mat[c, k] = s / M[c, c]


_Y_TYP = np.array([1.0, 10.0, 1e5, 1e5, 1e5, 1e5])


@numba.njit(cache=True)
def viscosity_pa_s(temp_k, P):
    """Walther viscosity (ASTM D341, :func:`afo_mj.hydraulics.fluid.walther_viscosity_m2_s`)
    times the density at ``temp_k``."""
    nu = (10.0 ** (10.0 ** (P[P_WALTHER_B] - P[P_WALTHER_C] * math.log10(temp_k))) - 0.7) * 1e-6
    rho = P[P_RHO] / (1.0 + P[P_RHO_T_COEF] * (temp_k - P[P_T_REF]))
    return rho * nu


@numba.njit(cache=True)
def linearise(y, P, W, scratch):
    """Fill ``W[A0:A5], W[B0:B5], W[TAU0], W[G]`` for the step ``h = scratch[0, 0]`` with the
    inputs held in ``W`` (the first half of the implicit step)."""
    h = scratch[0, 0]
    theta, thd = W[W_THETA], W[W_THETA_DOT]
    vc, vb, mu = W[W_V_CMD], W[W_V_BUS], W[W_MU]
    f0 = scratch[1, :N_Y]
    F0 = scratch[2]
    rhs(y, theta, thd, vc, vb, mu, P, f0, F0)
    tau0 = F0[F_TAU]
    yp = scratch[3, :N_Y]
    fp = scratch[4, :N_Y]
    Fp = scratch[5]
    M = scratch[6:12, :N_Y]
    R = scratch[12:18, :2]
    dtau_dy = scratch[18, :N_Y]
    Mcopy = scratch[19:25, :N_Y]
    for j in range(N_Y):
        for k in range(N_Y):
            yp[k] = y[k]
        d = 1e-7 * max(abs(y[j]), _Y_TYP[j])
        yp[j] = y[j] + d
        rhs(yp, theta, thd, vc, vb, mu, P, fp, Fp)
        for k in range(N_Y):
            M[k, j] = -h * (fp[k] - f0[k]) / d
        M[j, j] += 1.0
        dtau_dy[j] = (Fp[F_TAU] - tau0) / d
    dv = 1e-7 * max(abs(thd), 1.0)
    rhs(y, theta, thd + dv, vc, vb, mu, P, fp, Fp)
    dtau_dv = (Fp[F_TAU] - tau0) / dv
    for k in range(N_Y):
        R[k, 0] = h * f0[k]
        R[k, 1] = h * (fp[k] - f0[k]) / dv
    for j in range(N_Y):
        for k in range(N_Y):
            Mcopy[j, k] = M[j, k]
    _solve6(M, R, 2)
    g = dtau_dv
    t0 = tau0
    for k in range(N_Y):
        W[W_A0 + k] = R[k, 0]
        W[W_B0 + k] = R[k, 1]
        t0 += dtau_dy[k] * R[k, 0]
        g += dtau_dy[k] * R[k, 1]
    W[W_TAU0] = t0
    W[W_G] = g


@numba.njit(cache=True)
def controller(y, P, W, tau_cmd, h):
    """Low-level torque control through motor voltage (the circuit has no valve).

    The chamber pressure transducers give the hydraulic torque ``τ_m = −r A_e (p_ca − p_cb)``.
    The desired pump speed is the flow feedforward that keeps the chamber pressures while the
    ankle moves (line a must absorb ``−A_e r θ̇``) plus a PI law on the pressure error::

        ω_d = −A_e r θ̇ / d + k_p (Δp_d − Δp) + k_i ∫(Δp_d − Δp) dt      (anti-windup clamp)
        v   = R d Δp_d / K + K ω_d + k_ω (ω_d − ω)

    (current feedforward for the pump torque at ``Δp_d``, back-EMF at ``ω_d``, proportional
    speed loop on the motor's Hall speed). The driver then applies its current limit and duty
    limit (:func:`rhs`). In voltage mode (``MODE == 1``) ``tau_cmd`` is the motor voltage.
    Returns the commanded voltage.
    """
    r = P[P_R_PULLEY]
    ae = P[P_A_E]
    d = P[P_D]
    dp_meas = y[Y_PCA] - y[Y_PCB]
    W[W_TAU_MEAS] = -r * ae * dp_meas
    W[W_TAU_CMD] = tau_cmd
    if P[P_MODE] == MODE_VOLTAGE:
        return tau_cmd
    dp_des = -tau_cmd / (r * ae)
    err = dp_des - dp_meas
    integ = W[W_INT] + err * h
    lim = P[P_INT_LIM]
    if integ > lim:
        integ = lim
    elif integ < -lim:
        integ = -lim
    W[W_INT] = integ
    w_des = -ae * r * W[W_THETA_DOT] / d + P[P_K_PRESSURE] * err + P[P_K_INT] * integ
    i_ff = d * dp_des / P[P_K]
    return P[P_R] * i_ff + P[P_K] * w_des + P[P_K_SPEED] * (w_des - y[Y_W])


@numba.njit(cache=True)
def begin_step(Y, P, W, S, theta, theta_dot, tau_cmd, out):
    """First half of the coupled step for every side ``s``: hold the inputs, run the
    controller, linearise. ``out[s] = (τ_0 − G θ̇_n, −G)``: the explicit joint force and the
    extra joint damping to hand to MuJoCo (module docstring). ``S[s, 0, 0]`` holds the step."""
    for s in range(Y.shape[0]):
        Ws = W[s]
        Ps = P[s]
        h = S[s, 0, 0]
        Ws[W_THETA] = theta[s]
        Ws[W_THETA_DOT] = theta_dot[s]
        Ws[W_MU] = viscosity_pa_s(Ws[W_TEMP_K], Ps)
        v_oc = battery_ocv(Ws[W_SOC], Ps)
        Ws[W_V_BUS] = max(v_oc - Ps[P_BAT_R] * Ws[W_I_BAT], 0.0)
        Ws[W_V_CMD] = controller(Y[s], Ps, Ws, tau_cmd[s], h)
        linearise(Y[s], Ps, Ws, S[s])
        g = Ws[W_G]
        damping = -g if g < 0.0 else 0.0
        # τ_{n+1} = τ0 + G(θ̇_{n+1} − θ̇_n) = (τ0 − G θ̇_n) − D θ̇_{n+1} with D = −G ≥ 0.
        # A positive G (rare: a rising friction branch) is never handed to MuJoCo as negative
        # damping; it is applied at the current velocity (W_G = 0 keeps the ledger consistent).
        if g > 0.0:
            Ws[W_G] = 0.0
            out[s, 0] = Ws[W_TAU0]
        else:
            out[s, 0] = Ws[W_TAU0] - g * theta_dot[s]
        out[s, 1] = damping


@numba.njit(cache=True)
def finish_all(Y, P, W, S, theta_dot_new, tau_out):
    """Second half for every side; ``tau_out[s]`` gets the delivered torque."""
    ok = True
    for s in range(Y.shape[0]):
        tau_out[s] = finish_step(Y[s], P[s], W[s], theta_dot_new[s], S[s])
        for k in range(N_Y):
            if not math.isfinite(Y[s, k]):
                ok = False
    return ok


@numba.njit(cache=True)
def jacobian(y, theta, theta_dot, h, P, W, scratch, M):
    """``M = I − h ∂f/∂y`` at ``(y, θ̇)`` by forward differences (uses scratch rows 25–29)."""
    f0 = scratch[25, :N_Y]
    F0 = scratch[26]
    yp = scratch[27, :N_Y]
    fp = scratch[28, :N_Y]
    Fp = scratch[29]
    rhs(y, theta, theta_dot, W[W_V_CMD], W[W_V_BUS], W[W_MU], P, f0, F0)
    for j in range(N_Y):
        for k in range(N_Y):
            yp[k] = y[k]
        d = 1e-7 * max(abs(y[j]), _Y_TYP[j])
        yp[j] = y[j] + d
        rhs(yp, theta, theta_dot, W[W_V_CMD], W[W_V_BUS], W[W_MU], P, fp, Fp)
        for k in range(N_Y):
            M[k, j] = -h * (fp[k] - f0[k]) / d
        M[j, j] += 1.0


#: Newton tolerance on the backward-Euler residual, per state, in units of ``_Y_TYP``.
NEWTON_TOL = 1e-9
#: Smallest sub-step, as a fraction of the MuJoCo step, before a step is accepted unconverged.
MIN_SUBSTEP_FRACTION = 1.0 / 1024.0


@numba.njit(cache=True)
def _newton(y, yold, h, theta, theta_dot, P, W, scratch, first_matrix):
    """Solve the backward-Euler equations ``y − y_old − h f(y, θ̇) = 0`` by Newton from the
    guess in ``y`` (in place). The first iteration uses the step's own ``I − h J`` (scratch
    rows 19–24) when ``first_matrix``; later ones a fresh Jacobian. Leaves ``f`` and the
    power flows at the solution in scratch rows 1–2. Returns whether it converged."""
    f1 = scratch[1, :N_Y]
    F1 = scratch[2]
    Mw = scratch[6:12, :N_Y]
    Mcopy = scratch[19:25, :N_Y]
    rv = scratch[12:18, :1]
    ybest = scratch[4, :N_Y]
    step = scratch[5, :N_Y]
    err_prev = 1e300
    # chord iterations on the step's own matrix while they contract fast (a tenfold drop per
    # iteration), a fresh Jacobian from the first one that does not
    chord = first_matrix
    for it in range(24):
        rhs(y, theta, theta_dot, W[W_V_CMD], W[W_V_BUS], W[W_MU], P, f1, F1)
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
            # diverging (not merely non-monotone, which Newton often is after a large input
            # change), or still not contracting after 8 iterations (a cycle across a valve's
            # or a friction law's switch): halve the last step (damped Newton)
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
                    Mw[j, k] = Mcopy[j, k]
        else:
            jacobian(y, theta, theta_dot, h, P, W, scratch, Mw)
        _solve6(Mw, rv, 1)
        for k in range(N_Y):
            ybest[k] = y[k]
            step[k] = rv[k, 0]
            y[k] += rv[k, 0]
        for k in range(N_Y):
            if not math.isfinite(y[k]):
                return False
    return False


@numba.njit(cache=True)
def finish_step(y, P, W, theta_dot_new, scratch):
    """Second half of the implicit step: the new ankle velocity closes it.

    The linear prediction ``y_n + a + b Δθ̇`` is corrected by Newton iterations on the
    backward-Euler equations ``y − y_n − h f(y, θ̇_{n+1}) = 0`` (:func:`_newton`), so the end
    state satisfies them to ``NEWTON_TOL`` of each state's scale and the right-point energy
    ledger closes. Where Newton does not converge in one step (violent back-driving: the
    motor's EMF overtakes the bus, a make-up valve slams open), the step is redone as
    adaptive sub-steps (halved on failure, doubled after success, down to
    ``MIN_SUBSTEP_FRACTION`` of the step) with the ankle velocity ramped linearly from
    ``θ̇_n`` to ``θ̇_{n+1}`` across them: every sub-step is a converged backward-Euler step,
    so the ledger still closes. The torque MuJoCo integrated was the prediction
    ``τ_0 + G Δθ̇``; its difference from the end-point torque is accumulated as the coupling
    error. Updates ``y``, battery, temperature and the ledger; returns the applied torque."""
    h = scratch[0, 0]
    thd0 = W[W_THETA_DOT]
    dthd = theta_dot_new - thd0
    theta = W[W_THETA]
    yold = scratch[3, :N_Y]
    ystart = scratch[30, :N_Y]
    for k in range(N_Y):
        yold[k] = y[k]
        ystart[k] = y[k]
        y[k] += W[W_A0 + k] + W[W_B0 + k] * dthd
    tau = W[W_TAU0] + W[W_G] * dthd
    F1 = scratch[2]
    if _newton(y, yold, h, theta, theta_dot_new, P, W, scratch, True):
        _close_substep(y, yold, h, theta_dot_new, P, W, scratch)
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
            ok = _newton(y, yold, frac * h, theta, thd, P, W, scratch, False)
            if not ok and frac > MIN_SUBSTEP_FRACTION:
                for k in range(N_Y):
                    y[k] = yold[k]
                frac *= 0.5
                continue
            if not ok:
                # accepted unconverged at the smallest sub-step: counted, never silent
                W[W_NEWTON_FAIL] += 1.0
                for k in range(N_Y):
                    if not math.isfinite(y[k]):
                        y[k] = yold[k]
                rhs(y, theta, thd, W[W_V_CMD], W[W_V_BUS], W[W_MU], P, scratch[1, :N_Y], F1)
            W[W_SUBSTEPS] += 1.0
            _close_substep(y, yold, frac * h, thd, P, W, scratch)
            pos += frac
            if ok:
                frac *= 2.0
    W[W_TAU] = tau
    W[W_TAU_END] = F1[F_TAU]
    W[W_COUPLE_SQ] += (tau - F1[F_TAU]) ** 2
    W[W_P_MECH] = F1[F_TAU] * theta_dot_new
    return tau


@numba.njit(cache=True)
def _close_substep(y, yold, h, theta_dot, P, W, scratch):
    """Accept the backward-Euler (sub-)step ``yold → y`` of length ``h`` (power flows at
    ``y`` in scratch row 2): pressure floor, battery, right-point energy ledger, thermal."""
    F1 = scratch[2]
    floor = P[P_P_FLOOR] - P[P_P_ATM]
    # pressure floor (absolute): a node cannot go below the vapour pressure
    clipped = False
    for k in range(Y_PPA, Y_PCB + 1):
        if y[k] < floor:
            y[k] = floor
            clipped = True
    if clipped:
        W[W_CLIP_STEPS] += 1.0
        rhs(y, W[W_THETA], theta_dot, W[W_V_CMD], W[W_V_BUS], W[W_MU], P, scratch[1, :N_Y],
            F1)
    # battery: pack current for the bus power, V_oc from the state of charge
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
    # energy throughput (scale of the balance check when the ankle back-drives the pump)
    W[W_E_ABS_FLOW] += h * (abs(v_oc * i_bat) + abs(F1[F_TAU] * theta_dot))
    W[W_E_BATTERY] += h * rb * i_bat * i_bat
    W[W_E_MECH] += h * F1[F_TAU] * theta_dot
    W[W_E_DRIVER] += h * F1[F_DRIVER]
    W[W_E_COPPER] += h * F1[F_COPPER]
    W[W_E_MOTOR_FRICTION] += h * F1[F_MFRIC]
    W[W_E_PUMP_VOL] += h * F1[F_PVOL]
    W[W_E_PUMP_MECH] += h * F1[F_PMECH]
    W[W_E_LINE] += h * F1[F_LINE]
    W[W_E_FLUSH] += h * F1[F_FLUSH]
    W[W_E_RELIEF] += h * F1[F_RELIEF]
    W[W_E_SEAL] += h * F1[F_SEAL]
    W[W_E_LEAK] += h * F1[F_LEAK]
    W[W_E_HYD] += h * F1[F_HYD]
    # the reservoir (constant gauge pressure p_r) gives up p_r·Q when it feeds the lines
    W[W_E_RESERVOIR] -= h * P[P_P_RES] * F1[F_RES_Q]
    # discrete work on the stores (backward Euler): y_{n+1} · M · Δy
    W[W_E_STORE_L] += P[P_L] * y[Y_I] * (y[Y_I] - yold[Y_I])
    W[W_E_STORE_ROT] += P[P_J] * y[Y_W] * (y[Y_W] - yold[Y_W])
    W[W_E_STORE_OIL] += (F1[F_CAP_PA] * y[Y_PPA] * (y[Y_PPA] - yold[Y_PPA])
                         + F1[F_CAP_PB] * y[Y_PPB] * (y[Y_PPB] - yold[Y_PPB])
                         + F1[F_CAP_CA] * y[Y_PCA] * (y[Y_PCA] - yold[Y_PCA])
                         + F1[F_CAP_CB] * y[Y_PCB] * (y[Y_PCB] - yold[Y_PCB]))
    # thermal: oil heated by the hydraulic losses, cooled to ambient (explicit)
    temp = W[W_TEMP_K]
    W[W_TEMP_K] = temp + h * (F1[F_HEAT_OIL] - (temp - P[P_T_AMB]) / P[P_R_TH]) / P[P_C_TH]
    W[W_HEAT_TO_OIL] += h * F1[F_HEAT_OIL]
    pm = max(y[Y_PPA], y[Y_PPB], y[Y_PCA], y[Y_PCB])
    if pm > W[W_P_MAX]:
        W[W_P_MAX] = pm
    if abs(y[Y_I]) > W[W_I_PEAK]:
        W[W_I_PEAK] = abs(y[Y_I])


_OCV_SOC = np.array([0.0, 0.05, 0.10, 0.20, 0.30, 0.40, 0.50, 0.60, 0.70, 0.80, 0.90, 1.0])
_OCV_V = np.array([3.00, 3.45, 3.55, 3.62, 3.66, 3.70, 3.75, 3.81, 3.88, 3.96, 4.06, 4.20])


@numba.njit(cache=True)
def battery_ocv(soc, P):
    """Pack open-circuit voltage, ``N_s · v_cell(SOC)`` (:mod:`afo_mj.hydraulics.battery`)."""
    s = min(max(soc, 0.0), 1.0)
    for k in range(len(_OCV_SOC) - 1):
        if s <= _OCV_SOC[k + 1]:
            u = (s - _OCV_SOC[k]) / (_OCV_SOC[k + 1] - _OCV_SOC[k])
            return P[P_BAT_NS] * (_OCV_V[k] + u * (_OCV_V[k + 1] - _OCV_V[k]))
    return P[P_BAT_NS] * _OCV_V[-1]


# ---- the device's whole coupled step in two compiled calls ------------------------------------
# (afo_mj.devices.hafo.HafoDevice.begin_step / end_step: one dispatch each per 1 ms step instead
# of a Python loop over the sides with a compiled call per side and many small numpy writes;
# the arithmetic is the same, so results are bit-identical; benchmarks/coupling.py). A call's
# cost grows with its number of array arguments, so the device keeps all its per-side float
# arrays as views of one buffer ``buf``, laid out by the int64 array ``meta`` (offsets M_*,
# then the walker side of each worn side); :func:`device_views` cuts them out again.
from afo_mj.control.assistance import (  # noqa: E402
    N_PH as _N_PH, PH_PHASE as _PH_PHASE, phase_update as _phase_update,
    table_lookup as _table_lookup)

#: rows of the per-worn-side work array ``V`` (N_V, sides)
V_THETA, V_THETA_DOT, V_TAU_CMD, V_THETA_DOT_NEW, V_TAU = range(5)
N_V = 5
#: rows of the per-walker-side output array ``O`` (N_O, 2)
O_FORCE, O_DAMPING, O_DELIVERED, O_COMMANDED, O_PHASE = range(5)
N_O = 5
#: ``meta`` entries: buffer offsets of Y, P, W, S, phase state, profile, V, out (sides, 2), O,
#: stride limits (min, max); then buffer length, worn sides, profile points; side indices follow
(M_Y, M_P, M_W, M_S, M_PH, M_PROFILE, M_V, M_OUT, M_O, M_LIM, M_END, M_NS,
 M_NPROF) = range(13)
N_META = 13
#: the device log's signals, in the order of its rows (``hafo._DeviceLog.FIELDS``)
LOG_FIELDS = ("time_s", "commanded_torque_nm", "delivered_torque_nm", "measured_torque_nm",
              "phase", "motor_command_v", "motor_current_a", "motor_speed_rad_s",
              "pressure_a_pa", "pressure_b_pa", "chamber_a_pa", "chamber_b_pa",
              "bus_voltage_v", "battery_current_a", "mechanical_power_w", "oil_temperature_k",
              "ankle_velocity_rad_s")


def device_layout(sides: int, profile_points: int, side_index, n_y: int = N_Y,
                  n_p: int = N_P, n_w: int = N_W, n_scratch: int = N_SCRATCH,
                  n_f: int = N_F) -> np.ndarray:
    """``meta`` for a device worn on ``sides`` sides (walker sides ``side_index``); the sizes
    default to this kernel's (another kernel of the same layout passes its own)."""
    sizes = {M_Y: sides * n_y, M_P: sides * n_p, M_W: sides * n_w,
             M_S: sides * n_scratch * n_f, M_PH: sides * _N_PH, M_PROFILE: profile_points,
             M_V: N_V * sides, M_OUT: sides * 2, M_O: N_O * 2, M_LIM: 2}
    meta = np.zeros(N_META + sides, dtype=np.int64)
    off = 0
    for m in range(M_END):
        meta[m] = off
        off += sizes[m]
    meta[M_END], meta[M_NS], meta[M_NPROF] = off, sides, profile_points
    meta[N_META:] = side_index
    return meta


@numba.njit(cache=True)
def device_views(buf, meta):
    """``(Y, P, W, S, phase_state, profile, V, out, O)``: views of the device buffer."""
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
    """First half of the coupled step of every worn side ``k`` (walker side
    ``meta[N_META + k]``): gait-phase estimate from the foot switch, commanded torque from the
    tabulated profile (:mod:`afo_mj.control.assistance`), then :func:`begin_step`. Writes the
    joint force, extra damping, commanded torque and phase into rows ``O_*`` of ``O``
    (walker sides)."""
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
        cmd[k] = _table_lookup(profile, ph)
        O[O_PHASE, s] = ph
    begin_step(Y, P, W, S, th, thd, cmd, out)
    for k in range(ns):
        s = meta[N_META + k]
        O[O_FORCE, s] = out[k, 0]
        O[O_DAMPING, s] = out[k, 1]
        O[O_COMMANDED, s] = cmd[k]


@numba.njit(cache=True)
def device_end(velocity2, buf, meta, log, k, t):
    """Second half for every worn side: :func:`finish_all` with the new ankle velocities,
    delivered torques into ``O[O_DELIVERED]`` and, when ``k < log.shape[0]``, row ``k`` of the
    device log (steps × ``LOG_FIELDS`` × sides: one step's signals side by side in memory) at
    time ``t``. Returns 0 when a state became
    non-finite, 2 when the log row was written, 1 otherwise."""
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
        log[k, 8, j] = Yj[Y_PPA]
        log[k, 9, j] = Yj[Y_PPB]
        log[k, 10, j] = Yj[Y_PCA]
        log[k, 11, j] = Yj[Y_PCB]
        log[k, 12, j] = Wj[W_V_BUS]
        log[k, 13, j] = Wj[W_I_BAT]
        log[k, 14, j] = Wj[W_P_MECH]
        log[k, 15, j] = Wj[W_TEMP_K]
        log[k, 16, j] = vnew[j]
    return 2
