"""The walk's per-step loop in compiled code: controller, gait events, ``mj_step``, recording
and the fall and finiteness checks, with no Python per step.

:func:`walk_steps` runs steps ``k … k_end − 1`` of a walk (or stops earlier) and returns why it
stopped; the torque walker's walk (:class:`afo_mj.gait.tracking_walk.Walk`, a
:class:`~afo_mj.gait.controller_walk.ControllerWalk`) calls it on its own buffers in chunks
(one call per progress update, or one for the whole walk, or one per ``step()``). It is that
walk's Python step, step for step — the
same compiled control law (:func:`afo_mj.gait.control_law.control_step`), MuJoCo's own C
``mj_step`` called through :func:`afo_mj.gait.native_step.call_mj_step`, the same copies in
the same order — so its records equal the Python loop's bit for bit
(``tests/test_walk_loop.py``).

Per step:

1. ``control_step`` at the time MuJoCo holds; its event codes (heel strike, toe off, swing
   contact) go to the event buffers; after a right heel strike that completes the requested
   strides the loop stops before stepping (:data:`STRIDES_DONE`);
2. with a coupled device (``loop_index[LI_DEV_BEGIN] != 0``), its ``begin`` entry point
   (a C function at that address, e.g. a generated circuit's,
   :mod:`afo_mj.circuits.native_entry`) gets the ankle angles, velocities and stance flags;
   its joint force goes to ``qfrc_applied`` and its extra damping onto the ankles' base
   damping, and the wearer's ankle feedforward drops by ``adapt`` × the torque at the present
   velocity (:meth:`afo_mj.gait.tracking_controller.TrackingController.answer_device`);
3. ``mj_step``;
4. with a device, its ``end`` entry point gets the new ankle velocities and leaves the
   delivered torque (code 0, a non-finite device state, stops the loop:
   :data:`DEVICE_NON_FINITE`);
5. the raw state, the leg joints' and the pelvis residuals' actuator forces and the
   controller's phase estimate are copied into row ``k`` of the walk's buffers;
6. a non-finite ``qpos``/``qvel`` stops the loop (:data:`NON_FINITE`); a hip below the fall
   height or a trunk pitched past the fall tilt stops it (:data:`FELL`).

Codes returned: :data:`CHUNK_DONE` (reached ``k_end``), :data:`STRIDES_DONE`,
:data:`FELL`, :data:`NON_FINITE`, :data:`DEVICE_NON_FINITE`.
"""

from __future__ import annotations

import math

import numba
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from afo_mj.gait import control_law as law
from afo_mj.gait.native_step import call_mj_step
from afo_mj.numba_cache import cached_njit

__all__ = ["CHUNK_DONE", "STRIDES_DONE", "FELL", "NON_FINITE", "DEVICE_NON_FINITE",
           "walk_steps",
           "EV_HEEL_STRIKE", "EV_TOE_OFF", "EV_SWING_CONTACT",
           "L_STRIDES", "L_FALL_DZ", "L_FALL_TILT", "L_BASE_DAMP_R", "L_BASE_DAMP_L",
           "L_ADAPT", "L_DEV_DT", "L_DEV_LAST_T", "N_LOOP_CONST",
           "LI_PZ", "LI_PT", "LI_FN", "LI_MODEL", "LI_DATA", "LI_N_EVENTS", "LI_RIGHT_STRIDES",
           "LI_DEV_BEGIN", "LI_DEV_END", "LI_P_IO", "LI_P_BUF", "LI_P_META", "LI_P_LOG",
           "LI_LOG_N", "LI_LOG_F", "LI_LOG_S", "LI_DEV_STEPS", "LI_ANK_R", "LI_ANK_L",
           "LI_DANK_R", "LI_DANK_L", "LI_FF_R", "LI_FF_L", "N_LOOP_INDEX"]

CHUNK_DONE, STRIDES_DONE, FELL, NON_FINITE, DEVICE_NON_FINITE = 0, 1, 2, 3, 4
EV_HEEL_STRIKE, EV_TOE_OFF, EV_SWING_CONTACT = 1, 2, 3

# loop constants (float64): strides, fall limits; device: the ankles' base damping, the
# wearer's adaptation, the device step, and (written by the loop) the time its last step began
(L_STRIDES, L_FALL_DZ, L_FALL_TILT, L_BASE_DAMP_R, L_BASE_DAMP_L, L_ADAPT, L_DEV_DT,
 L_DEV_LAST_T, N_LOOP_CONST) = range(9)
# loop integers (int64): qpos addresses, the native step's addresses, two counters the loop
# updates (events recorded, right heel strikes); device: entry points (0: none), addresses
# of its in/out block (``dev_io``: angle ×2, velocity ×2, stance ×2), buffer, layout and log,
# the log's shape, the device's step counter (updated), the ankles' qpos/dof addresses and
# the ankle feedforward actuators
(LI_PZ, LI_PT, LI_FN, LI_MODEL, LI_DATA, LI_N_EVENTS, LI_RIGHT_STRIDES,
 LI_DEV_BEGIN, LI_DEV_END, LI_P_IO, LI_P_BUF, LI_P_META, LI_P_LOG, LI_LOG_N, LI_LOG_F,
 LI_LOG_S, LI_DEV_STEPS, LI_ANK_R, LI_ANK_L, LI_DANK_R, LI_DANK_L, LI_FF_R, LI_FF_L,
 N_LOOP_INDEX) = range(24)


@intrinsic
def _call_begin(typingctx, fn, t, p_angle, p_velocity, p_stance, p_buf, p_meta):
    """Call ``void begin(double, double*, double*, double*, double*, int64*)`` at ``fn``."""
    sig = types.void(fn, t, p_angle, p_velocity, p_stance, p_buf, p_meta)

    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [ir.DoubleType()] + [vp] * 5)
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [args[1]] + [builder.inttoptr(a, vp) for a in args[2:]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _call_end(typingctx, fn, p_velocity, p_buf, p_meta, p_log, n_log, n_fields, n_sides, k, t):
    """Call ``int64 end(double*, double*, int64*, double*, int64 ×4, double)`` at ``fn``."""
    sig = types.int64(fn, p_velocity, p_buf, p_meta, p_log, n_log, n_fields, n_sides, k, t)

    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        i64 = ir.IntType(64)
        fnty = ir.FunctionType(i64, [vp] * 4 + [i64] * 4 + [ir.DoubleType()])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(f, [builder.inttoptr(a, vp) for a in args[1:5]] + list(args[5:]))

    return sig, codegen


# cached on disk with the sources of the law and the native step it compiles in (afo_mj.numba_cache)
@numba.njit(inline="always", _nrt=False)
def device_end_step(dev_end, dev_io, qvel, dank_r, dank_l, p_io, p_buf, p_meta, p_log, log_n,
                    log_f, log_s, n_dev, t_end, dev_delivered2, b_dev, k):  # pragma: no cover
    """A coupled device's ``end`` entry point after ``mj_step``, shared by the compiled walk
    loops: the new ankle velocities into its input block, the end of its step ``n_dev`` at
    ``t_end``, its delivered torque into row ``k`` of ``b_dev``; returns its code (0: its
    state went non-finite, nothing recorded)."""
    dev_io[2] = qvel[dank_r]
    dev_io[3] = qvel[dank_l]
    code = _call_end(dev_end, p_io + 16, p_buf, p_meta, p_log, log_n, log_f, log_s, n_dev,
                     t_end)
    if code != 0:
        b_dev[k, 0] = dev_delivered2[0]
        b_dev[k, 1] = dev_delivered2[1]
    return code


@numba.njit(inline="always", _nrt=False)
def all_finite(a):  # pragma: no cover
    """Every entry of the 1-D array ``a`` finite (no NaN, no ±inf)."""
    for j in range(a.shape[0]):
        if not math.isfinite(a[j]):
            return False
    return True


@numba.njit(inline="always", _nrt=False)
def record_raw_state(k, time1, qpos, qvel, sens, gxpos, contact, b_time, b_qpos, b_qvel,
                     b_sens, b_cz):  # pragma: no cover
    """Row ``k`` of the raw-state buffers every compiled walk loop keeps: the time, ``qpos``,
    ``qvel``, the sensors and the contact geoms' heights."""
    b_time[k] = time1[0]
    for j in range(qpos.shape[0]):
        b_qpos[k, j] = qpos[j]
    for j in range(qvel.shape[0]):
        b_qvel[k, j] = qvel[j]
    for j in range(sens.shape[0]):
        b_sens[k, j] = sens[j]
    for j in range(contact.shape[0]):
        b_cz[k, j] = gxpos[contact[j], 2]


@cached_njit(depends_on=(law, "afo_mj.gait.native_step"), fastmath=False, _nrt=False)
def walk_steps(k, k_end, time1, qpos, qvel, sens, gxpos, state, table, table_step, const,
               index, ctrl, actfrc, qfrc_actuator, contact_geoms, leg_dof, pelvis_dof,
               b_time, b_qpos, b_qvel, b_tau, b_res, b_sens, b_cz, b_phase,
               ev_time, ev_code, loop_const, loop_index, qfrc_applied, dof_damping, dev_io,
               dev_force2, dev_damping2, dev_delivered2, b_dev):  # pragma: no cover
    """Run steps ``k … k_end − 1``; returns ``(code, k)`` with ``k`` the rows recorded.

    ``time1``: one-element view of ``mjData.time``; ``qpos … actfrc``, ``qfrc_actuator``,
    ``qfrc_applied``, ``dof_damping``: MuJoCo's live arrays; ``state … index``: the control
    law's packed arrays; ``leg_dof`` (2, 3), ``pelvis_dof`` (3,): the dof addresses whose
    actuator forces are recorded as the joint moments (``b_tau``, (n, 2, 3)) and the pelvis
    residuals (``b_res``, (n, 3)); ``b_*``: the record buffers (rows ``k`` on);
    ``ev_time``/``ev_code`` (``(n, 2)``: side, code): event buffers filled from
    ``loop_index[LI_N_EVENTS]`` on; ``dev_io`` (6): the device's input block (its address
    is ``loop_index[LI_P_IO]``); ``dev_force2 … dev_delivered2``: views of the device buffer's
    outputs per walker side."""
    strides = loop_const[L_STRIDES]
    fall_dz = loop_const[L_FALL_DZ]
    fall_tilt = loop_const[L_FALL_TILT]
    pz = loop_index[LI_PZ]
    pt = loop_index[LI_PT]
    fn = loop_index[LI_FN]
    m_addr = loop_index[LI_MODEL]
    d_addr = loop_index[LI_DATA]
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
    ff_r = loop_index[LI_FF_R]
    ff_l = loop_index[LI_FF_L]
    base_r = loop_const[L_BASE_DAMP_R]
    base_l = loop_const[L_BASE_DAMP_L]
    adapt = loop_const[L_ADAPT]
    dev_dt = loop_const[L_DEV_DT]
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
        if dev_begin != 0:
            dev_io[0] = qpos[ank_r]
            dev_io[1] = qpos[ank_l]
            dev_io[2] = qvel[dank_r]
            dev_io[3] = qvel[dank_l]
            dev_io[4] = 1.0 if state[law.S_SWING] < 0.5 else 0.0
            dev_io[5] = 1.0 if state[law.S_SWING + 1] < 0.5 else 0.0
            _call_begin(dev_begin, t, p_io, p_io + 16, p_io + 32, p_buf, p_meta)
            loop_const[L_DEV_LAST_T] = t
            f_r = dev_force2[0]
            f_l = dev_force2[1]
            d_r = dev_damping2[0]
            d_l = dev_damping2[1]
            qfrc_applied[dank_r] = f_r
            qfrc_applied[dank_l] = f_l
            dof_damping[dank_r] = base_r + d_r
            dof_damping[dank_l] = base_l + d_l
            if adapt != 0.0:
                # the wearer anticipates the torque at the present ankle velocity
                ctrl[ff_r] -= adapt * (f_r - d_r * dev_io[2])
                ctrl[ff_l] -= adapt * (f_l - d_l * dev_io[3])
        call_mj_step(fn, m_addr, d_addr)
        if dev_end != 0:
            n_dev = loop_index[LI_DEV_STEPS]
            code = device_end_step(dev_end, dev_io, qvel, dank_r, dank_l, p_io, p_buf, p_meta,
                                   p_log, log_n, log_f, log_s, n_dev, t + dev_dt,
                                   dev_delivered2, b_dev, k)
            loop_index[LI_DEV_STEPS] = n_dev + 1
            if code == 0:
                return DEVICE_NON_FINITE, k
        # --- record the raw state --------------------------------------------------------
        record_raw_state(k, time1, qpos, qvel, sens, gxpos, contact_geoms, b_time, b_qpos,
                         b_qvel, b_sens, b_cz)
        for s in range(2):
            for j in range(3):
                b_tau[k, s, j] = qfrc_actuator[leg_dof[s, j]]
        for j in range(3):
            b_res[k, j] = qfrc_actuator[pelvis_dof[j]]
        b_phase[k, 0] = state[law.S_PHASE]
        b_phase[k, 1] = state[law.S_PHASE + 1]
        k += 1
        if not (all_finite(qpos) and all_finite(qvel)):
            return NON_FINITE, k
        if qpos[pz] < fall_dz or abs(qpos[pt]) > fall_tilt:
            return FELL, k
    return CHUNK_DONE, k
