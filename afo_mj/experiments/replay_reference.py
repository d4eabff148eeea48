"""The bench replay's numerical check: the same described circuit, on the same record inputs,
integrated by scipy's ``solve_ivp(method="Radau")`` at a tight tolerance.

The replay (:meth:`afo_mj.experiments.bench_replay.BenchReplay.simulate`) steps the circuit with
the one compiled stepper (:mod:`afo_mj.circuits.stepper`: linearly implicit prediction,
Newton-corrected backward Euler, sub-steps of at most ``max_step_s``) and, with a simulated
load, integrates the load by semi-implicit Euler with the circuit's end-of-step torque. Its
own discretisation error is part of every residual a calibration sees. This module integrates
the same equations as an ODE with error control, so that the difference between the two is
the stepper's error alone: a check, not a fit (nothing here is adjusted to the record).

What is integrated
------------------
The state is the circuit's states ``y`` (node pressures, shaft speeds, currents), then, with a
simulated load, the joint angle and velocity, then one state per value the circuit holds from
a step's end (:meth:`afo_mj.circuits.codegen.Emitter.held`). The right-hand side is the
circuit's generated ``rhs_step(y, y, θ, θ̇, U, P, dy, F)``: with ``y_old = y`` each node's
compliance is the tangent ``1/B(p)``, i.e. the ODE whose backward-Euler discretisation the
stepper solves (``stepper_globals.rhs_step``). The held inputs ``U`` are set as the stepper sets
them before each step (:func:`afo_mj.circuits.stepper.hold_inputs`: the joint motion, the
viscosity, density and bus voltage from the oil temperature by ``begin_extra``, the
controller's actuation from the command), and an open-loop command is written over the
controller's ``command`` input as the replay writes it. The load is the replay's
:class:`~afo_mj.circuits.device.JointLoad`, ``J θ̈ = τ − k (θ − θ_r) − c θ̇`` (Newton's
second law), with ``τ`` the circuit's joint torque ``F[F_TAU]``.

A held value ``g`` (e.g. a series cable's force other than the hydraulic one, whose stretch
rate the cylinder writes as the difference quotient ``(S(f) − S(g))·U_INV_H`` over a step)
has no continuous-time form in the generated code. Here it becomes a first-order lag,
``ġ = (f − g)/τ_h`` with ``U_INV_H = 1/τ_h`` and ``τ_h`` = :data:`HELD_LAG_S`: then
``(S(f) − S(g))/τ_h ≈ d S(g)/dt``, the derivative of the value lagged by ``τ_h`` (10 µs,
fifty times shorter than the replay's sub-step); the lag is stiff and Radau, being L-stable,
takes it in its stride.

Inputs are held as the replay holds them (:data:`afo_mj.experiments.bench_replay.HOLDS`): the
imposed angle, its velocity and the oil temperature linear between samples; the command held
over each interval (``zero_order``) or linear between samples (``linear``: the continuous
signal the replay's mid-point sub-steps approximate). The integration restarts at every sample
instant (a held command steps there), each interval one ``solve_ivp`` call from the last
state; the outputs are read at the end of each interval (the stepper's log convention), the
probes and the joint torque from ``F`` at that state and interval's inputs.

Limits, each refused with its reason (:class:`ReferenceUnavailable`) rather than run: a torque
reference (the device's own torque controller is a discrete-time element stepped with the
replay, with slots the ODE has no form for) and a controller with internal slots. Output
channels that are neither states, probes, the joint torque nor the load's angle (the battery
current, the bus voltage: the stepper's per-step bookkeeping) are listed as not compared. The
stepper raises a pressure below the vapour floor to it (``clip_floor``); the ODE does not, so
a run that reaches the floor differs there by construction (reported: ``below_floor_samples``).

Method: Radau IIA of order 5 with error control (Hairer & Wanner, *Solving Ordinary
Differential Equations II*, 2nd ed., 1996, §IV.8; scipy's implementation).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Mapping

import numpy as np
from scipy.integrate import solve_ivp

from afo_mj.circuits.device import CircuitDevice
from afo_mj.experiments.bench_replay import BenchReplay, ReplayError
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA

__all__ = ["reference_replay", "ReferenceRun", "ReferenceUnavailable", "HELD_LAG_S",
           "REFERENCE_RTOL"]

#: time constant of the lag that stands for a value held from a step's end, s
HELD_LAG_S = 1e-5
#: default relative tolerance of the Radau integration
REFERENCE_RTOL = 1e-8
#: typical sizes of the load's angle [rad] and velocity [rad/s] and of a held value, for the
#: absolute tolerances (``rtol`` times these)
_THETA_TYP, _THETA_DOT_TYP, _HELD_TYP = 0.1, 1.0, 1.0


class ReferenceUnavailable(ReplayError):
    """The replay cannot be checked by the Radau reference (the reason names what)."""


@dataclasses.dataclass(frozen=True)
class ReferenceRun:
    """A reference replay: its output channels, those it could not compare and why, and
    its cost."""

    outputs: dict                   #: channel → samples, as :meth:`BenchReplay.simulate`
    not_compared: dict              #: channel → reason
    rhs_evaluations: int
    wall_s: float
    below_floor_samples: int        #: samples with a pressure below the vapour floor
    rtol: float


def reference_replay(replay: BenchReplay, time_s, inputs: Mapping[str, np.ndarray],
                     row_changes: Mapping[str, float] | None = None,
                     backlash_rad: float = 0.0, temperature_rate_k_s: float = 0.0,
                     rtol: float = REFERENCE_RTOL) -> ReferenceRun:
    """The replay of ``inputs`` at ``time_s`` (arguments as :meth:`BenchReplay.simulate`)
    integrated by Radau at relative tolerance ``rtol`` (module docstring). Raises
    :class:`ReferenceUnavailable` for a run it cannot reproduce, :class:`ReplayError` when the
    integration fails."""
    if not (isinstance(rtol, float) and 1e-12 <= rtol <= 1e-4):
        raise ValueError(f"rtol = {rtol!r}; allowed: a float in [1e-12, 1e-4]")
    t_wall = time.perf_counter()
    run = replay.prepare(time_s, inputs, row_changes, backlash_rad, temperature_rate_k_s)
    if not run.open_loop:
        raise ReferenceUnavailable(
            f"the numerical check integrates an open-loop command; {run.command_channel} is "
            "the reference of the device's own torque controller, a discrete-time element "
            "stepped with the replay")
    dev = CircuitDevice(replay.cc, timestep_s=run.dt_s / run.substeps)
    for label, v in replay.initial_state.items():
        dev.Y[0, replay.cc.index(label)] = v
    for label, v in run.changes.items():
        dev.P[0, replay.index(label)] = v
    m = dev.k
    if m.N_CTRL > 0:
        raise ReferenceUnavailable(
            f"the circuit {replay.cc.circuit.name!r}'s controller keeps {m.N_CTRL} internal "
            "slot(s) (a discrete-time state); the numerical check needs a memoryless one")
    P = np.array(dev.P[0])
    W0 = np.array(dev.W[0])
    ny, nh = int(m.N_Y), int(m.N_HELD)
    load = run.load
    nl = 2 if load is not None else 0
    f_held = int(m.N_F) - nh
    u_held = int(m.N_U_HEAD) + int(m.N_INPUT)
    h = run.dt_s / run.substeps
    t = run.time_s
    u, th_in, thd_in, temp = run.command, run.theta, run.theta_dot, run.temperature_k
    linear = run.hold == "linear"
    W = W0.copy()
    dy = np.zeros(ny)
    F = np.zeros(dev.S.shape[2])
    counter = [0]

    def evaluate(tt: float, z: np.ndarray, i: int) -> np.ndarray:
        """The right-hand side at ``tt`` in sample interval ``i`` (inputs held as the
        replay holds them); leaves ``F`` filled."""
        counter[0] += 1
        s = (tt - t[i]) / (t[i + 1] - t[i])
        y = z[:ny]
        if load is not None:
            th, thd = float(z[ny]), float(z[ny + 1])
        else:
            th = th_in[i] + s * (th_in[i + 1] - th_in[i])
            thd = thd_in[i] + s * (thd_in[i + 1] - thd_in[i])
        cmd = u[i] + s * (u[i + 1] - u[i]) if linear else u[i]
        W[:] = W0
        W[m.W_TEMP_K] = temp[i] + s * (temp[i + 1] - temp[i])
        W[m.W_THETA] = th
        W[m.W_THETA_DOT] = thd
        m.begin_extra(y, P, W)
        W[m.W_CMD] = cmd
        W[m.W_U] = m.controller(y, th, thd, cmd, h, P, W)
        if run.imposed:
            W[m.W_U] = cmd                          # the "command" input's slot, U_CMD
        U = W[m.W_U:m.W_U + m.N_U]
        if nh:
            U[m.U_INV_H] = 1.0 / HELD_LAG_S
            U[u_held:u_held + nh] = z[ny + nl:]
        m.rhs_step(y, y, th, thd, U, P, dy, F)
        out = np.empty(ny + nl + nh)
        out[:ny] = dy
        if load is not None:
            out[ny] = thd
            out[ny + 1] = (F[m.F_TAU] - load.stiffness_nm_rad * (th - load.rest_angle_rad)
                           - load.damping_nm_s_rad * thd) / load.inertia_kg_m2
        if nh:
            out[ny + nl:] = (F[f_held:f_held + nh] - z[ny + nl:]) / HELD_LAG_S
        return out

    z = np.concatenate([np.array(dev.Y[0]),
                        [] if load is None else [load.initial_angle_rad,
                                                 load.initial_velocity_rad_s],
                        np.zeros(nh)])
    atol = rtol * np.concatenate([np.asarray(m.Y_TYP, dtype=float),
                                  [_THETA_TYP, _THETA_DOT_TYP][:nl], np.full(nh, _HELD_TYP)])
    names = list(replay.cc.state_names)
    probes = list(replay.cc.probe_names)
    n = len(t)
    log = {k: np.empty(n - 1) for k in names + probes + ["torque_nm", "angle_rad"]}
    p_rows = [k for k, kind in enumerate(replay.cc.state_kinds) if kind == "pressure"]
    floor = float(replay.cc.circuit.fluid.pressure_floor_pa) - ATMOSPHERIC_PRESSURE_PA
    below = 0
    for i in range(n - 1):
        sol = solve_ivp(evaluate, (float(t[i]), float(t[i + 1])), z, method="Radau",
                        rtol=rtol, atol=atol, args=(i,), first_step=float(t[i + 1] - t[i]))
        if not sol.success or not np.all(np.isfinite(sol.y[:, -1])):
            raise ReplayError(f"Radau reference of {replay.preset!r} failed in the interval "
                              f"{t[i]:g}–{t[i + 1]:g} s: {sol.message}")
        z = sol.y[:, -1]
        evaluate(float(t[i + 1]), z, i)
        for k, name in enumerate(names):
            log[name][i] = z[k]
        for k, name in enumerate(probes):
            log[name][i] = F[m.F_PROBE + k]
        log["torque_nm"][i] = F[m.F_TAU]
        log["angle_rad"][i] = z[ny] if load is not None else th_in[i + 1]
        if p_rows and min(z[k] for k in p_rows) < floor:
            below += 1
    channels, skipped = [], {}
    for c in replay.outputs:
        sig = replay.signal_of(c)
        if sig is None or sig in log:
            channels.append(c)
        else:
            skipped[c] = (f"{sig} is the stepper's per-step bookkeeping, not a state, probe "
                          "or joint torque of the circuit's equations")
    out = replay.outputs_of(log, temp, load, row_changes, channels=channels)
    return ReferenceRun(out, skipped, counter[0], time.perf_counter() - t_wall, below,
                        float(rtol))
