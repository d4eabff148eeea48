"""A user's numba controller for the tests, written only against the controller interface
(:mod:`afo_mj.gait.controller`) with a compiled step (:mod:`afo_mj.gait.controller_loop`).

The clock-driven torque-profile gait of ``tests/clock_controller.py``, with the reference
sampled into a table (256 phases; linear interpolation) so that the whole law is one numba
function, :func:`clock_law`. The Python ``step`` calls that function on the controller's
arrays and the compiled step (a ``numba.cfunc``) calls the same function on the same arrays,
so the two loops walk the same walk bit for bit — the property the tests check.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import carray

from afo_mj.gait import controller_loop as cl
from afo_mj.gait.controller import CompiledStep, HumanController
from clock_controller import ClockParams

NAME = "clock_profile_compiled_test"
N_TABLE = 256
# F: cycle time, kp, kv, ankle fraction, moment feedforward, mass, start speed, body-weight
# support, support damping, trunk stiffness, trunk damping, stance on / off fractions, heel
# strike window (lo, hi), toe off window (lo, hi), speed gain
N_F = 18
# I: leg qpos (6), leg dofs (6), torque motors (6), touch sensors (4), pelvis qpos (3),
# pelvis dofs (3), residuals (3), nq, nv, ns, nu
I_LQ, I_LV, I_FF, I_TOUCH, I_PQ, I_PV, I_RES, I_N = 0, 6, 12, 18, 22, 25, 28, 31
N_I = 35
# S: stance per side, then the commanded joint torques (2 × 3)
S_STANCE, S_TAU, N_S = 0, 2, 8


@numba.njit(cache=True)
def clock_law(t, qpos, qvel, sens, ctrl, F, I, S, TAB, out):  # pragma: no cover
    """One step: PD toward the table's reference at the clock's phase per leg plus the
    moment feedforward; the pelvis residuals (speed, body-weight support, trunk); stance and
    events in the clock's windows; ``out`` per :mod:`afo_mj.gait.controller_loop`."""
    T = F[0]
    n = TAB.shape[0]
    g = 9.81
    for s in range(2):
        ph = (t / T + 0.5 * s) % 1.0
        x = ph * n
        i0 = int(x) % n
        i1 = (i0 + 1) % n
        w = x - np.floor(x)
        load = (sens[I[I_TOUCH + 2 * s]] + sens[I[I_TOUCH + 2 * s + 1]]) / (F[5] * g)
        for j in range(3):
            ang = TAB[i0, j] + w * (TAB[i1, j] - TAB[i0, j])
            vel = TAB[i0, 3 + j] + w * (TAB[i1, 3 + j] - TAB[i0, 3 + j])
            mom = TAB[i0, 6 + j] + w * (TAB[i1, 6 + j] - TAB[i0, 6 + j])
            gain = F[3] if j == 2 else 1.0
            tau = (gain * (F[1] * (ang - qpos[I[I_LQ + 3 * s + j]])
                           + F[2] * (vel - qvel[I[I_LV + 3 * s + j]]))
                   + F[4] * F[5] * mom)
            ctrl[I[I_FF + 3 * s + j]] = tau
            S[S_TAU + 3 * s + j] = tau
            out[cl.OUT_TAU + 3 * s + j] = tau
        in_hs = ph >= F[13] or ph < F[14]
        in_to = F[15] <= ph < F[16]
        ev = 0.0
        if S[S_STANCE + s] < 0.5 and in_hs and load > F[11]:
            S[S_STANCE + s] = 1.0
            ev = 1.0
        elif S[S_STANCE + s] > 0.5 and in_to and load < F[12]:
            S[S_STANCE + s] = 0.0
            ev = 2.0
        out[cl.OUT_EVENT + s] = ev
        out[cl.OUT_STANCE + s] = S[S_STANCE + s]
    ctrl[I[I_RES]] = F[17] * (F[6] - qvel[I[I_PV]])
    ctrl[I[I_RES + 1]] = F[7] * F[5] * g - F[8] * qvel[I[I_PV + 1]]
    ctrl[I[I_RES + 2]] = -F[9] * qpos[I[I_PQ + 2]] - F[10] * qvel[I[I_PV + 2]]


@numba.cfunc(cl.STEP_SIGNATURE, cache=True, error_model="numpy")
def _cstep(t, qpos_p, qvel_p, sens_p, gxpos_p, blk, ctrl_p, out_p):  # pragma: no cover
    # block: [F, I, S, TAB, TAB rows, out] addresses; sizes from I
    I = carray(cl.i64_ptr(blk[1]), (N_I,))
    qpos = carray(qpos_p, (I[I_N],))
    qvel = carray(qvel_p, (I[I_N + 1],))
    sens = carray(sens_p, (I[I_N + 2],))
    ctrl = carray(ctrl_p, (I[I_N + 3],))
    F = carray(cl.f64_ptr(blk[0]), (N_F,))
    S = carray(cl.f64_ptr(blk[2]), (N_S,))
    TAB = carray(cl.f64_ptr(blk[3]), (blk[4], 9))
    out = carray(out_p, (cl.N_OUT,))
    clock_law(t, qpos, qvel, sens, ctrl, F, I, S, TAB, out)


class CompiledClockController(HumanController):
    """The clock controller as one numba law with a compiled step (module docstring)."""

    name = NAME
    Params = ClockParams
    actuators = ("ff", "residual")
    reads = ("time", "qpos", "qvel", "touch")
    signals = {"commanded_torque_nm": ("N*m", (2, 3))}

    def start(self, phys) -> None:
        super().start(phys)
        p, setup = self.params, self.setup
        ref, T = setup.reference, setup.cycle_time_s
        ph = np.arange(N_TABLE) / N_TABLE
        self._tab = np.ascontiguousarray(np.column_stack(
            [ref.angles_rad(ph), ref.velocities_rad_s(ph, T), ref.moments_nm_per_kg(ph)]))
        mass = float(self.walker_params().body_mass_kg)
        self._F = np.array([T, p.kp_nm_per_rad, p.kv_nm_s_per_rad, p.ankle_gain_fraction,
                            p.moment_feedforward, mass,
                            float(phys.data.qvel[phys.pelvis_dof[0]]), p.body_weight_support,
                            p.support_n_s_per_m, p.trunk_nm_per_rad, p.trunk_nm_s_per_rad,
                            self.stance_on_fraction, self.stance_off_fraction, 0.85, 0.25,
                            0.45, 0.80, p.speed_n_s_per_m])
        m = phys.model
        self._I = np.concatenate([phys.leg_qpos.ravel(), phys.leg_dof.ravel(),
                                  phys.ff_act.ravel(), phys.touch_adr.ravel(),
                                  phys.pelvis_qpos, phys.pelvis_dof, phys.residual_act,
                                  [m.nq, m.nv, m.nsensordata, m.nu]]).astype(np.int64)
        self._S = np.zeros(N_S)
        self._S[S_STANCE:S_STANCE + 2] = self._stance
        self._out = np.zeros(cl.N_OUT)

    def step(self, t, phys):
        d = phys.data
        clock_law(t, d.qpos, d.qvel, d.sensordata, d.ctrl, self._F, self._I, self._S,
                  self._tab, self._out)
        return int(self._out[cl.OUT_EVENT]), int(self._out[cl.OUT_EVENT + 1])

    @property
    def stance(self):
        return self._S[S_STANCE:S_STANCE + 2] > 0.5

    def state_array(self):
        return self._S

    def signal_values(self):
        return {"commanded_torque_nm": self._S[S_TAU:S_TAU + 6].reshape(2, 3)}

    def compiled(self, phys) -> CompiledStep:
        block = np.array([self._F.ctypes.data, self._I.ctypes.data, self._S.ctypes.data,
                          self._tab.ctypes.data, self._tab.shape[0]], dtype=np.int64)
        return CompiledStep(_cstep.address, block, self._S,
                            {"commanded_torque_nm": np.arange(S_TAU, S_TAU + 6).reshape(2, 3)},
                            moments_from_out=False,
                            keep=(self._F, self._I, self._S, self._tab))
