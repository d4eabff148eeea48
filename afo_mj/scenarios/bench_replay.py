"""Replay a measured bench record through a device model: measured inputs in, model outputs out.

On the ankle test stand the ankle angle is imposed (a motor or a position-controlled load
drives it), so the orthosis's hydraulics see the ankle only through the cylinders' kinematics
``x = r θ``, ``ẋ = r θ̇``. The replay therefore needs no multibody step: it drives the device's
compiled kernel (:mod:`afo_mj.devices.pump_ankle_actuator` for the pump-controlled HAFO,
:mod:`afo_mj.devices.valve_ankle_actuator` for the valve circuits) directly with the measured
inputs, sample by sample, in one compiled loop (the kernels' own coupled step: linearly
implicit prediction, Newton-corrected backward Euler, adaptive sub-steps). That is what makes a
calibration, which replays a record hundreds of times, affordable
(``benchmarks/calibrate.py``). ``tests/test_bench_replay.py`` checks the replay against the same
device stepped on the MuJoCo test stand with the same imposed angle.

Inputs (channel names of :data:`afo_mj.analysis.measured_data.CHANNELS`):

* ``ankle_angle_rad`` (required): imposed angle. The velocity is its Savitzky–Golay derivative
  (cubic, 21-sample window: encoder noise is not differentiated into the flow ``A_e r θ̇``).
* ``motor_voltage_v`` (HAFO, open loop: the driver's voltage command), or ``valve_command``
  (valve circuits, open loop: the spool command ``u ∈ [−1, 1]``, or the digital valve's duty);
  or, for either, ``commanded_torque_nm``: the torque reference of the device's own low-level
  torque controller, which then runs in the replay on the model's pressures (closed loop: a
  device tracking a profile on the bench, or in a walk whose measured ankle kinematics are
  replayed as the imposed angle).
* ``fluid_temperature_k`` (optional): the oil temperature, which sets the viscosity
  (Walther, ASTM D341). Without it the temperature is prescribed as ``T_0 + ṫ (t − t_0)``
  (``temperature_rate_k_s``, 0 by default: isothermal at the preset's ambient temperature).

Samples are zero-order held over the step; the step is the record's sample period, split into
equal sub-steps of at most 1 ms when the record is sampled more slowly. Output sample ``k`` is
the state at ``t_k``; sample 0 is the device's initial state (every pressure node at the
reservoir pressure; the valve circuits' supply at its initial pressure).

Transmission effects that act on the kinematics before the hydraulics see them (backlash) are
applied here with :func:`afo_mj.hydraulics.transmission.play_operator`.
"""

from __future__ import annotations

import math
from typing import Mapping

import numba
import numpy as np
from scipy.signal import savgol_filter

from afo_mj.devices import pump_ankle_actuator as pa
from afo_mj.devices import valve_ankle_actuator as va
from afo_mj.devices.hafo import PRESETS as HAFO_PRESETS, HafoDevice, hafo_params
from afo_mj.devices.valve_afo import VALVE_PRESETS, ValveAfoDevice, valve_params
from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.transmission import play_operator

__all__ = ["BenchReplay", "REPLAY_OUTPUTS", "REPLAY_INPUTS", "ReplayError", "kind_of_preset"]


class ReplayError(RuntimeError):
    """The model could not be replayed (a state became non-finite, or inputs are missing)."""


#: output channels each kind of replay produces, in the order of its compiled log
REPLAY_OUTPUTS = {
    "hafo": ("pressure_a_pa", "pressure_b_pa", "chamber_a_pa", "chamber_b_pa",
             "ankle_torque_nm", "motor_current_a", "motor_speed_rad_s", "fluid_temperature_k",
             "battery_current_a", "bus_voltage_v"),
    "valve": ("pump_pressure_pa", "supply_pressure_pa", "pressure_a_pa", "pressure_b_pa",
              "chamber_a_pa", "chamber_b_pa", "valve_position", "ankle_torque_nm",
              "motor_current_a", "motor_speed_rad_s", "fluid_temperature_k"),
}
#: the open-loop command input of each kind (besides the imposed ankle angle)
REPLAY_INPUTS = {"hafo": ("motor_voltage_v", "ankle_angle_rad"),
                 "valve": ("valve_command", "ankle_angle_rad")}
#: the command channels each kind accepts, in order of preference: the open-loop command, or
#: the torque reference of the device's own low-level torque controller (closed loop)
REPLAY_COMMANDS = {"hafo": ("motor_voltage_v", "commanded_torque_nm"),
                   "valve": ("valve_command", "commanded_torque_nm")}

_HAFO_COLS = np.array([pa.Y_PPA, pa.Y_PPB, pa.Y_PCA, pa.Y_PCB], dtype=np.int64)
_VALVE_COLS = np.array([va.Y_PP, va.Y_PS, va.Y_PVA, va.Y_PVB, va.Y_PCA, va.Y_PCB, va.Y_XV],
                       dtype=np.int64)


def kind_of_preset(preset: str) -> str:
    """``"hafo"`` for a pump-controlled preset, ``"valve"`` for a valve circuit's."""
    if preset in HAFO_PRESETS:
        return "hafo"
    if preset in VALVE_PRESETS:
        return "valve"
    raise ParameterError(f"source.preset = {preset!r}; allowed: "
                         f"{', '.join(list(HAFO_PRESETS) + list(VALVE_PRESETS))}")


@numba.njit(cache=True)
def _replay_pump(Y, P, W, S, theta, theta_dot, u, temp_k, sub, out):
    """Step the HAFO kernel through the record; returns the number of samples filled (less
    than ``len(theta)`` when a state became non-finite)."""
    n = theta.shape[0]
    th = np.empty(1)
    thd = np.empty(1)
    cmd = np.empty(1)
    o = np.empty((1, 2))
    tau = np.empty(1)
    vnew = np.empty(1)
    _log_pump(Y, W, temp_k[0], out, 0)
    for k in range(n - 1):
        for j in range(sub):
            f0 = j / sub
            f1 = (j + 1) / sub
            W[0, pa.W_TEMP_K] = temp_k[k] + f0 * (temp_k[k + 1] - temp_k[k])
            th[0] = theta[k] + f0 * (theta[k + 1] - theta[k])
            thd[0] = theta_dot[k] + f0 * (theta_dot[k + 1] - theta_dot[k])
            cmd[0] = u[k]
            pa.begin_step(Y, P, W, S, th, thd, cmd, o)
            vnew[0] = theta_dot[k] + f1 * (theta_dot[k + 1] - theta_dot[k])
            if not pa.finish_all(Y, P, W, S, vnew, tau):
                return k + 1
        _log_pump(Y, W, temp_k[k + 1], out, k + 1)
    return n


@numba.njit(cache=True)
def _log_pump(Y, W, temp, out, k):
    out[k, 0] = Y[0, pa.Y_PPA]
    out[k, 1] = Y[0, pa.Y_PPB]
    out[k, 2] = Y[0, pa.Y_PCA]
    out[k, 3] = Y[0, pa.Y_PCB]
    out[k, 4] = W[0, pa.W_TAU_END]
    out[k, 5] = Y[0, pa.Y_I]
    out[k, 6] = Y[0, pa.Y_W]
    out[k, 7] = temp
    out[k, 8] = W[0, pa.W_I_BAT]
    out[k, 9] = W[0, pa.W_V_BUS]


@numba.njit(cache=True)
def _replay_valve(Y, P, W, S, theta, theta_dot, u, temp_k, sub, t0, h, out):
    """Step the valve kernel through the record (see :func:`_replay_pump`)."""
    n = theta.shape[0]
    th = np.empty(1)
    thd = np.empty(1)
    cmd = np.empty(1)
    o = np.empty((1, 2))
    tau = np.empty(1)
    vnew = np.empty(1)
    _log_valve(Y, W, temp_k[0], out, 0)
    for k in range(n - 1):
        for j in range(sub):
            f0 = j / sub
            f1 = (j + 1) / sub
            W[0, va.W_TEMP_K] = temp_k[k] + f0 * (temp_k[k + 1] - temp_k[k])
            th[0] = theta[k] + f0 * (theta[k + 1] - theta[k])
            thd[0] = theta_dot[k] + f0 * (theta_dot[k + 1] - theta_dot[k])
            cmd[0] = u[k]
            va.begin_step(Y, P, W, S, th, thd, cmd, o, t0 + (k * sub + j) * h)
            vnew[0] = theta_dot[k] + f1 * (theta_dot[k + 1] - theta_dot[k])
            if not va.finish_all(Y, P, W, S, vnew, tau):
                return k + 1
        _log_valve(Y, W, temp_k[k + 1], out, k + 1)
    return n


@numba.njit(cache=True)
def _log_valve(Y, W, temp, out, k):
    out[k, 0] = Y[0, va.Y_PP]
    out[k, 1] = Y[0, va.Y_PS]
    out[k, 2] = Y[0, va.Y_PVA]
    out[k, 3] = Y[0, va.Y_PVB]
    out[k, 4] = Y[0, va.Y_PCA]
    out[k, 5] = Y[0, va.Y_PCB]
    out[k, 6] = Y[0, va.Y_XV]
    out[k, 7] = W[0, va.W_TAU_END]
    out[k, 8] = Y[0, va.Y_I]
    out[k, 9] = Y[0, va.Y_W]
    out[k, 10] = temp


def ankle_velocity(theta_rad: np.ndarray, dt_s: float) -> np.ndarray:
    """Savitzky–Golay (1964) derivative of the imposed angle: a cubic fitted over 21 samples
    (fewer for short records), evaluated at the window centre."""
    n = len(theta_rad)
    win = min(21, n - (1 - n % 2))
    if win < 5:
        return np.gradient(theta_rad, dt_s)
    return savgol_filter(theta_rad, win, 3, deriv=1, delta=dt_s, mode="interp")


class BenchReplay:
    """A device preset (with dotted-name ``overrides``) ready to replay records.

    ``kind`` is ``"hafo"`` or ``"valve"`` (default: from the preset). The kernel's parameter
    row is :attr:`base_row`; :meth:`simulate` takes per-run changes to it by index
    (``P_*`` of the kernel module :attr:`kernel`), which is how the calibration sets fitted
    parameters and switches effects on without rebuilding the device.
    """

    def __init__(self, preset: str, overrides: Mapping[str, object] | None = None,
                 kind: str | None = None):
        self.preset = preset
        self.kind = kind or kind_of_preset(preset)
        if self.kind == "hafo":
            params = hafo_params(dict(overrides or {}), preset)
            dev = HafoDevice(params, mode="voltage", torque_fn=lambda t, a, v: 0.0)
            self.kernel = pa
        elif self.kind == "valve":
            params = valve_params(dict(overrides or {}), preset)
            dev = ValveAfoDevice(params, mode="valve_command", torque_fn=lambda t, a, v: 0.0)
            self.kernel = va
        else:
            raise ParameterError(f"kind = {self.kind!r}; allowed: hafo, valve")
        self.params = params
        self._buf0 = dev._buf.copy()
        self._meta = dev._meta
        self._dev = dev
        self.base_row = dev.P[0].copy()
        self.outputs = REPLAY_OUTPUTS[self.kind]
        self.inputs = REPLAY_INPUTS[self.kind]
        self.ambient_temperature_k = float(params.ambient_temperature_k)
        self.max_step_s = 1e-3

    def check_inputs(self, channels) -> tuple[str, str]:
        """The record's command channel and the imposed angle: ``(command, "ankle_angle_rad")``
        (the open-loop command when the record has it, else ``commanded_torque_nm``)."""
        cmds = [c for c in REPLAY_COMMANDS[self.kind] if c in channels]
        if not cmds or "ankle_angle_rad" not in channels:
            raise ReplayError(f"the {self.kind} bench replay needs ankle_angle_rad and one of "
                              f"{list(REPLAY_COMMANDS[self.kind])}; the record has "
                              f"{sorted(channels)}")
        return cmds[0], "ankle_angle_rad"

    def simulate(self, time_s: np.ndarray, inputs: Mapping[str, np.ndarray],
                 row_changes: Mapping[int, float] | None = None, backlash_rad: float = 0.0,
                 temperature_rate_k_s: float = 0.0) -> dict[str, np.ndarray]:
        """Replay: the model's output channels (:data:`REPLAY_OUTPUTS`) at ``time_s``.

        ``row_changes``: kernel parameter row entries to set for this run (index → value);
        ``backlash_rad``: total play of the cable on the pulley; ``temperature_rate_k_s``: oil
        temperature drift when the record has no temperature input. Raises
        :class:`ReplayError` when a state becomes non-finite (never returns NaN)."""
        cmd_name = self.check_inputs(inputs)[0]
        t = np.asarray(time_s, dtype=float)
        n = len(t)
        dt = float(np.median(np.diff(t)))
        sub = max(1, int(math.ceil(dt / self.max_step_s - 1e-9)))
        h = dt / sub
        theta = np.ascontiguousarray(inputs["ankle_angle_rad"], dtype=float)
        if backlash_rad > 0.0:
            theta = play_operator(theta, backlash_rad)
        theta_dot = ankle_velocity(theta, dt)
        u = np.ascontiguousarray(inputs[cmd_name], dtype=float)
        if "fluid_temperature_k" in inputs:
            temp = np.ascontiguousarray(inputs["fluid_temperature_k"], dtype=float)
        else:
            temp = self.ambient_temperature_k + temperature_rate_k_s * (t - t[0])
        buf = self._buf0.copy()
        K = self.kernel
        Y, P, W, S = K.device_views(buf, self._meta)[:4]
        K_open = pa.MODE_VOLTAGE if self.kind == "hafo" else va.MODE_VALVE_COMMAND
        P[0, K.P_MODE] = K_open if cmd_name != "commanded_torque_nm" else K.MODE_TORQUE
        if row_changes:
            for i, v in row_changes.items():
                P[0, i] = v
        S[0, 0, 0] = h
        W[0, K.W_TEMP_K] = temp[0]
        out = np.zeros((n, len(self.outputs)))
        if self.kind == "hafo":
            filled = _replay_pump(Y, P, W, S, theta, theta_dot, u, temp, sub, out)
        else:
            filled = _replay_valve(Y, P, W, S, theta, theta_dot, u, temp, sub, float(t[0]), h,
                                   out)
        if filled < n or not np.all(np.isfinite(out)):
            bad = min(filled, n - 1)
            raise ReplayError(f"{self.kind} replay ({self.preset}) became non-finite at "
                              f"t = {t[bad]:.4f} s (sample {bad}); parameters "
                              f"{dict(row_changes or {})}")
        return {name: out[:, j] for j, name in enumerate(self.outputs)}
