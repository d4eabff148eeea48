"""The coupled-device protocol over a hand-written compiled kernel.

Before the circuits were generated from components (:mod:`afo_mj.circuits`), each device was
one hand-written numba kernel with a coupled-step API (``device_layout``/``device_views``,
``begin_step``, ``device_begin``/``device_end``, ``W_*``/``LOSS_INDEX``). The HAFO and the
valve orthoses now step their generated circuits; :class:`KernelDevice` keeps the old kernels
runnable as devices for the equivalence tests and the speed comparison
(``benchmarks/circuits.py``) and for the valve orthosis modes the generated circuits do not
have yet.
"""

from __future__ import annotations

import numpy as np

from afo_mj.circuits.device import SIDE_NAMES
from afo_mj.control import assistance as asst
from afo_mj.hydraulics.params import ParameterError

__all__ = ["KernelDevice", "KernelLog"]


class KernelDevice:
    """A device stepped by one of the hand-written compiled kernels
    (:mod:`~afo_mj.devices.pump_ankle_actuator`, :mod:`~afo_mj.devices.valve_ankle_actuator`:
    the same coupled-step API and buffer layout), with the coupled-device protocol of
    :class:`~afo_mj.circuits.device.CircuitDevice`. Subclasses name the ``kernel`` and its
    ``loss_names`` and give ``_pack`` (parameter row), ``_initial_state`` and
    ``_kernel_begin_step`` (the bench path's begin step).

    ``begin_step(t, angle, velocity, stance)`` → ``(joint_force, joint_damping)`` per walker
    side (zeros where not worn); MuJoCo steps; ``end_step(velocity_new)`` → delivered torque.
    ``profile`` is a tabulated torque vs stride phase (+dorsiflexion, N·m,
    :mod:`afo_mj.control.assistance`) or ``None`` (transparent: zero commanded torque).
    ``torque_fn(t, angle, velocity) -> N·m`` replaces the profile (bench tests); with
    ``mode="voltage"`` it returns the motor voltage instead (open-loop bench tests).
    """

    coupled = True
    #: the compiled kernel module that steps it (set by the subclass)
    kernel = None
    #: the ledger's loss names, in the order of the kernel's ``LOSS_INDEX``
    loss_names = ()

    def __init__(self, params, sides=("right",),
                 profile: np.ndarray | None = None, timestep_s: float = 1e-3,
                 max_steps: int = 0, mode: str = "torque", torque_fn=None,
                 initial_pressure_pa: float | None = None, min_stride_s: float = 0.4,
                 max_stride_s: float = 3.0):
        if mode not in ("torque", "voltage"):
            raise ParameterError(f"device.mode = {mode!r}; allowed: torque, voltage")
        bad = [s for s in sides if s not in SIDE_NAMES]
        if bad or not sides or len(set(sides)) != len(sides):
            raise ParameterError(f"device.sides = {list(sides)!r}; allowed: a non-empty subset "
                                 "of ['right', 'left']")
        self.params = params
        self.sides = tuple(sides)
        self.side_index = np.array([SIDE_NAMES.index(s) for s in self.sides], dtype=np.int64)
        ns = len(self.sides)
        self.mode = mode
        self.transparent = profile is None and torque_fn is None
        profile = (np.zeros(asst.TABLE_POINTS) if profile is None
                   else np.ascontiguousarray(profile, dtype=float))
        self.torque_fn = torque_fn
        self.timestep_s = float(timestep_s)
        # Every per-side float array is a view of one buffer, laid out by ``_meta``
        # (kernel.device_layout), so that the compiled step (device_begin / device_end)
        # takes two arrays instead of a dozen: the call overhead grows with their number.
        K = self.kernel
        self._meta = K.device_layout(ns, profile.shape[0], self.side_index)
        self._buf = np.zeros(self._meta[K.M_END])
        (self.Y, self.P, self.W, self.S, self.phase_state, self.profile, self._V, self._out,
         self._O) = K.device_views(self._buf, self._meta)
        self.P[:] = self._pack(params, mode)
        self.profile[:] = profile
        p0 = params.reservoir_pressure_pa if initial_pressure_pa is None else initial_pressure_pa
        self._initial_state(p0)
        self.W[:, K.W_SOC] = params.initial_soc
        self.W[:, K.W_TEMP_K] = params.ambient_temperature_k
        self.W[:, K.W_P_MAX] = p0
        self.S[:, 0, 0] = self.timestep_s
        self.phase_state[:] = asst.new_phase_state(ns)
        self.stride_limits = (float(min_stride_s), float(max_stride_s))
        self._buf[self._meta[K.M_LIM]:self._meta[K.M_LIM] + 2] = self.stride_limits
        # per-worn-side work rows and per-walker-side outputs: views of the rows of V and O
        self._theta, self._thd, self._cmd = (self._V[K.V_THETA], self._V[K.V_THETA_DOT],
                                             self._V[K.V_TAU_CMD])
        self._vnew, self._tau = self._V[K.V_THETA_DOT_NEW], self._V[K.V_TAU]
        self._O[K.O_PHASE] = -1.0
        self.force2, self.damping2 = self._O[K.O_FORCE], self._O[K.O_DAMPING]
        self.delivered2, self.commanded2 = self._O[K.O_DELIVERED], self._O[K.O_COMMANDED]
        self.phase2 = self._O[K.O_PHASE]
        self._out2 = (self.force2, self.damping2)
        self.steps = 0
        self.log = KernelLog(max_steps, ns, K.LOG_FIELDS) if max_steps else None
        self._log_data = (self.log.data if self.log is not None
                          else np.zeros((0, len(K.LOG_FIELDS), ns)))
        self.t_s = 0.0

    # -- stepping ------------------------------------------------------------------------------
    def begin_step(self, t: float, angle_rad, velocity_rad_s, stance):
        """Hold inputs, compute the commanded torque and linearise (see module docs of
        :mod:`~afo_mj.devices.pump_ankle_actuator`); returns views of the per-walker-side
        joint force and extra damping (length 2). The arguments are numpy arrays indexed by
        walker side (0 right, 1 left)."""
        self.t_s = t
        if self.torque_fn is None:
            # phase estimate, profile lookup and linearisation in one compiled call
            self.kernel.device_begin(t, angle_rad, velocity_rad_s, stance, self._buf,
                                     self._meta)
            return self._out2
        si = self.side_index
        th, thd, cmd = self._theta, self._thd, self._cmd
        for k in range(len(si)):
            s = si[k]
            th[k] = angle_rad[s]
            thd[k] = velocity_rad_s[s]
            cmd[k] = self.torque_fn(t, th[k], thd[k])
        self._kernel_begin_step(th, thd, cmd, t)
        f2, d2 = self.force2, self.damping2
        for k in range(len(si)):
            f2[si[k]] = self._out[k, 0]
            d2[si[k]] = self._out[k, 1]
            self.commanded2[si[k]] = cmd[k]
        return self._out2

    def end_step(self, velocity_new_rad_s):
        """Close the step with the ankle velocity MuJoCo produced; returns delivered torques
        (length 2, zero where not worn)."""
        k = self.steps
        # finish_all, delivered torques and the log row in one compiled call
        code = self.kernel.device_end(velocity_new_rad_s, self._buf, self._meta, self._log_data, k,
                             self.t_s + self.timestep_s)
        if not code:
            raise FloatingPointError(
                f"{type(self).__name__} hydraulic state became non-finite at t = "
                f"{self.t_s:.4f} s: {dict(zip(self.kernel.STATE_NAMES, self.Y[0].tolist()))}")
        if code == 2:
            self.log.n = k + 1
        self.steps = k + 1
        return self.delivered2

    # -- results ---------------------------------------------------------------------------
    def ledger(self, k: int = 0) -> dict:
        """Energy ledger of worn side ``k`` (J), with the balance residual."""
        K = self.kernel
        W = self.W[k]
        losses = {n: float(W[i]) for n, i in zip(self.loss_names, K.LOSS_INDEX)}
        stored = {"inductance": float(W[K.W_E_STORE_L]), "rotor": float(W[K.W_E_STORE_ROT]),
                  "oil": float(W[K.W_E_STORE_OIL]),
                  # the reservoir gives energy when it feeds the lines: its store falls
                  "reservoir": float(W[K.W_E_RESERVOIR])}
        e_in = float(W[K.W_E_CHEM])
        e_out = float(W[K.W_E_MECH])
        resid = e_in - e_out - sum(losses.values()) - sum(stored.values())
        drawn = float(W[K.W_E_CHEM_DRAWN])
        scale = max(drawn, 1e-12)
        return {"electrical_in_j": e_in, "electrical_drawn_j": drawn,
                "electrical_regenerated_j": drawn - e_in, "mechanical_out_j": e_out,
                "balance_error_rel": resid / scale,
                "energy_throughput_j": float(W[K.W_E_ABS_FLOW]),
                "hydraulic_j": float(W[K.W_E_HYD]), "losses_j": losses,
                "stored_change_j": stored, "residual_j": resid,
                "heat_to_oil_j": float(W[K.W_HEAT_TO_OIL]),
                "peak_pressure_pa": float(W[K.W_P_MAX]),
                "peak_current_a": float(W[K.W_I_PEAK]),
                "temperature_rise_k": float(W[K.W_TEMP_K] - self.params.ambient_temperature_k),
                "soc": float(W[K.W_SOC]), "pressure_floor_steps": int(W[K.W_CLIP_STEPS]),
                "newton_iterations": int(W[K.W_NEWTON_ITERS]),
                "newton_unconverged_steps": int(W[K.W_NEWTON_FAIL]),
                "substepped_steps": int(W[K.W_SUBSTEPPED]),
                "substeps": int(W[K.W_SUBSTEPS]),
                "coupling_torque_error_rms_nm": float(np.sqrt(W[K.W_COUPLE_SQ]
                                                              / max(self.steps, 1)))}



class KernelLog:
    """Preallocated per-step device signals (per worn side): ``data[step, field, side]`` (one
    step's signals side by side in memory), written by the compiled
    kernel's ``device_end``."""

    def __init__(self, n: int, ns: int, fields=()):
        self.n = 0
        self.FIELDS = tuple(fields)
        self.data = np.zeros((n, len(self.FIELDS), ns))

    def arrays(self) -> dict:
        return {f: self.data[:self.n, i].copy() for i, f in enumerate(self.FIELDS)}
