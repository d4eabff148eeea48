"""A generated circuit worn on a joint: the coupled-device protocol for MuJoCo, the replay
loops with the load simulated or imposed, and the energy ledger named per component.

``CircuitDevice`` speaks the protocol :func:`afo_mj.gait.walk.run_walk` and
:meth:`afo_mj.human.test_stand.AnkleTestStand.run_device` use (``coupled``, ``timestep_s``,
``begin_step`` → joint force and extra damping per walker side, ``end_step`` → delivered
torque), so any described circuit walks and runs on the test stand like the presets.
"""

from __future__ import annotations

import numpy as np

from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.codegen import CompiledCircuit, build
from afo_mj.circuits.components import CircuitError

SIDE_NAMES = ("right", "left")


class CircuitDevice:
    """One compiled circuit per worn side. ``torque_fn(t, angle, velocity)`` gives the command
    (a torque for a torque controller, a voltage for ``open_loop``); ``None`` commands 0."""

    coupled = True

    def __init__(self, circuit: Circuit | CompiledCircuit, sides=("right",),
                 timestep_s: float = 1e-3, torque_fn=None):
        cc = circuit if isinstance(circuit, CompiledCircuit) else build(circuit)
        bad = [s for s in sides if s not in SIDE_NAMES]
        if bad or not sides or len(set(sides)) != len(sides):
            raise CircuitError(f"device.sides = {list(sides)!r}; allowed: a non-empty subset "
                               "of ['right', 'left']")
        self.cc = cc
        self.k = cc.module
        self.sides = tuple(sides)
        self.side_index = np.array([SIDE_NAMES.index(s) for s in self.sides], dtype=np.int64)
        ns = len(self.sides)
        self.timestep_s = float(timestep_s)
        self.torque_fn = torque_fn
        self.Y = np.tile(cc.y0, (ns, 1))
        self.P = np.tile(cc.P, (ns, 1))
        self.W = np.zeros((ns, cc.n_w))
        self.S = np.zeros((ns, cc.n_scratch, cc.s_width))
        self.S[:, 0, 0] = self.timestep_s
        for key, v in cc.w_init.items():
            self.W[:, getattr(self.k, "W_" + key)] = v
        self.W[:, self.k.W_P_MAX] = cc.circuit.options.initial_pressure_pa
        self._th = np.zeros(ns)
        self._thd = np.zeros(ns)
        self._cmd = np.zeros(ns)
        self._out = np.zeros((ns, 2))
        self._vnew = np.zeros(ns)
        self._tau = np.zeros(ns)
        self.force2 = np.zeros(2)
        self.damping2 = np.zeros(2)
        self.delivered2 = np.zeros(2)
        self.steps = 0
        self.t_s = 0.0

    # -- coupled protocol --------------------------------------------------------------------
    def begin_step(self, t: float, angle_rad, velocity_rad_s, stance):
        self.t_s = t
        si = self.side_index
        for j in range(len(si)):
            s = si[j]
            self._th[j] = angle_rad[s]
            self._thd[j] = velocity_rad_s[s]
            self._cmd[j] = (0.0 if self.torque_fn is None
                            else self.torque_fn(t, self._th[j], self._thd[j]))
        self.k.begin_step(self.Y, self.P, self.W, self.S, self._th, self._thd, self._cmd,
                          self._out)
        for j in range(len(si)):
            self.force2[si[j]] = self._out[j, 0]
            self.damping2[si[j]] = self._out[j, 1]
        return self.force2, self.damping2

    def end_step(self, velocity_new_rad_s):
        si = self.side_index
        for j in range(len(si)):
            self._vnew[j] = velocity_new_rad_s[si[j]]
        if not self.k.finish_all(self.Y, self.P, self.W, self.S, self._vnew, self._tau):
            raise FloatingPointError(
                f"circuit {self.cc.circuit.name!r}: a state became non-finite at t = "
                f"{self.t_s:.4f} s: {dict(zip(self.cc.state_names, self.Y[0].tolist()))}")
        for j in range(len(si)):
            self.delivered2[si[j]] = self._tau[j]
        self.steps += 1
        return self.delivered2

    # -- ledger ----------------------------------------------------------------------------
    def ledger(self, j: int = 0) -> dict:
        """Energy ledger of worn side ``j`` (J): input, mechanical output, every loss and
        store by component instance, and the balance residual."""
        k, W, cc = self.k, self.W[j], self.cc
        losses = {n: float(W[k.W_E_LOSS + i]) for i, n in enumerate(cc.loss_names)}
        stored = {}
        for i, (name, kind) in enumerate(zip(cc.state_names, cc.state_kinds)):
            label = {"pressure": "oil", "speed": "rotor"}.get(kind, "state")
            stored[f"{label}.{name}"] = float(W[k.W_E_STORE + i])
        for i, n in enumerate(cc.srate_names):
            stored[n] = float(W[k.W_E_SRATE + i])
        e_in = float(W[k.W_E_IN])
        e_out = float(W[k.W_E_MECH])
        resid = e_in - e_out - sum(losses.values()) - sum(stored.values())
        scale = max(float(W[k.W_E_ABS_FLOW]), 1e-12)
        return {"input_j": e_in, "input_drawn_j": float(W[k.W_E_IN_DRAWN]),
                "mechanical_out_j": e_out, "losses_j": losses, "stored_change_j": stored,
                "residual_j": resid, "balance_error_rel": resid / scale,
                "energy_throughput_j": scale,
                "heat_to_oil_j": float(W[k.W_HEAT_TO_OIL]),
                "peak_pressure_pa": float(W[k.W_P_MAX]),
                "monitors": {n: float(W[k.W_MON + i]) for i, n in enumerate(cc.monitor_names)},
                "newton_iterations": int(W[k.W_NEWTON_ITERS]),
                "newton_unconverged_steps": int(W[k.W_NEWTON_FAIL]),
                "substepped_steps": int(W[k.W_SUBSTEPPED]),
                "pressure_floor_steps": int(W[k.W_CLIP_STEPS]),
                "coupling_torque_error_rms_nm": float(np.sqrt(W[k.W_COUPLE_SQ]
                                                              / max(self.steps, 1)))}

    # -- replay loops ------------------------------------------------------------------------
    def _log_dict(self, log, n):
        out = {"time_s": log[:n, 0], "angle_rad": log[:n, 1], "velocity_rad_s": log[:n, 2],
               "torque_nm": log[:n, 3], "actuated_input": log[:n, 4]}
        for i, name in enumerate(self.cc.state_names):
            out[name] = log[:n, 5 + i]
        return out

    def run_load(self, command, inertia_kg_m2: float, stiffness_nm_rad: float = 0.0,
                 damping_nm_s_rad: float = 0.0, rest_angle_rad: float = 0.0,
                 theta0_rad: float = 0.0, external_torque_nm=None) -> dict:
        """Drive a simulated load (inertia on a torsional spring and damper) with the
        per-step ``command`` (side 0 only). Returns the logged signals per step."""
        cmd = np.ascontiguousarray(command, dtype=float)
        ext = (np.zeros_like(cmd) if external_torque_nm is None
               else np.ascontiguousarray(external_torque_nm, dtype=float))
        if not inertia_kg_m2 > 0:
            raise CircuitError(f"load inertia_kg_m2 = {inertia_kg_m2!r}; allowed: > 0")
        log = np.zeros((cmd.shape[0], 5 + len(self.cc.state_names)))
        n = self.k.run_load(self.Y[:1], self.P[:1], self.W[:1], self.S[:1], float(theta0_rad),
                            0.0, float(inertia_kg_m2), float(stiffness_nm_rad),
                            float(damping_nm_s_rad), float(rest_angle_rad), cmd, ext, log)
        self.steps += n
        if n < cmd.shape[0]:
            raise FloatingPointError(f"circuit {self.cc.circuit.name!r}: non-finite state "
                                     f"at step {n}")
        return self._log_dict(log, n)

    def run_imposed(self, command, angle_rad, velocity_rad_s) -> dict:
        """Replay with the joint motion imposed (per-step angle and velocity)."""
        cmd = np.ascontiguousarray(command, dtype=float)
        th = np.ascontiguousarray(angle_rad, dtype=float)
        thd = np.ascontiguousarray(velocity_rad_s, dtype=float)
        log = np.zeros((cmd.shape[0], 5 + len(self.cc.state_names)))
        n = self.k.run_imposed(self.Y[:1], self.P[:1], self.W[:1], self.S[:1], th, thd, cmd,
                               log)
        self.steps += n
        if n < cmd.shape[0]:
            raise FloatingPointError(f"circuit {self.cc.circuit.name!r}: non-finite state "
                                     f"at step {n}")
        return self._log_dict(log, n)
