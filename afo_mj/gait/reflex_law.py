"""The muscle-reflex walking controller's per-step law, compiled (numba).

Fourteen muscle–tendon units (seven per leg, :mod:`afo_mj.human.muscle`) driven by the reflex
controller of Geyer & Herr, "A muscle-reflex model that encodes principles of legged
mechanics produces human walking dynamics and muscle activities", IEEE TNSRE 18 (2010) 263
(their parameter set as the defaults, :data:`DEFAULTS`). Each step :func:`reflex_step`:

1. detects stance per leg from the foot's load (heel + ball touch sensors) with hysteresis
   (on above 5 % of body weight, off below 1 %, each phase lasting at least 50 ms), and
   records the event (stance onset = heel
   strike, 1; stance end = toe off, 2) and, at toe off, the trunk's lean;
2. stores the signals the reflexes read into a ring buffer (muscle forces and CE lengths,
   read back as force / F_max and length / l_opt, knee angle and velocity, leg load / body
   weight, trunk lean and its rate) and reads them back with the neural delays: 20 ms for
   the ankle muscles (SOL, GAS, TA), 10 ms for VAS, 5 ms for the hip muscles (HAM, GLU,
   HFL);
3. sets the stimulations (clipped to [0.01, 1]):
   stance — SOL, GAS: positive force feedback; TA: length feedback beyond ``l_off,TA``, less
   SOL force; VAS: force feedback less the knee-overextension term
   ``k_φ (φ_k − φ_off)`` (extending past φ_off); hip muscles: a PD law on the trunk's lean
   ``k_p (θ − θ_ref) + k_d θ̇`` scaled by the leg's load (GLU and HAM +, HFL −); in double
   support the trailing leg adds ``ΔS`` to HFL, takes it from GLU, and inhibits VAS by
   ``k_bw`` × the other leg's load;
   swing — HFL: ``k_lean (θ_TO − θ_ref)`` plus length feedback beyond ``l_off,HFL`` less
   HAM length beyond ``l_off,HAM``; HAM, GLU: force feedback; TA: length feedback; SOL, GAS:
   their pre-stimulation; VAS: ``s0_vasti_swing`` (Geyer & Herr: the floor, 0.01);
4. advances every activation (exact first-order step) and CE length (backward Euler,
   :func:`afo_mj.human.muscle.mtu_step`) and takes the tendon force;
5. sums the joint torques ``s r(φ) F`` of every path, adds Geyer's soft joint limits (knee
   beyond 5° of hyperextension, ankle outside −40…+20°: ``τ = k Δφ (1 − φ̇_in/v)``,
   0.3 N·m/deg, damped toward a ``v`` = 1°/s penetration speed) and writes them to the joint
   torque motors. The limit's damping ``c = k Δφ/v`` grows with the penetration; applied
   explicitly it made the swinging foot (~0.01 kg m² about the ankle) unstable at a 1 ms
   step beyond ~1° (``c h/I > 2``). So the motor takes the spring part ``k Δφ`` and the
   damping goes to MuJoCo as joint damping (``X_LIMIT_DAMP``), which its implicit integrator
   applies at the step's end velocity: ``τ = k Δφ − c φ̇_{n+1}`` (Geyer's law with the
   velocity of the step's end; the clip of ``1 − φ̇_in/v`` at zero, a limit that only
   pushes, is decided at the step's start);
6. computes each muscle's metabolic rate by Umberger (2010) and Bhargava et al. (2004)
   (:mod:`afo_mj.human.metabolics`).

Layouts: muscle table ``T`` (:func:`muscle_table`), parameters ``P`` (:data:`PARAM_NAMES`),
state ``X`` (the ``X_*`` offsets), ring buffer ``ring`` (``RING_LEN`` × ``RING_COLS``).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np

from afo_mj.human import metabolics as me
from afo_mj.human import muscle as mu
from afo_mj.numba_cache import declare_module_dependencies

#: muscle order per leg; index ``side * 7 + m``
MUSCLES = ("soleus", "gastrocnemius", "tibialis_anterior", "vasti", "hamstrings", "gluteals",
           "hip_flexors")
SOL, GAS, TA, VAS, HAM, GLU, HFL = range(7)
N_MUSCLES = 7
#: neural delays per muscle (ms): ankle 20, knee 10, hip 5 (Geyer & Herr 2010)
DELAY_MS = (20, 20, 20, 10, 5, 5, 5)
#: joint index of the walker's (hip, knee, ankle) order
JOINT_INDEX = {"hip": 0, "knee": 1, "ankle": 2}

# muscle table columns: F_max, v_max, l_opt, l_slack, delay (steps), paths, then per path
# (joint, sign, r0, φ_max, φ_ref, ρ, constant arm, cos φ_max, sin φ_max, sin(φ_ref − φ_max)),
# then mass, slow-twitch fraction
T_FMAX, T_VMAX, T_LOPT, T_LSLACK, T_DELAY, T_NPATH, T_PATH = range(7)
PATH_W = 10
T_MASS = T_PATH + 2 * PATH_W
T_SLOW = T_MASS + 1
T_COLS = T_SLOW + 1

#: the controller's parameters, in ``P`` order, with Geyer & Herr's (2010) values
DEFAULTS = {
    "s0_soleus": 0.01, "g_soleus": 1.2, "s0_tibialis": 0.01, "g_tibialis": 1.1,
    "loff_tibialis": 1.0 - 0.5 * mu.W_WIDTH, "g_soleus_tibialis": 0.4,
    "s0_gastrocnemius": 0.01, "g_gastrocnemius": 1.1, "s0_vasti": 0.08, "g_vasti": 1.2,
    "k_knee_overextension": 2.0, "knee_overextension_rad": math.radians(170.0),
    "s0_stance_hip": 0.05, "kp_trunk_per_rad": 1.0 / math.radians(30.0),
    "kd_trunk_s_per_rad": 0.2, "trunk_lean_ref_rad": math.radians(6.0),
    "swing_initiation": 0.25, "k_bodyweight_vasti": 1.0, "s0_hip_flexors": 0.01,
    "k_lean": 2.0 / 100.0 * 180.0 / math.pi, "g_hip_flexors": 0.5, "loff_hip_flexors": 0.65,
    "g_hamstrings_hip_flexors": 4.0, "loff_hamstrings": 0.85, "s0_hamstrings": 0.01,
    "g_hamstrings": 0.65, "s0_gluteals": 0.01, "g_gluteals": 0.5,
    # the vasti's stimulation in swing: Geyer & Herr's VAS pre-stimulation is a stance term
    # (so in Geijtenbeek's rendition of the controller in SCONE), leaving the swing vasti at
    # the floor; the sets shipped before it was a parameter held s0_vasti through swing, and
    # carry that value
    "s0_vasti_swing": 0.01,
}
PARAM_NAMES = tuple(DEFAULTS)
N_P = len(PARAM_NAMES)
(P_S0_SOL, P_G_SOL, P_S0_TA, P_G_TA, P_LOFF_TA, P_G_SOLTA, P_S0_GAS, P_G_GAS, P_S0_VAS,
 P_G_VAS, P_K_PHI, P_PHI_OFF, P_S0_GG, P_KP, P_KD, P_THETA_REF, P_DS, P_K_BW, P_S0_HFL,
 P_K_LEAN, P_G_HFL, P_LOFF_HFL, P_G_HAMHFL, P_LOFF_HAM, P_S0_HAM, P_G_HAM, P_S0_GLU,
 P_G_GLU, P_S0_VAS_SWING) = range(N_P)

# state X offsets (14 = 2 legs × 7 muscles)
X_ACT, X_LCE, X_F, X_U, X_VCE = 0, 14, 28, 42, 56
X_EDOT_U, X_EDOT_B, X_TAU = 70, 84, 98                     # X_TAU: 2 × 3
X_STANCE, X_TOUCHDOWN_T, X_THETA_TO, X_EVENT, X_SWITCH_T = 104, 106, 108, 110, 112
X_RING_POS = 114
X_LIMIT_DAMP = 115                                          # 2 × 3: soft-limit damping
#: the CE velocities of the two steps before the last (m/s, 14 each): with ``X_VCE`` they
#: extrapolate the next step's velocity, the start of the CE-length solve (it does not enter
#: the result)
X_VCE_PREV, X_VCE_PREV2 = 121, 135
#: the excitation whose fibre excitations (Bhargava et al. 2004: ``u_ST``, ``u_FT``,
#: :func:`afo_mj.human.metabolics.bhargava_fibre_excitations`) are held at ``X_FIBRE_ST``
#: and ``X_FIBRE_FT`` (14 each): while a muscle's excitation holds (at its floor or its
#: clip, about 40 % of a walk's muscle-steps) they are taken from there, the values
#: computed from it before (−1 at the start: none held)
X_FIBRE_U, X_FIBRE_ST, X_FIBRE_FT = 149, 163, 177
N_X = 191
#: ring buffer: per leg 17 columns (force (N) ×7, l_CE (m) ×7, φ_k, φ̇_k, load/mg), then
#: trunk lean and its rate
RING_LEN = 64
RING_LEG = 17
RING_COLS = 2 * RING_LEG + 2
#: stance hysteresis (fraction of body weight) and the shortest stance or swing (s): a
#: foot that bounces at contact does not end its stance
STANCE_ON, STANCE_OFF = 0.05, 0.01
MIN_PHASE_S = 0.05
#: soft joint limits (Geyer's model): stiffness per rad, relaxation speed, knee and ankle
SOFT_LIMIT_NM_PER_RAD = 0.3 / math.radians(1.0)
SOFT_LIMIT_SPEED_RAD_S = math.radians(1.0)
KNEE_LIMIT_RAD = math.radians(5.0)
ANKLE_LIMITS_RAD = (math.radians(-40.0), math.radians(20.0))


def muscle_table(timestep_s: float) -> np.ndarray:
    """The compiled law's muscle table (7 × ``T_COLS``) from
    :data:`afo_mj.human.muscle.GEYER_HERR_2010`, delays in steps of ``timestep_s``."""
    T = np.zeros((N_MUSCLES, T_COLS))
    for m, name in enumerate(MUSCLES):
        p, paths = mu.GEYER_HERR_2010[name]
        T[m, :T_PATH] = [p.max_force_n, p.max_velocity_lopt_s, p.optimal_length_m,
                         p.slack_length_m, round(DELAY_MS[m] * 1e-3 / timestep_s), len(paths)]
        for k, jp in enumerate(paths):
            c = T_PATH + PATH_W * k
            pm = jp.phi_max_rad or 0.0
            T[m, c:c + PATH_W] = [JOINT_INDEX[jp.joint], jp.sign, jp.r0_m, pm,
                                  jp.phi_ref_rad, jp.rho, 1.0 if jp.phi_max_rad is None else 0.0,
                                  math.cos(pm), math.sin(pm), math.sin(jp.phi_ref_rad - pm)]
        T[m, T_MASS] = p.mass_kg
        T[m, T_SLOW] = p.slow_twitch_fraction
    if T[:, T_DELAY].max() >= RING_LEN:
        raise ValueError(f"timestep_s = {timestep_s!r}: the 20 ms delay needs "
                         f"{int(T[:, T_DELAY].max())} steps; allowed: >= {0.02 / (RING_LEN - 1)}")
    return T


@numba.njit(cache=True)
def geyer_angles(hip, knee, ankle):
    """Geyer's internal angles (φ_h, φ_k, φ_a) from the walker's (flexion, flexion,
    dorsiflexion) angles."""
    return math.pi - hip, math.pi - knee, 0.5 * math.pi - ankle


@numba.njit(cache=True, inline="always")
def mtu_length_and_arms_sc(T, m, phi_h, sin_k, cos_k, sin_a, cos_a):
    """:func:`mtu_length_and_arms` from ``sin φ`` and ``cos φ`` of the knee and ankle (a
    leg's four sines and cosines serve all its muscles): ``sin(φ − φ_max) = sin φ cos φ_max −
    cos φ sin φ_max`` and ``cos(φ − φ_max) = cos φ cos φ_max + sin φ sin φ_max``, with the
    path's ``cos φ_max``, ``sin φ_max`` and ``sin(φ_ref − φ_max)`` from the table; then
    ``Δl = s ρ r_0 [sin(φ − φ_max) − sin(φ_ref − φ_max)]`` and ``r = r_0 cos(φ − φ_max)``,
    at the hip ``Δl = s ρ r_0 (φ − φ_ref)`` and ``r = r_0`` (Geyer & Herr 2010, section
    II-B; :func:`afo_mj.human.muscle.path_length_and_arm`)."""
    lm = T[m, T_LOPT] + T[m, T_LSLACK]
    r0 = 0.0
    r1 = 0.0
    for q in range(int(T[m, T_NPATH])):
        c = T_PATH + PATH_W * q
        j = int(T[m, c])
        sr = T[m, c + 1] * T[m, c + 5] * T[m, c + 2]         # s ρ r_0
        if T[m, c + 6] > 0.5:
            dl = sr * (phi_h - T[m, c + 4])
            r = T[m, c + 2]
        else:
            sp = sin_k if j == 1 else sin_a
            cp = cos_k if j == 1 else cos_a
            dl = sr * ((sp * T[m, c + 7] - cp * T[m, c + 8]) - T[m, c + 9])
            r = T[m, c + 2] * (cp * T[m, c + 7] + sp * T[m, c + 8])
        lm += dl
        if q == 0:
            r0 = r
        else:
            r1 = r
    return lm, r0, r1


@numba.njit(cache=True)
def mtu_length_and_arms(T, m, phi_h, phi_k, phi_a):
    """MTU length of muscle ``m`` at Geyer's angles and the moment arms of its (up to two)
    paths (Geyer & Herr 2010, section II-B): ``(l_MTU, r_0, r_1)``
    (:func:`mtu_length_and_arms_sc`)."""
    return mtu_length_and_arms_sc(T, m, phi_h, math.sin(phi_k), math.cos(phi_k),
                                  math.sin(phi_a), math.cos(phi_a))


@numba.njit(cache=True, inline="always")
def _delayed_force(ring, T, pos, b, m):
    """Muscle ``m``'s force / F_max (leg columns from ``b``) as it was its neural delay ago
    (normalised as it is read: only the few the reflexes read)."""
    return ring[(pos - int(T[m, T_DELAY])) % RING_LEN, b + m] / T[m, T_FMAX]


@numba.njit(cache=True, inline="always")
def _delayed_length(ring, T, pos, b, m):
    """Muscle ``m``'s CE length / l_opt (leg columns from ``b``) its neural delay ago."""
    return ring[(pos - int(T[m, T_DELAY])) % RING_LEN, b + N_MUSCLES + m] / T[m, T_LOPT]


@numba.njit(cache=True)
def reflex_step(t, h, qpos, qvel, sens, leg_q, leg_v, touch, pelvis_tilt_q, pelvis_tilt_v,
                P, T, X, ring, mg):  # pragma: no cover - compiled; exercised by the tests
    """One control step at time ``t`` (step ``h``): reads MuJoCo's state, advances the
    muscles, leaves the joint torques (N·m, walker sign, ``X[X_TAU:X_TAU+6]`` as [side][hip,
    knee, ankle]), the soft limits' joint damping (N·m·s/rad, ``X[X_LIMIT_DAMP:+6]``, same
    layout: the caller adds it to MuJoCo's ``dof_damping``), the events, and the metabolic
    rates in ``X``."""
    pos = int(X[X_RING_POS])
    theta = qpos[pelvis_tilt_q]
    omega = qvel[pelvis_tilt_v]
    # --- stance detection with hysteresis, events ------------------------------------------
    for s in range(2):
        load = sens[touch[s, 0]] + sens[touch[s, 1]]
        was = X[X_STANCE + s] > 0.5
        st = load > (STANCE_OFF * mg if was else STANCE_ON * mg)
        if st != was and t - X[X_SWITCH_T + s] < MIN_PHASE_S:
            st = was
        X[X_EVENT + s] = 0.0
        if st != was:
            X[X_SWITCH_T + s] = t
        if st and not was:
            X[X_TOUCHDOWN_T + s] = t
            X[X_EVENT + s] = 1.0
        elif was and not st:
            X[X_THETA_TO + s] = theta
            X[X_EVENT + s] = 2.0
        X[X_STANCE + s] = 1.0 if st else 0.0
    # --- the present signals into the ring -------------------------------------------------
    w = pos % RING_LEN
    for s in range(2):
        b = s * RING_LEG
        for m in range(N_MUSCLES):
            ring[w, b + m] = X[X_F + s * N_MUSCLES + m]
            ring[w, b + N_MUSCLES + m] = X[X_LCE + s * N_MUSCLES + m]
        ring[w, b + 14] = math.pi - qpos[leg_q[s, 1]]
        ring[w, b + 15] = -qvel[leg_v[s, 1]]
        ring[w, b + 16] = (sens[touch[s, 0]] + sens[touch[s, 1]]) / mg
    ring[w, 2 * RING_LEG] = theta
    ring[w, 2 * RING_LEG + 1] = omega
    X[X_RING_POS] = pos + 1
    d_knee = int(T[VAS, T_DELAY])
    d_hip = int(T[HFL, T_DELAY])
    # --- stimulations ----------------------------------------------------------------------
    # (the stimulations S go to X[X_U:] unclipped; the muscles' loop clips them to u)
    for s in range(2):
        o = 1 - s
        b = s * RING_LEG
        S = X_U + s * N_MUSCLES
        if X[X_STANCE + s] > 0.5:
            f_sol = _delayed_force(ring, T, pos, b, SOL)
            X[S + SOL] = P[P_S0_SOL] + P[P_G_SOL] * f_sol
            X[S + TA] = (P[P_S0_TA]
                         + P[P_G_TA] * max(_delayed_length(ring, T, pos, b, TA) - P[P_LOFF_TA], 0.0)
                         - P[P_G_SOLTA] * f_sol)
            X[S + GAS] = P[P_S0_GAS] + P[P_G_GAS] * _delayed_force(ring, T, pos, b, GAS)
            rk = (pos - d_knee) % RING_LEN
            phik = ring[rk, b + 14]
            dphi = phik - P[P_PHI_OFF] if (phik > P[P_PHI_OFF] and ring[rk, b + 15] > 0.0) \
                else 0.0
            X[S + VAS] = (P[P_S0_VAS] + P[P_G_VAS] * _delayed_force(ring, T, pos, b, VAS)
                          - P[P_K_PHI] * dphi)
            rh = (pos - d_hip) % RING_LEN
            load = min(max(ring[rh, b + 16], 0.0), 1.0)
            pd = (P[P_KP] * (ring[rh, 2 * RING_LEG] - P[P_THETA_REF])
                  + P[P_KD] * ring[rh, 2 * RING_LEG + 1])
            X[S + GLU] = P[P_S0_GG] + pd * load
            X[S + HAM] = P[P_S0_GG] + pd * load
            X[S + HFL] = P[P_S0_GG] - pd * load
            if X[X_STANCE + o] > 0.5 and X[X_TOUCHDOWN_T + o] > X[X_TOUCHDOWN_T + s]:
                # double support, this leg trailing: prepare its swing
                X[S + HFL] += P[P_DS]
                X[S + GLU] -= P[P_DS]
                X[S + VAS] -= P[P_K_BW] * min(max(ring[rk, o * RING_LEG + 16], 0.0), 1.0)
        else:
            X[S + SOL] = P[P_S0_SOL]
            X[S + GAS] = P[P_S0_GAS]
            X[S + VAS] = P[P_S0_VAS_SWING]
            X[S + TA] = P[P_S0_TA] + P[P_G_TA] * max(_delayed_length(ring, T, pos, b, TA)
                                                     - P[P_LOFF_TA], 0.0)
            X[S + HFL] = (P[P_S0_HFL] + P[P_K_LEAN] * (X[X_THETA_TO + s] - P[P_THETA_REF])
                          + P[P_G_HFL] * max(_delayed_length(ring, T, pos, b, HFL)
                                             - P[P_LOFF_HFL], 0.0)
                          - P[P_G_HAMHFL] * max(_delayed_length(ring, T, pos, b, HAM)
                                                - P[P_LOFF_HAM], 0.0))
            X[S + HAM] = P[P_S0_HAM] + P[P_G_HAM] * _delayed_force(ring, T, pos, b, HAM)
            X[S + GLU] = P[P_S0_GLU] + P[P_G_GLU] * _delayed_force(ring, T, pos, b, GLU)
    # --- muscles: each muscle's left and right solved together (mu.mtu_step_pair) ---------
    ph0, sk0, ck0, sa0, ca0 = _leg_trig(qpos, leg_q, 0)
    ph1, sk1, ck1, sa1, ca1 = _leg_trig(qpos, leg_q, 1)
    for j in range(6):
        X[X_TAU + j] = 0.0
    for m in range(0, N_MUSCLES - 1, 2):
        # two muscles (four solves) at a time; the last, HFL, with SOL..GLU's pairs done
        n = m + 1
        a0, lm0, ra0, rb0 = _muscle_inputs(X, T, m, 0, h, ph0, sk0, ck0, sa0, ca0)
        a1, lm1, ra1, rb1 = _muscle_inputs(X, T, m, 1, h, ph1, sk1, ck1, sa1, ca1)
        a2, lm2, ra2, rb2 = _muscle_inputs(X, T, n, 0, h, ph0, sk0, ck0, sa0, ca0)
        a3, lm3, ra3, rb3 = _muscle_inputs(X, T, n, 1, h, ph1, sk1, ck1, sa1, ca1)
        lce0, lce1, lce2, lce3 = mu.mtu_step_quad(
            X[X_LCE + m], a0, lm0, _velocity_guess(X, m),
            X[X_LCE + N_MUSCLES + m], a1, lm1, _velocity_guess(X, N_MUSCLES + m),
            T[m, T_VMAX], T[m, T_LOPT], T[m, T_LSLACK],
            X[X_LCE + n], a2, lm2, _velocity_guess(X, n),
            X[X_LCE + N_MUSCLES + n], a3, lm3, _velocity_guess(X, N_MUSCLES + n),
            T[n, T_VMAX], T[n, T_LOPT], T[n, T_LSLACK], h)
        _muscle_outputs(X, T, m, 0, h, a0, lm0, ra0, rb0, lce0)
        _muscle_outputs(X, T, m, 1, h, a1, lm1, ra1, rb1, lce1)
        _muscle_outputs(X, T, n, 0, h, a2, lm2, ra2, rb2, lce2)
        _muscle_outputs(X, T, n, 1, h, a3, lm3, ra3, rb3, lce3)
    m = N_MUSCLES - 1
    a0, lm0, ra0, rb0 = _muscle_inputs(X, T, m, 0, h, ph0, sk0, ck0, sa0, ca0)
    a1, lm1, ra1, rb1 = _muscle_inputs(X, T, m, 1, h, ph1, sk1, ck1, sa1, ca1)
    lce0, lce1 = mu.mtu_step_pair(
        X[X_LCE + m], a0, lm0, _velocity_guess(X, m),
        X[X_LCE + N_MUSCLES + m], a1, lm1, _velocity_guess(X, N_MUSCLES + m),
        h, T[m, T_FMAX], T[m, T_VMAX], T[m, T_LOPT], T[m, T_LSLACK])
    _muscle_outputs(X, T, m, 0, h, a0, lm0, ra0, rb0, lce0)
    _muscle_outputs(X, T, m, 1, h, a1, lm1, ra1, rb1, lce1)
    # --- soft joint limits (Geyer's model; damping implicit, step 5 above) ---------------
    for s in range(2):
        c_knee = 0.0
        c_ankle = 0.0
        thk = qpos[leg_q[s, 1]]
        if thk < KNEE_LIMIT_RAD and qvel[leg_v[s, 1]] < SOFT_LIMIT_SPEED_RAD_S:
            pen = KNEE_LIMIT_RAD - thk
            X[X_TAU + 3 * s + 1] += SOFT_LIMIT_NM_PER_RAD * pen
            c_knee = SOFT_LIMIT_NM_PER_RAD * pen / SOFT_LIMIT_SPEED_RAD_S
        tha = qpos[leg_q[s, 2]]
        wa = qvel[leg_v[s, 2]]
        if tha > ANKLE_LIMITS_RAD[1] and wa > -SOFT_LIMIT_SPEED_RAD_S:
            pen = tha - ANKLE_LIMITS_RAD[1]
            X[X_TAU + 3 * s + 2] -= SOFT_LIMIT_NM_PER_RAD * pen
            c_ankle = SOFT_LIMIT_NM_PER_RAD * pen / SOFT_LIMIT_SPEED_RAD_S
        elif tha < ANKLE_LIMITS_RAD[0] and wa < SOFT_LIMIT_SPEED_RAD_S:
            pen = ANKLE_LIMITS_RAD[0] - tha
            X[X_TAU + 3 * s + 2] += SOFT_LIMIT_NM_PER_RAD * pen
            c_ankle = SOFT_LIMIT_NM_PER_RAD * pen / SOFT_LIMIT_SPEED_RAD_S
        X[X_LIMIT_DAMP + 3 * s] = 0.0
        X[X_LIMIT_DAMP + 3 * s + 1] = c_knee
        X[X_LIMIT_DAMP + 3 * s + 2] = c_ankle


@numba.njit(cache=True, inline="always")
def _velocity_guess(X, k):
    """Muscle ``k``'s CE velocity over the coming step extrapolated by the quadratic through
    the last three, ``3 v_n − 3 v_{n−1} + v_{n−2}`` (the start of its solve)."""
    return 3.0 * (X[X_VCE + k] - X[X_VCE_PREV + k]) + X[X_VCE_PREV2 + k]


@numba.njit(cache=True, inline="always")
def _leg_trig(qpos, leg_q, s):
    """Leg ``s``'s hip angle φ_h and the sines and cosines of its knee and ankle angles
    (Geyer's internal angles, :func:`geyer_angles`)."""
    phi_h, phi_k, phi_a = geyer_angles(qpos[leg_q[s, 0]], qpos[leg_q[s, 1]], qpos[leg_q[s, 2]])
    return phi_h, math.sin(phi_k), math.cos(phi_k), math.sin(phi_a), math.cos(phi_a)


@numba.njit(cache=True, inline="always")
def _muscle_inputs(X, T, m, s, h, phi_h, sin_k, cos_k, sin_a, cos_a):
    """Muscle ``m`` of leg ``s`` before its solve: the stimulation ``X[X_U]`` clipped to the
    excitation ``u`` (written back), the activation advanced (``τ ȧ = u − a``, exact step),
    the MTU length and moment arms: ``(a, l_MTU, r_0, r_1)``."""
    k = s * N_MUSCLES + m
    u = min(max(X[X_U + k], mu.PREACTIVATION), 1.0)
    X[X_U + k] = u
    a = mu.activation_step(X[X_ACT + k], u, h, mu.TAU_ACTIVATION_S)
    lm, r0, r1 = mtu_length_and_arms_sc(T, m, phi_h, sin_k, cos_k, sin_a, cos_a)
    return a, lm, r0, r1


@numba.njit(cache=True, inline="always")
def _muscle_outputs(X, T, m, s, h, a, lm, r0, r1, lce):
    """Muscle ``m`` of leg ``s`` after its solve (new CE length ``lce``): the state
    (activation, CE length, tendon force, CE velocity and the one before), the metabolic
    rates (Umberger 2010, Bhargava et al. 2004) and its paths' torques ``s r F`` added to
    the leg's ``X[X_TAU]``."""
    k = s * N_MUSCLES + m
    fmax = T[m, T_FMAX]
    lopt = T[m, T_LOPT]
    u = X[X_U + k]
    lce_old = X[X_LCE + k]
    f_se = mu.se_force_n(lm - lce, T[m, T_LSLACK], fmax)
    v = (lce - lce_old) / h
    X[X_ACT + k] = a
    X[X_LCE + k] = lce
    X[X_F + k] = f_se
    X[X_VCE_PREV2 + k] = X[X_VCE_PREV + k]
    X[X_VCE_PREV + k] = X[X_VCE + k]
    X[X_VCE + k] = v
    # metabolic rates
    fl = mu.ce_force_length(lce, lopt)
    fv = mu.ce_force_velocity(v / lopt, T[m, T_VMAX])
    f_act = a * fmax * fl * fv
    f_fib = f_act + mu.pe_force_n(lce, lopt, fmax)
    X[X_EDOT_U + k] = me.umberger2010_rate_w(u, a, lce / lopt, v / lopt, f_act, fl,
                                             T[m, T_VMAX], lopt, T[m, T_MASS],
                                             T[m, T_SLOW])[0]
    if u != X[X_FIBRE_U + k]:
        u_st, u_ft = me.bhargava_fibre_excitations(u, T[m, T_SLOW])
        X[X_FIBRE_U + k] = u
        X[X_FIBRE_ST + k] = u_st
        X[X_FIBRE_FT + k] = u_ft
    X[X_EDOT_B + k] = me.bhargava2004_rate_from_fibres_w(
        X[X_FIBRE_ST + k], X[X_FIBRE_FT + k], lce / lopt, v, f_fib, f_act, T[m, T_MASS])[0]
    for q in range(int(T[m, T_NPATH])):
        c = T_PATH + PATH_W * q
        j = int(T[m, c])
        X[X_TAU + 3 * s + j] += T[m, c + 1] * (r0 if q == 0 else r1) * f_se


def initial_state(T: np.ndarray, leg_angles_rad: np.ndarray, stance: tuple[bool, bool],
                  touchdown_s: tuple[float, float] = (0.0, -0.5),
                  trunk_lean_rad: float = 0.0) -> np.ndarray:
    """``X`` at the start: pre-activation, every CE at its static balance with the tendon at
    the initial joint angles (``leg_angles_rad`` (2, 3) [side][hip, knee, ankle]), the
    stance flags and touchdown times, the trunk lean as the lean at the last toe off."""
    X = np.zeros(N_X)
    X[X_ACT:X_ACT + 14] = mu.PREACTIVATION
    X[X_U:X_U + 14] = mu.PREACTIVATION
    X[X_FIBRE_U:X_FIBRE_U + 14] = -1.0
    for s in range(2):
        ph, pk, pa = geyer_angles(*[float(v) for v in leg_angles_rad[s]])
        for m, name in enumerate(MUSCLES):
            lm = mtu_length_and_arms(T, m, ph, pk, pa)[0]
            # the table's muscle (scaled by body size or strength) balanced at rest
            p = dataclasses.replace(mu.GEYER_HERR_2010[name][0], max_force_n=T[m, T_FMAX],
                                    optimal_length_m=T[m, T_LOPT],
                                    slack_length_m=T[m, T_LSLACK])
            X[X_LCE + s * N_MUSCLES + m] = mu.equilibrium_ce_length_m(
                mu.PREACTIVATION, lm, p)
        X[X_STANCE + s] = 1.0 if stance[s] else 0.0
        X[X_TOUCHDOWN_T + s] = touchdown_s[s]
        X[X_SWITCH_T + s] = -1.0
        X[X_THETA_TO + s] = trunk_lean_rad
    return X


# the law's cached functions call the muscle and metabolic modules' compiled functions: their
# caches follow those sources too (afo_mj.numba_cache)
declare_module_dependencies(__name__)
