"""The walk's per-step loop in compiled code: controller, gait events, ``mj_step``, recording
and the fall and finiteness checks, with no Python per step.

:func:`walk_steps` runs steps ``k … k_end − 1`` of a walk (or stops earlier) and returns why it
stopped; :func:`afo_mj.gait.walk.run_walk` calls it in chunks (one call per progress update,
or one for the whole walk) and turns its buffers into a
:class:`~afo_mj.gait.record.GaitRecord`. It is the loop of ``run_walk`` step for step — the
same compiled control law (:func:`afo_mj.gait.control_law.control_step`), MuJoCo's own C
``mj_step`` called through :func:`afo_mj.gait.native_step.call_mj_step`, the same copies in
the same order — so its records equal the Python loop's bit for bit
(``tests/test_walk_loop.py``).

Per step:

1. ``control_step`` at the time MuJoCo holds; its event codes (heel strike, toe off, swing
   contact) go to the event buffers; after a right heel strike that completes the requested
   strides the loop stops before stepping (:data:`STRIDES_DONE`);
2. ``mj_step``;
3. the raw state is copied into row ``k`` of the preallocated buffers;
4. a non-finite ``qpos``/``qvel`` stops the loop (:data:`NON_FINITE`); a hip below the fall
   height or a trunk pitched past the fall tilt stops it (:data:`FELL`).

Codes returned: :data:`CHUNK_DONE` (reached ``k_end``), :data:`STRIDES_DONE`,
:data:`FELL`, :data:`NON_FINITE`.
"""

from __future__ import annotations

import math

import numba

from afo_mj.gait import control_law as law
from afo_mj.gait.native_step import call_mj_step

__all__ = ["CHUNK_DONE", "STRIDES_DONE", "FELL", "NON_FINITE", "walk_steps",
           "EV_HEEL_STRIKE", "EV_TOE_OFF", "EV_SWING_CONTACT",
           "L_STRIDES", "L_FALL_DZ", "L_FALL_TILT", "N_LOOP_CONST",
           "LI_PZ", "LI_PT", "LI_FN", "LI_MODEL", "LI_DATA", "LI_N_EVENTS", "LI_RIGHT_STRIDES",
           "N_LOOP_INDEX"]

CHUNK_DONE, STRIDES_DONE, FELL, NON_FINITE = 0, 1, 2, 3
EV_HEEL_STRIKE, EV_TOE_OFF, EV_SWING_CONTACT = 1, 2, 3

# loop constants (float64)
L_STRIDES, L_FALL_DZ, L_FALL_TILT, N_LOOP_CONST = range(4)
# loop integers (int64): qpos addresses, the native step's addresses, and two counters the
# loop updates (events recorded, right heel strikes)
LI_PZ, LI_PT, LI_FN, LI_MODEL, LI_DATA, LI_N_EVENTS, LI_RIGHT_STRIDES, N_LOOP_INDEX = range(8)


@numba.njit(cache=True, fastmath=False)
def walk_steps(k, k_end, time1, qpos, qvel, sens, gxpos, state, table, table_step, const,
               index, ctrl, actfrc, qfrc_actuator, actuator_force, contact_geoms,
               b_time, b_qpos, b_qvel, b_qfrc, b_act, b_sens, b_cz, b_phase,
               ev_time, ev_code, loop_const, loop_index):  # pragma: no cover - compiled
    """Run steps ``k … k_end − 1``; returns ``(code, k)`` with ``k`` the rows recorded.

    ``time1``: one-element view of ``mjData.time``; ``qpos … actfrc``, ``qfrc_actuator``,
    ``actuator_force``: MuJoCo's live arrays; ``state … index``: the control law's packed
    arrays; ``b_*``: the record buffers (rows ``k`` on); ``ev_time``/``ev_code`` (``(n, 2)``:
    side, code): event buffers filled from ``loop_index[LI_N_EVENTS]`` on."""
    strides = loop_const[L_STRIDES]
    fall_dz = loop_const[L_FALL_DZ]
    fall_tilt = loop_const[L_FALL_TILT]
    pz = loop_index[LI_PZ]
    pt = loop_index[LI_PT]
    fn = loop_index[LI_FN]
    m_addr = loop_index[LI_MODEL]
    d_addr = loop_index[LI_DATA]
    nq = qpos.shape[0]
    nv = qvel.shape[0]
    nu = actuator_force.shape[0]
    ns = sens.shape[0]
    nc = contact_geoms.shape[0]
    while k < k_end:
        t = time1[0]
        law.control_step(t, qpos, qvel, sens, gxpos, state, table, table_step, const, index,
                         ctrl, actfrc)
        e0 = state[law.S_EVENT]
        e1 = state[law.S_EVENT + 1]
        if e0 != 0.0 or e1 != 0.0:
            for s in range(2):
                code = state[law.S_EVENT + s]
                if code == 1.0 or code == 2.0 or code == 3.0:
                    n = loop_index[LI_N_EVENTS]
                    ev_time[n] = t
                    ev_code[n, 0] = s
                    ev_code[n, 1] = int(code)
                    loop_index[LI_N_EVENTS] = n + 1
                    if code == 1.0 and s == 0:
                        loop_index[LI_RIGHT_STRIDES] += 1
            if loop_index[LI_RIGHT_STRIDES] > strides:
                return STRIDES_DONE, k
        call_mj_step(fn, m_addr, d_addr)
        # --- record the raw state --------------------------------------------------------
        b_time[k] = time1[0]
        for j in range(nq):
            b_qpos[k, j] = qpos[j]
        for j in range(nv):
            b_qvel[k, j] = qvel[j]
            b_qfrc[k, j] = qfrc_actuator[j]
        for j in range(nu):
            b_act[k, j] = actuator_force[j]
        for j in range(ns):
            b_sens[k, j] = sens[j]
        for j in range(nc):
            b_cz[k, j] = gxpos[contact_geoms[j], 2]
        b_phase[k, 0] = state[law.S_PHASE]
        b_phase[k, 1] = state[law.S_PHASE + 1]
        k += 1
        finite = True
        for j in range(nq):
            if not math.isfinite(qpos[j]):
                finite = False
        for j in range(nv):
            if not math.isfinite(qvel[j]):
                finite = False
        if not finite:
            return NON_FINITE, k
        if qpos[pz] < fall_dz or abs(qpos[pt]) > fall_tilt:
            return FELL, k
    return CHUNK_DONE, k
