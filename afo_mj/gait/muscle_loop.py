"""The muscle-driven walk's per-step loop in compiled code: the reflex law, gait events, soft
limits, a coupled device, ``mj_step``, recording and the checks, with no Python per step.

:func:`muscle_walk_steps` runs steps ``k … k_end − 1`` of a walk of
:class:`afo_mj.gait.muscle_walk.MuscleWalkStepper` (or stops earlier) and returns why it
stopped; the stepper calls it for the whole walk (:func:`~afo_mj.gait.muscle_walk.run_muscle_walk`)
or for one step (``step()`` with no action) and turns its buffers into a
:class:`~afo_mj.gait.muscle_walk.MuscleWalk`. It is the stepper's Python step, step for step —
the same compiled law (:func:`afo_mj.gait.reflex_law.reflex_step`), MuJoCo's own C ``mj_step``
called through :func:`afo_mj.gait.native_step.call_mj_step`, a coupled device through its C
entry points (:mod:`afo_mj.circuits.native_entry`, called as
:mod:`afo_mj.gait.walk_loop` calls them), the same sums in the same order — so its walks
equal the Python loop's bit for bit (``tests/test_muscle_loop.py``). A device whose torque is
a Python callable, or an external action torque, needs the Python step.

Per step (``t`` the time MuJoCo holds):

1. ``reflex_step``: stance detection, the delayed reflexes, the muscles, the joint torques,
   the soft limits' damping and the metabolic rates into the state ``X``; its event codes
   (heel strike 1, toe off 2, per side) go with ``t`` to the event buffers;
2. the six joint torques to the torque motors' ``ctrl``;
3. the soft limits' damping (Geyer & Herr 2010; :mod:`afo_mj.gait.reflex_law`, step 5),
   integrated implicitly by MuJoCo: the knees' and ankles' ``dof_damping`` = base + the
   limit's, written while a limit is engaged or was the step before (then back to the base);
4. with a coupled device (``loop_index[LI_DEV_BEGIN] != 0``), its ``begin`` entry point gets
   the ankle angles, velocities and stance flags (the reflex controller's); its joint force
   goes to ``qfrc_applied`` and its extra damping onto the ankles'
   (``base + limit + device``, implicit in MuJoCo: the end-of-step torque is
   ``force − D q̇_{n+1}``);
5. ``mj_step``; a time that went back (MuJoCo met a huge or non-finite acceleration or
   control and reset its state) stops the loop (:data:`DIVERGED`, with ``t`` in
   ``loop_const[L_T]``);
6. with a device, its ``end`` entry point gets the new ankle velocities and leaves the
   delivered torque (code 0, a non-finite device state, stops the loop:
   :data:`DEVICE_NON_FINITE`);
7. row ``k`` of the buffers: time, ``qpos``, ``qvel``, sensors, contact heights, the device's
   torque, per muscle excitation, activation, force, CE velocity and the two metabolic rates,
   and the joint moments (motor torque, less the limits' damping at the step's end velocity
   while a limit is engaged);
8. a non-finite ``qpos`` or ``X`` stops the loop (:data:`NON_FINITE`); a hip below the fall
   height or a trunk pitched past the fall tilt stops it (:data:`FELL`).

Codes returned: :data:`CHUNK_DONE` (reached ``k_end``), :data:`FELL`, :data:`NON_FINITE`,
:data:`DIVERGED`, :data:`DEVICE_NON_FINITE`.
"""

from __future__ import annotations

import math


from afo_mj.gait import reflex_law as rl
from afo_mj.gait.native_step import call_mj_step
from afo_mj.gait.walk_loop import _call_begin, _call_end
from afo_mj.numba_cache import cached_njit, declare_module_dependencies

__all__ = ["CHUNK_DONE", "FELL", "NON_FINITE", "DIVERGED", "DEVICE_NON_FINITE",
           "muscle_walk_steps",
           "L_H", "L_MG", "L_FALL_Z", "L_FALL_TILT", "L_BASE_DAMP_R", "L_BASE_DAMP_L",
           "L_DEV_DT", "L_DEV_LAST_T", "L_T", "N_LOOP_CONST",
           "LI_PZ", "LI_PT_Q", "LI_PT_V", "LI_FN", "LI_MODEL", "LI_DATA", "LI_N_EVENTS",
           "LI_LIM_WAS", "LI_DEV_BEGIN", "LI_DEV_END", "LI_P_IO", "LI_P_BUF", "LI_P_META",
           "LI_P_LOG", "LI_LOG_N", "LI_LOG_F", "LI_LOG_S", "LI_DEV_STEPS", "LI_ANK_R",
           "LI_ANK_L", "LI_DANK_R", "LI_DANK_L", "N_LOOP_INDEX"]

CHUNK_DONE, FELL, NON_FINITE, DIVERGED, DEVICE_NON_FINITE = 0, 1, 2, 3, 4

# loop constants (float64): the step, the body weight (N), the fall height and tilt; device:
# the ankles' base damping, the device step; written by the loop: the time the device's last
# step began and the time the last step began
(L_H, L_MG, L_FALL_Z, L_FALL_TILT, L_BASE_DAMP_R, L_BASE_DAMP_L, L_DEV_DT, L_DEV_LAST_T, L_T,
 N_LOOP_CONST) = range(10)
# loop integers (int64): the pelvis height and tilt addresses, the native step's addresses,
# two values the loop updates (events recorded; a soft limit engaged in the last step, 0/1);
# device: entry points (0: none), addresses of its in/out block (``dev_io``: angle ×2,
# velocity ×2, stance ×2), buffer, layout and log, the log's shape, the device's step counter
# (updated), the ankles' qpos and dof addresses
(LI_PZ, LI_PT_Q, LI_PT_V, LI_FN, LI_MODEL, LI_DATA, LI_N_EVENTS, LI_LIM_WAS, LI_DEV_BEGIN,
 LI_DEV_END, LI_P_IO, LI_P_BUF, LI_P_META, LI_P_LOG, LI_LOG_N, LI_LOG_F, LI_LOG_S,
 LI_DEV_STEPS, LI_ANK_R, LI_ANK_L, LI_DANK_R, LI_DANK_L, N_LOOP_INDEX) = range(23)


# the reflex law's cached functions call afo_mj.human.muscle and .metabolics: their caches follow
# those files too, so that this loop, recompiled, never links a stale law (belongs in reflex_law)
declare_module_dependencies(rl)


# cached on disk with the sources of the reflex law (and its muscles and metabolics), the native
# step and walk_loop's device intrinsics it compiles in (afo_mj.numba_cache)
@cached_njit(depends_on=(rl, "afo_mj.gait.walk_loop", "afo_mj.gait.native_step"),
             fastmath=False, _nrt=False)
def muscle_walk_steps(k, k_end, time1, qpos, qvel, sens, gxpos, ctrl, qfrc_applied,
                      dof_damping, P, T, X, ring, leg_q, leg_v, touch, ff, dlim, base_limit,
                      contact, b_time, b_qpos, b_qvel, b_sens, b_cz, b_dev, b_u, b_a, b_f, b_v,
                      b_eu, b_eb, b_tau, ev_time, ev_code, loop_const, loop_index, dev_io,
                      dev_force2, dev_damping2, dev_delivered2):  # pragma: no cover
    """Run steps ``k … k_end − 1``; returns ``(code, k)`` with ``k`` the rows recorded.

    ``time1``: one-element view of ``mjData.time``; ``qpos … dof_damping``: MuJoCo's live
    arrays; ``P, T, X, ring``: the reflex law's parameters, muscle table, state and ring
    buffer; ``leg_q``/``leg_v`` (2, 3), ``touch`` (2, 2), ``ff`` (2, 3): the legs' qpos and
    dof addresses, touch sensors and torque motors; ``dlim`` (2, 2): the knee and ankle dofs
    per side, ``base_limit`` (2, 2) their base damping; ``contact`` (4): the contact geoms;
    ``b_*``: the record buffers (rows ``k`` on); ``ev_time``/``ev_code`` (``(n, 2)``: side,
    code): event buffers filled from ``loop_index[LI_N_EVENTS]`` on; ``dev_io`` (6): the
    device's input block (its address is ``loop_index[LI_P_IO]``); ``dev_force2 …
    dev_delivered2``: views of the device buffer's outputs per walker side."""
    h = loop_const[L_H]
    mg = loop_const[L_MG]
    fall_z = loop_const[L_FALL_Z]
    fall_tilt = loop_const[L_FALL_TILT]
    pz = loop_index[LI_PZ]
    pt_q = loop_index[LI_PT_Q]
    pt_v = loop_index[LI_PT_V]
    fn = loop_index[LI_FN]
    m_addr = loop_index[LI_MODEL]
    d_addr = loop_index[LI_DATA]
    nq = qpos.shape[0]
    nv = qvel.shape[0]
    ns = sens.shape[0]
    nc = contact.shape[0]
    nx = X.shape[0]
    dev_begin = loop_index[LI_DEV_BEGIN]
    dev_end = loop_index[LI_DEV_END]
    p_io = loop_index[LI_P_IO]
    p_buf = loop_index[LI_P_BUF]
    p_meta = loop_index[LI_P_META]
    p_log = loop_index[LI_P_LOG]
    log_n = loop_index[LI_LOG_N]
    log_f = loop_index[LI_LOG_F]
    log_s = loop_index[LI_LOG_S]
    ank_r = loop_index[LI_ANK_R]
    ank_l = loop_index[LI_ANK_L]
    dank_r = loop_index[LI_DANK_R]
    dank_l = loop_index[LI_DANK_L]
    base_r = loop_const[L_BASE_DAMP_R]
    base_l = loop_const[L_BASE_DAMP_L]
    dev_dt = loop_const[L_DEV_DT]
    lim_was = loop_index[LI_LIM_WAS] != 0
    while k < k_end:
        t = time1[0]
        loop_const[L_T] = t
        rl.reflex_step(t, h, qpos, qvel, sens, leg_q, leg_v, touch, pt_q, pt_v, P, T, X, ring,
                       mg)
        for s in range(2):
            code = X[rl.X_EVENT + s]
            if code == 1.0 or code == 2.0:
                n = loop_index[LI_N_EVENTS]
                ev_time[n] = t
                ev_code[n, 0] = s
                ev_code[n, 1] = int(code)
                loop_index[LI_N_EVENTS] = n + 1
        for s in range(2):
            for j in range(3):
                ctrl[ff[s, j]] = X[rl.X_TAU + 3 * s + j]
        # the soft limits' damping (c_lim: X_LIMIT_DAMP's knee and ankle per side)
        lim_now = False
        for s in range(2):
            for j in range(2):
                if X[rl.X_LIMIT_DAMP + 3 * s + 1 + j] != 0.0:
                    lim_now = True
        if lim_now or lim_was:
            for s in range(2):
                for j in range(2):
                    dof_damping[dlim[s, j]] = (base_limit[s, j]
                                               + X[rl.X_LIMIT_DAMP + 3 * s + 1 + j])
        lim_was = lim_now
        loop_index[LI_LIM_WAS] = 1 if lim_now else 0
        if dev_begin != 0:
            dev_io[0] = qpos[ank_r]
            dev_io[1] = qpos[ank_l]
            dev_io[2] = qvel[dank_r]
            dev_io[3] = qvel[dank_l]
            dev_io[4] = 1.0 if X[rl.X_STANCE] > 0.5 else 0.0
            dev_io[5] = 1.0 if X[rl.X_STANCE + 1] > 0.5 else 0.0
            _call_begin(dev_begin, t, p_io, p_io + 16, p_io + 32, p_buf, p_meta)
            loop_const[L_DEV_LAST_T] = t
            qfrc_applied[dank_r] = dev_force2[0]
            qfrc_applied[dank_l] = dev_force2[1]
            dof_damping[dank_r] = base_r + X[rl.X_LIMIT_DAMP + 2] + dev_damping2[0]
            dof_damping[dank_l] = base_l + X[rl.X_LIMIT_DAMP + 5] + dev_damping2[1]
        call_mj_step(fn, m_addr, d_addr)
        if time1[0] < t:
            return DIVERGED, k
        if dev_end != 0:
            dev_io[2] = qvel[dank_r]
            dev_io[3] = qvel[dank_l]
            n_dev = loop_index[LI_DEV_STEPS]
            code_d = _call_end(dev_end, p_io + 16, p_buf, p_meta, p_log, log_n, log_f, log_s,
                               n_dev, t + dev_dt)
            loop_index[LI_DEV_STEPS] = n_dev + 1
            if code_d == 0:
                return DEVICE_NON_FINITE, k
            b_dev[k, 0] = dev_delivered2[0]
            b_dev[k, 1] = dev_delivered2[1]
        # --- record ---------------------------------------------------------------------
        b_time[k] = time1[0]
        for j in range(nq):
            b_qpos[k, j] = qpos[j]
        for j in range(nv):
            b_qvel[k, j] = qvel[j]
        for j in range(ns):
            b_sens[k, j] = sens[j]
        for j in range(nc):
            b_cz[k, j] = gxpos[contact[j], 2]
        for s in range(2):
            for m in range(7):
                i = 7 * s + m
                b_u[k, s, m] = X[rl.X_U + i]
                b_a[k, s, m] = X[rl.X_ACT + i]
                b_f[k, s, m] = X[rl.X_F + i]
                b_v[k, s, m] = X[rl.X_VCE + i]
                b_eu[k, s, m] = X[rl.X_EDOT_U + i]
                b_eb[k, s, m] = X[rl.X_EDOT_B + i]
        # the joint moment: the motors' and the limits' damping at the step's end velocity
        for s in range(2):
            b_tau[k, s, 0] = X[rl.X_TAU + 3 * s]
            for j in range(2):
                tq = X[rl.X_TAU + 3 * s + 1 + j]
                if lim_now:
                    tq = tq - X[rl.X_LIMIT_DAMP + 3 * s + 1 + j] * qvel[dlim[s, j]]
                b_tau[k, s, 1 + j] = tq
        k += 1
        finite = True
        for j in range(nq):
            if not math.isfinite(qpos[j]):
                finite = False
        for j in range(nx):
            if not math.isfinite(X[j]):
                finite = False
        if not finite:
            return NON_FINITE, k
        if qpos[pz] < fall_z or abs(qpos[pt_q]) > fall_tilt:
            return FELL, k
    return CHUNK_DONE, k
