"""The compiled walk loop of any human controller that has a compiled step: the controller's
step called by address through one fixed C signature, gait events, the controller's joint
damping, a coupled device, ``mj_step``, recording and the checks, with no Python per step.

A controller (:class:`afo_mj.gait.controller.HumanController`) may give, besides its Python
``step``, a **compiled step** (:meth:`~afo_mj.gait.controller.HumanController.compiled`): the
address of a C-callable function (a ``numba.cfunc`` of :data:`STEP_SIGNATURE`)::

    void step(double t, double* qpos, double* qvel, double* sensordata, double* geom_xpos,
              int64* block, double* ctrl, double* out)

``qpos … geom_xpos`` and ``ctrl`` are MuJoCo's live arrays; ``block`` is the controller's
own int64 block (addresses and sizes of its parameter and state arrays; the loop never reads
it: :func:`f64_ptr` / :func:`i64_ptr` turn its addresses back into pointers inside the
cfunc); ``out`` (:data:`N_OUT` float64) is what the loop reads back each step:

* ``out[OUT_EVENT + s]``: the gait event of side ``s`` (0 none, 1 heel strike, 2 toe off);
* ``out[OUT_STANCE + s]``: 1.0 while side ``s`` is in stance (the foot switch a worn device
  reads);
* ``out[OUT_DAMP + 2 s + j]``: extra damping of side ``s``'s knee (``j = 0``) and ankle
  (``j = 1``) that MuJoCo integrates implicitly this step (N·m·s/rad), e.g. soft limits;
* ``out[OUT_TAU + 3 s + j]``: the joint moment the controller commands at side ``s``'s hip,
  knee, ankle (N·m), recorded (less the damping at the step's end velocity while some is
  engaged) when ``out[OUT_MOMENT_SOURCE]`` is 1; with 0 the loop records what MuJoCo's
  actuators applied to the leg joints (``qfrc_actuator``), as the Python walk's default.

The loop is :class:`afo_mj.gait.controller_walk.ControllerWalk`'s Python step, step for
step, in the same order and arithmetic, so a controller whose Python ``step`` and compiled
step compute the same thing walks the same walk bit for bit in either
(``tests/test_controller_loop.py``; the reflex controller's compiled step walks what the muscle
walker walks). Per step ``k`` (``t`` the time MuJoCo holds):

1. the controller's step; its events go with ``t`` to the event buffers; after a right heel
   strike that completes the requested strides the loop stops before stepping
   (:data:`STRIDES_DONE`);
2. its extra damping on the knees and ankles (base + extra), written while some is engaged
   or was the step before;
3. with a coupled device (``loop_index[LI_DEV_BEGIN] != 0``), its ``begin`` entry point
   (:mod:`afo_mj.circuits.native_entry`) gets the ankle angles, velocities and the
   controller's stance; its joint force goes to ``qfrc_applied`` and its extra damping onto
   the ankles' (base + controller's + device's);
4. ``mj_step``; a time that went back (MuJoCo reset a diverging state) stops the loop
   (:data:`DIVERGED`, ``t`` in ``loop_const[L_T]``);
5. with a device, its ``end`` entry point gets the new ankle velocities and leaves the
   delivered torque (code 0 stops the loop: :data:`DEVICE_NON_FINITE`);
6. row ``k``: time, ``qpos``, ``qvel``, sensors, contact heights, the device's torque, the
   joint moments, the pelvis residuals' generalised forces, and the declared signals (the
   entries ``state[signal_index]`` of the controller's state array);
7. a non-finite ``qpos``, ``qvel`` or controller state stops the loop (:data:`NON_FINITE`);
   the pelvis below or
   the trunk pitched past the controller's fall limits stops it (:data:`FELL`).
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from afo_mj.gait.native_step import call_mj_step
from afo_mj.gait.walk_loop import _call_begin, all_finite, device_end_step, record_raw_state
from afo_mj.numba_cache import cached_njit

__all__ = ["STEP_SIGNATURE", "N_OUT", "OUT_EVENT", "OUT_STANCE", "OUT_DAMP", "OUT_TAU",
           "OUT_MOMENT_SOURCE", "f64_ptr", "i64_ptr", "controller_steps",
           "CHUNK_DONE", "STRIDES_DONE", "FELL", "NON_FINITE", "DIVERGED", "DEVICE_NON_FINITE",
           "L_STRIDES", "L_FALL_Z", "L_FALL_TILT", "L_DEV_DT", "L_DEV_LAST_T", "L_T",
           "N_LOOP_CONST", "LI_STEP", "LI_BLOCK", "LI_PZ", "LI_PT", "LI_FN", "LI_MODEL",
           "LI_DATA", "LI_N_EVENTS", "LI_RIGHT_STRIDES", "LI_LIM_WAS", "LI_DEV_BEGIN",
           "LI_DEV_END", "LI_P_IO", "LI_P_BUF", "LI_P_META", "LI_P_LOG", "LI_LOG_N",
           "LI_LOG_F", "LI_LOG_S", "LI_DEV_STEPS", "LI_OUT", "N_LOOP_INDEX"]

CHUNK_DONE, STRIDES_DONE, FELL, NON_FINITE, DIVERGED, DEVICE_NON_FINITE = 0, 1, 2, 3, 4, 5

#: the compiled step's ``out`` layout (module docstring)
OUT_EVENT, OUT_STANCE, OUT_DAMP, OUT_TAU, OUT_MOMENT_SOURCE = 0, 2, 4, 8, 14
N_OUT = 16

#: the C signature of a controller's compiled step (module docstring)
STEP_SIGNATURE = types.void(types.float64, types.CPointer(types.float64),
                            types.CPointer(types.float64), types.CPointer(types.float64),
                            types.CPointer(types.float64), types.CPointer(types.int64),
                            types.CPointer(types.float64), types.CPointer(types.float64))

# loop constants (float64): strides (0: none), the fall limits, the device step; written by
# the loop: the time the device's last step began, the time the last step began
(L_STRIDES, L_FALL_Z, L_FALL_TILT, L_DEV_DT, L_DEV_LAST_T, L_T, N_LOOP_CONST) = range(7)
# loop integers (int64): the controller's step and block addresses, the pelvis height and tilt
# qpos addresses, the native step's addresses, values the loop updates (events recorded,
# right heel strikes, damping engaged in the last step 0/1); device: entry points (0: none),
# addresses of its in/out block, buffer, layout and log, the log's shape, its step counter
# (updated); the address of ``out``
(LI_STEP, LI_BLOCK, LI_PZ, LI_PT, LI_FN, LI_MODEL, LI_DATA, LI_N_EVENTS, LI_RIGHT_STRIDES,
 LI_LIM_WAS, LI_DEV_BEGIN, LI_DEV_END, LI_P_IO, LI_P_BUF, LI_P_META, LI_P_LOG, LI_LOG_N,
 LI_LOG_F, LI_LOG_S, LI_DEV_STEPS, LI_OUT, N_LOOP_INDEX) = range(22)


@intrinsic
def f64_ptr(typingctx, address):
    """``double*`` at an integer address (for a compiled step reading its block)."""
    if not isinstance(address, types.Integer):
        return None
    sig = types.CPointer(types.float64)(address)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.DoubleType().as_pointer())

    return sig, codegen


@intrinsic
def i64_ptr(typingctx, address):
    """``int64*`` at an integer address (for a compiled step reading its block)."""
    if not isinstance(address, types.Integer):
        return None
    sig = types.CPointer(types.int64)(address)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.IntType(64).as_pointer())

    return sig, codegen


@intrinsic
def _call_step(typingctx, fn, t, p_qpos, p_qvel, p_sens, p_gxpos, p_block, p_ctrl, p_out):
    """Call a controller's compiled step (:data:`STEP_SIGNATURE`) at address ``fn``; the
    pointers are integer addresses."""
    sig = types.void(fn, t, p_qpos, p_qvel, p_sens, p_gxpos, p_block, p_ctrl, p_out)

    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [ir.DoubleType()] + [vp] * 7)
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [args[1]] + [builder.inttoptr(a, vp) for a in args[2:]])
        return context.get_dummy_value()

    return sig, codegen


@cached_njit(depends_on=("afo_mj.gait.walk_loop", "afo_mj.gait.native_step"), fastmath=False,
             _nrt=False)
def controller_steps(k, k_end, time1, qpos, qvel, sens, gxpos, ctrl, qfrc_applied,
                     dof_damping, qfrc_actuator, state, signal_runs, leg_dof, ank_q, dlim,
                     base_limit, contact, pelvis_dof, b_time, b_qpos, b_qvel, b_sens, b_cz,
                     b_dev, b_tau, b_res, b_sig, ev_time, ev_code, out, loop_const,
                     loop_index, dev_io, dev_force2, dev_damping2,
                     dev_delivered2):  # pragma: no cover - compiled; exercised by the tests
    """Run steps ``k … k_end − 1``; returns ``(code, k)`` with ``k`` the rows recorded.

    ``time1``: one-element view of ``mjData.time``; ``qpos … qfrc_actuator``: MuJoCo's live
    arrays; ``state``: the controller's state array, ``signal_runs`` (m, 3) the entries of it
    recorded per step into ``b_sig``, as runs ``(first entry, first column, length)``;
    ``leg_dof`` (2, 3), ``ank_q`` (2: the ankles' qpos addresses), ``dlim`` (2, 2: knee,
    ankle dofs), ``base_limit`` (2, 2), ``contact`` (4), ``pelvis_dof`` (3): addresses and
    the knees' and ankles' base damping; ``b_*``: the record buffers (rows ``k`` on); ``ev_time`` /
    ``ev_code`` (``(n, 2)``: side, code) filled from ``loop_index[LI_N_EVENTS]`` on; ``out``:
    the compiled step's output block (its address is ``loop_index[LI_OUT]``); ``dev_io``
    (6): the device's input block; ``dev_force2 … dev_delivered2``: views of the device
    buffer's outputs per walker side."""
    strides = loop_const[L_STRIDES]
    fall_z = loop_const[L_FALL_Z]
    fall_tilt = loop_const[L_FALL_TILT]
    dev_dt = loop_const[L_DEV_DT]
    step_fn = loop_index[LI_STEP]
    p_block = loop_index[LI_BLOCK]
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
    p_out = loop_index[LI_OUT]
    p_qpos = qpos.ctypes.data
    p_qvel = qvel.ctypes.data
    p_sens = sens.ctypes.data
    p_gxpos = gxpos.ctypes.data
    p_ctrl = ctrl.ctypes.data
    nrun = signal_runs.shape[0]
    ank_r = dlim[0, 1]
    ank_l = dlim[1, 1]
    lim_was = loop_index[LI_LIM_WAS] != 0
    while k < k_end:
        t = time1[0]
        loop_const[L_T] = t
        _call_step(step_fn, t, p_qpos, p_qvel, p_sens, p_gxpos, p_block, p_ctrl, p_out)
        for s in range(2):
            code = out[OUT_EVENT + s]
            if code == 1.0 or code == 2.0:
                n = loop_index[LI_N_EVENTS]
                ev_time[n] = t
                ev_code[n, 0] = s
                ev_code[n, 1] = int(code)
                loop_index[LI_N_EVENTS] = n + 1
                if code == 1.0 and s == 0:
                    loop_index[LI_RIGHT_STRIDES] += 1
        if strides > 0.0 and loop_index[LI_RIGHT_STRIDES] > strides:
            return STRIDES_DONE, k
        lim_now = False
        for j in range(4):
            if out[OUT_DAMP + j] != 0.0:
                lim_now = True
        if lim_now or lim_was:
            for s in range(2):
                for j in range(2):
                    dof_damping[dlim[s, j]] = base_limit[s, j] + out[OUT_DAMP + 2 * s + j]
        lim_was = lim_now
        loop_index[LI_LIM_WAS] = 1 if lim_now else 0
        if dev_begin != 0:
            dev_io[0] = qpos[ank_q[0]]
            dev_io[1] = qpos[ank_q[1]]
            dev_io[2] = qvel[ank_r]
            dev_io[3] = qvel[ank_l]
            dev_io[4] = out[OUT_STANCE]
            dev_io[5] = out[OUT_STANCE + 1]
            _call_begin(dev_begin, t, p_io, p_io + 16, p_io + 32, p_buf, p_meta)
            loop_const[L_DEV_LAST_T] = t
            qfrc_applied[ank_r] = dev_force2[0]
            qfrc_applied[ank_l] = dev_force2[1]
            dof_damping[ank_r] = base_limit[0, 1] + out[OUT_DAMP + 1] + dev_damping2[0]
            dof_damping[ank_l] = base_limit[1, 1] + out[OUT_DAMP + 3] + dev_damping2[1]
        call_mj_step(fn, m_addr, d_addr)
        if time1[0] < t:
            return DIVERGED, k
        if dev_end != 0:
            n_dev = loop_index[LI_DEV_STEPS]
            code_d = device_end_step(dev_end, dev_io, qvel, ank_r, ank_l, p_io, p_buf,
                                     p_meta, p_log, log_n, log_f, log_s, n_dev, t + dev_dt,
                                     dev_delivered2, b_dev, k)
            loop_index[LI_DEV_STEPS] = n_dev + 1
            if code_d == 0:
                return DEVICE_NON_FINITE, k
        # --- record ---------------------------------------------------------------------
        record_raw_state(k, time1, qpos, qvel, sens, gxpos, contact, b_time, b_qpos, b_qvel,
                         b_sens, b_cz)
        if out[OUT_MOMENT_SOURCE] == 1.0:
            for s in range(2):
                b_tau[k, s, 0] = out[OUT_TAU + 3 * s]
                for j in range(2):
                    tq = out[OUT_TAU + 3 * s + 1 + j]
                    if lim_now:
                        tq = tq - out[OUT_DAMP + 2 * s + j] * qvel[dlim[s, j]]
                    b_tau[k, s, 1 + j] = tq
        else:
            for s in range(2):
                for j in range(3):
                    b_tau[k, s, j] = qfrc_actuator[leg_dof[s, j]]
        for j in range(3):
            b_res[k, j] = qfrc_actuator[pelvis_dof[j]]
        for r in range(nrun):
            src = signal_runs[r, 0]
            dst = signal_runs[r, 1]
            for j in range(signal_runs[r, 2]):
                b_sig[k, dst + j] = state[src + j]
        k += 1
        if not (all_finite(qpos) and all_finite(qvel) and all_finite(state)):
            return NON_FINITE, k
        if qpos[pz] < fall_z or abs(qpos[pt]) > fall_tilt:
            return FELL, k
    return CHUNK_DONE, k
