"""The walking controller's per-step law, compiled (numba): gait events, reference lookup,
servo targets and feedforward, foot placement, toe-clearance reflex, trunk control, pelvis
residuals and the Hill-limited plantarflexor range.

What each part does and where it comes from is described in
:mod:`afo_mj.gait.tracking_controller`, whose :class:`~afo_mj.gait.tracking_controller.
TrackingController` builds the packed arrays this function reads (``const``: scalars,
``index``: MuJoCo addresses, ``state``: the controller's memory) and calls it once per MuJoCo
step (its Python step; the compiled loop :mod:`afo_mj.gait.walk_loop` calls it too). Keeping
the law in one compiled function keeps Python out of the 1 ms loop
(``benchmarks/gait_step.py``).

Event codes written to ``state[S_EVENT + side]``: 0 none, 1 heel strike, 2 toe off,
3 start of a swing-phase floor contact (scuff).
"""

from __future__ import annotations

import numba

# --- state slots --------------------------------------------------------------------------------
S_PHASE = 0          # 2: gait phase per leg
S_SWING = 2          # 2: 1.0 in swing
S_SCUFF = 4          # 2: 1.0 while a swing contact lasts
S_TOE_OFF_T = 6      # 2: time of the last toe off
S_V_MEAN = 8         # stride-mean forward speed
S_Z_MEAN = 9         # stride-mean pelvis height coordinate
S_EVENT = 10         # 2: event code of this step
N_STATE = 12

# --- constants ----------------------------------------------------------------------------------
(C_DT, C_INV_T, C_ON_N, C_OFF_N, C_HS_PHASE, C_CHATTER_S, C_ALPHA, C_V_REF, C_LEAN_GAIN,
 C_LEAN_MAX, C_AHEAD_NORM, C_CV, C_CLEAR_M, C_CLEAR_GAIN, C_RADIUS, C_TRACK, C_LEAD_HIP,
 C_TRUNK_KP, C_TRUNK_KD, C_EXTRA_GAIN, C_WARMUP_S, C_RES_TX, C_RES_TZ, C_RES_TZD, C_RES_TK,
 C_RES_TKD, C_PF_W_MAX, C_HILL_A, C_PF_ISO, _C_PF_ISO_L, C_TABLE_N, C_LEAD, _C_LEAD1, _C_LEAD2,
 C_FF, _C_FF1, _C_FF2, C_SPEED_ADAPT, N_CONST) = range(39)

# --- MuJoCo addresses ---------------------------------------------------------------------------
(I_TOUCH, _I_T1, _I_T2, _I_T3,          # sensordata: heel_r, ball_r, heel_l, ball_l
 I_HIP_Q, _I_HIP_Q_L,                   # qpos of hip r, l
 I_HIP_V, _I_HIP_V_L,                   # qvel of hip r, l
 I_ANKLE_V, _I_ANKLE_V_L,               # qvel of ankle r, l
 I_PX, I_PZ, I_PT, I_DPX, I_DPZ, I_DPT,  # pelvis qpos and qvel addresses
 I_BALL, _I_BALL_L,                     # ball sphere geoms
 I_ANKLE_J, _I_ANKLE_J_L,               # ankle joints (for jnt_actfrcrange)
 I_PD, _I_PD1, _I_PD2, _I_PD3, _I_PD4, _I_PD5,   # servo actuators [r hip knee ankle, l ...]
 I_FF, _I_FF1, _I_FF2, _I_FF3, _I_FF4, _I_FF5,   # torque motors, same order
 I_RES_X, I_RES_Z, I_RES_T, N_INDEX) = range(36)

# Reference table columns (see afo_mj.gait.tracking_controller.ReferenceTable)
_ANGLE, _RATE, _MOMENT, _AHEAD_RATE = 0, 3, 6, 10


@numba.njit(cache=True, inline="always")
def _row(table, table_step, i, f, c):
    """Column ``c`` of the reference table at row ``i`` plus fraction ``f`` (linear)."""
    return table[i, c] + f * table_step[i, c]


@numba.njit(cache=True, fastmath=False, _nrt=False)
def control_step(t, qpos, qvel, sens, geom_xpos, state, table, table_step, const, index,
                 ctrl, actfrcrange):  # pragma: no cover - compiled; exercised by the walk tests
    """Advance the controller by one step at time ``t`` and write ``ctrl`` and the ankle's
    plantarflexion torque limit. Arrays are MuJoCo's live views and the packed arrays above."""
    n = int(const[C_TABLE_N])
    dt = const[C_DT]
    # --- gait events from foot load (touch sensors: heel + ball) -------------------------------
    # (no arrays are allocated here: scalars per side, the reference rows read on demand and
    # the targets and torques kept in ctrl, as this runs every step)
    load0 = 0.0
    load1 = 0.0
    for s in range(2):
        load = sens[index[I_TOUCH + 2 * s]] + sens[index[I_TOUCH + 2 * s + 1]]
        if s == 0:
            load0 = load
        else:
            load1 = load
        state[S_EVENT + s] = 0.0
        ph = state[S_PHASE + s] + dt * const[C_INV_T]
        if state[S_SWING + s] > 0.5:
            if load > const[C_ON_N] and ph > const[C_HS_PHASE]:
                state[S_SWING + s] = 0.0
                ph = 0.0
                state[S_SCUFF + s] = 0.0
                state[S_EVENT + s] = 1.0
            elif load > const[C_ON_N] and t - state[S_TOE_OFF_T + s] > const[C_CHATTER_S]:
                # a floor contact in swing (not the last touch of toe off): a scuff
                if state[S_SCUFF + s] < 0.5:
                    state[S_EVENT + s] = 3.0
                    state[S_SCUFF + s] = 1.0
            elif load <= const[C_OFF_N]:
                state[S_SCUFF + s] = 0.0
        elif load <= const[C_OFF_N] and ph > 0.4:
            state[S_SWING + s] = 1.0
            state[S_TOE_OFF_T + s] = t
            state[S_EVENT + s] = 2.0
        if ph > 0.999:
            ph = 0.999           # a late heel strike: the swing leg holds its end of swing
        state[S_PHASE + s] = ph

    # --- reference rows at each leg's phase (linear interpolation) ------------------------------
    x = min(max(state[S_PHASE], 0.0), 1.0) * n
    i0 = min(int(x), n - 1)
    f0 = x - i0
    x = min(max(state[S_PHASE + 1], 0.0), 1.0) * n
    i1 = min(int(x), n - 1)
    f1 = x - i1
    for s in range(2):
        i = i0 if s == 0 else i1
        f = f0 if s == 0 else f1
        for j in range(3):
            ctrl[index[I_PD + 3 * s + j]] = (
                _row(table, table_step, i, f, _ANGLE + j)
                + const[C_LEAD + j] * _row(table, table_step, i, f, _RATE + j))
            ctrl[index[I_FF + 3 * s + j]] = const[C_FF + j] * _row(table, table_step, i, f,
                                                                    _MOMENT + j)

    vx = qvel[index[I_DPX]]
    v_mean = state[S_V_MEAN]
    lean = min(max(const[C_LEAN_GAIN] * (const[C_V_REF] - v_mean), 0.0), const[C_LEAN_MAX])
    tilt = qpos[index[I_PT]] - lean          # trunk pitch error (+ = too far forward)
    tilt_rate = qvel[index[I_DPT]]
    v_mean += const[C_ALPHA] * (vx - v_mean)
    state[S_V_MEAN] = v_mean
    z = qpos[index[I_PZ]]
    z_mean = state[S_Z_MEAN] + const[C_ALPHA] * (z - state[S_Z_MEAN])
    state[S_Z_MEAN] = z_mean

    # --- swing legs: foot placement and toe-clearance reflex ------------------------------------
    for s in range(2):
        if state[S_SWING + s] < 0.5:
            continue
        v_level = const[C_SPEED_ADAPT] * v_mean + (1.0 - const[C_SPEED_ADAPT]) * const[C_V_REF]
        ahead = (_row(table, table_step, i1, f1, _AHEAD_RATE) if s == 0
                 else _row(table, table_step, i0, f0, _AHEAD_RATE))
        v_target = v_level * ahead * const[C_AHEAD_NORM]
        ctrl[index[I_PD + 3 * s]] += const[C_CV] * (vx - v_target)
        ph = state[S_PHASE + s]
        if const[C_CLEAR_GAIN] != 0.0 and 0.6 < ph < 0.9:
            deficit = const[C_CLEAR_M] - (geom_xpos[index[I_BALL + s], 2] - const[C_RADIUS])
            if deficit > 0.0:
                ctrl[index[I_PD + 3 * s + 1]] += const[C_CLEAR_GAIN] * deficit
                ctrl[index[I_PD + 3 * s]] += 0.5 * const[C_CLEAR_GAIN] * deficit

    # --- stance legs: trunk through the stance hip(s), by load share ----------------------------
    st0 = state[S_SWING] < 0.5
    st1 = state[S_SWING + 1] < 0.5
    if st0 or st1:
        l0 = load0 if st0 else 0.0
        l1 = load1 if st1 else 0.0
        total = l0 + l1
        if total > 0.0:
            share0 = l0 / total
            share1 = l1 / total
        else:
            n_st = (1.0 if st0 else 0.0) + (1.0 if st1 else 0.0)
            share0 = (1.0 if st0 else 0.0) / n_st
            share1 = (1.0 if st1 else 0.0) / n_st
        tau_trunk = -const[C_TRUNK_KP] * tilt - const[C_TRUNK_KD] * tilt_rate
        a = const[C_TRACK]
        for s in range(2):
            if state[S_SWING + s] > 0.5:
                continue
            if a < 1.0:
                upright = (qpos[index[I_HIP_Q + s]] - tilt
                           + const[C_LEAD_HIP] * (qvel[index[I_HIP_V + s]] - tilt_rate))
                ctrl[index[I_PD + 3 * s]] = a * ctrl[index[I_PD + 3 * s]] + (1.0 - a) * upright
                ctrl[index[I_FF + 3 * s]] *= a
            ctrl[index[I_FF + 3 * s]] += (share0 if s == 0 else share1) * tau_trunk

    g = 1.0 + const[C_EXTRA_GAIN] * max(0.0, 1.0 - t / const[C_WARMUP_S])
    ctrl[index[I_RES_X]] = -const[C_RES_TX] * g * (vx - v_mean)
    ctrl[index[I_RES_Z]] = (-const[C_RES_TZ] * g * (z - z_mean)
                            - const[C_RES_TZD] * g * qvel[index[I_DPZ]])
    ctrl[index[I_RES_T]] = -const[C_RES_TK] * g * tilt - const[C_RES_TKD] * g * tilt_rate
    # Plantarflexor capacity falls with shortening speed (Hill's hyperbola at joint level, see
    # afo_mj.human.walker.hill_concentric_fraction): the ankle's net torque limit follows it.
    for s in range(2):
        w = -qvel[index[I_ANKLE_V + s]] / const[C_PF_W_MAX]
        w = 0.0 if w < 0.0 else (1.0 if w > 1.0 else w)
        actfrcrange[index[I_ANKLE_J + s], 0] = (const[C_PF_ISO + s] * (1.0 - w)
                                                / (1.0 + w / const[C_HILL_A]))
