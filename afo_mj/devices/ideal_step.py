"""The ideal orthosis's step in compiled code: the one implementation of its laws, called from
Python (:class:`afo_mj.devices.ideal.IdealDevice`'s ``begin_step``/``end_step``) and, by
address, from the compiled walk loops (:mod:`afo_mj.gait.controller_loop`,
:mod:`afo_mj.gait.walk_loop`).

The device's whole state lives in one float64 buffer and one int64 layout (``meta``), as a
generated circuit's does (:mod:`afo_mj.circuits.native_entry`), so the two C entry points
here have that module's signatures and a compiled loop steps the ideal device exactly as it
steps a worn circuit:

``begin(t, angle2*, velocity2*, stance2*, buf*, meta*)`` (``void``)
    :func:`ideal_begin`: per worn side the gait phase from the foot switch
    (:func:`afo_mj.control.assistance.phase_update`) and the command of the device's mode —
    the profile (:func:`afo_mj.control.assistance.table_lookup`, only in stance), the
    impedance rows (:func:`afo_mj.control.impedance.impedance_torque`) or the clutched
    spring (:func:`clutch_stretch`, ``τ = −K·stretch``) — times the ramp gain
    ``min(1, strides measured / ramp_strides)``; none: transparent, zero.
``end(velocity2*, buf*, meta*, log*, n_log, n_fields, n_sides, k, t)`` (``int64``)
    :func:`ideal_end`: the delivered torque is the command; the work ``τ·q̇ₙ₊₁·h`` (MuJoCo's
    semi-implicit Euler moves the ankle by ``h·q̇ₙ₊₁``) goes to the positive or negative
    ledger, the peak torque on, and row ``k`` of the log (fields
    :data:`afo_mj.devices.ideal.LOG_FIELDS`) is written while ``k < n_log``; returns 0 when a
    torque is not finite, 2 when logged, else 1.

The entry points are compiled (or loaded from numba's cache, :mod:`afo_mj.numba_cache`) on
the first use of their addresses, so a walk that steps the device in Python compiles only the
two kernels.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import carray, types

from afo_mj.control import assistance as asst
from afo_mj.control.impedance import impedance_torque
from afo_mj.numba_cache import cached_cfunc, cached_njit

__all__ = ["LOG_FIELDS", "MODE_TRANSPARENT", "MODE_PROFILE", "MODE_IMPEDANCE", "MODE_SPRING",
           "new_buffer", "ideal_begin", "ideal_end", "clutch_stretch", "entry_addresses"]

#: what the device commands (``meta[M_MODE]``)
MODE_TRANSPARENT, MODE_PROFILE, MODE_IMPEDANCE, MODE_SPRING = 0, 1, 2, 3

# buffer (float64): the time the present step began, the timestep, the phase estimator's
# stride limits, the ramp (strides), the spring's stiffness and phases; then per walker side
# (two each): joint force, extra damping (always 0), delivered torque, command, phase, angle
# and stance at the step's start, the clutch's engagement angle (NaN while open) and whether
# it engaged in this stance (0/1); the phase estimators (2 × N_PH); per worn side the
# positive and negative work (J) and the peak |torque| (N·m); the profile or impedance table
B_T, B_H, B_LO, B_HI, B_RAMP, B_K, B_ENGAGE, B_RELEASE = range(8)
B_FORCE, B_DAMP, B_DELIV, B_CMD, B_PHASE, B_ANGLE, B_STANCE, B_TH_ENG, B_USED = range(8, 26, 2)
B_PH = 26
B_POS = B_PH + 2 * asst.N_PH
B_NEG = B_POS + 2
B_PEAK = B_NEG + 2
B_TABLE = B_PEAK + 2
# layout (int64): buffer length, worn sides, mode, ratchet (0/1), table length, the worn
# sides' walker-side indices (two slots)
M_END, M_NS, M_MODE, M_RATCHET, M_TABLE_N, M_SIDES = range(6)
N_META = M_SIDES + 2

#: the log's columns per worn side (:data:`afo_mj.devices.ideal.LOG_FIELDS`)
LOG_FIELDS = ("time_s", "commanded_torque_nm", "delivered_torque_nm", "measured_torque_nm",
              "phase", "stance", "mechanical_power_w", "ankle_velocity_rad_s",
              "ankle_angle_rad", "command_angle_rad", "clutch_engaged", "engaged_angle_rad")
(_T, _CMD, _DLV, _MEAS, _PH, _ST, _PW, _VEL, _ANG, _CANG, _ENG, _EANG) = range(len(LOG_FIELDS))


def new_buffer(side_index, mode: int, table, timestep_s: float, min_stride_s: float,
               max_stride_s: float, ramp_strides: int, stiffness_nm_per_rad: float = 0.0,
               engage_phase: float = 0.0, release_phase: float = 0.0,
               ratchet: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The buffer and layout of a fresh device (module docstring): no stride measured (phase
    −1), clutch open, ledger empty; ``table`` the profile or packed impedance rows (None for
    the spring or transparent)."""
    tab = np.zeros(0) if table is None else np.ascontiguousarray(table, dtype=float)
    buf = np.zeros(B_TABLE + tab.size)
    buf[B_H], buf[B_LO], buf[B_HI] = timestep_s, min_stride_s, max_stride_s
    buf[B_RAMP] = float(ramp_strides)
    buf[B_K], buf[B_ENGAGE], buf[B_RELEASE] = stiffness_nm_per_rad, engage_phase, release_phase
    buf[B_PHASE:B_PHASE + 2] = -1.0
    buf[B_TH_ENG:B_TH_ENG + 2] = np.nan
    buf[B_PH:B_POS] = asst.new_phase_state(2).ravel()
    buf[B_TABLE:] = tab
    meta = np.zeros(N_META, dtype=np.int64)
    meta[M_END], meta[M_NS], meta[M_MODE] = buf.size, len(side_index), mode
    meta[M_RATCHET], meta[M_TABLE_N] = int(bool(ratchet)), tab.size
    meta[M_SIDES:M_SIDES + len(side_index)] = side_index
    return buf, meta


@numba.njit(inline="always", _nrt=False)
def clutch_stretch(buf, ratchet, s, ph, stance, theta):  # pragma: no cover - compiled
    """The clutched spring of walker side ``s`` (Collins, Wiggin & Sawicki 2015; see
    :class:`afo_mj.devices.ideal.ClutchedSpring`): its dorsiflexion past the engagement angle
    (rad, ≥ 0; 0 while the clutch is open: the engagement angle ``buf[B_TH_ENG + s]`` is NaN
    then). The clutch opens in swing, with no stride
    estimate and past ``release_phase``; it engages once per stance at the first step whose
    phase reaches ``engage_phase``, slack at that step's angle; with ``ratchet`` an ankle
    that plantarflexes below the engagement angle moves it down (a ratchet and pawl)."""
    if not stance or ph < 0.0 or ph > buf[B_RELEASE]:
        buf[B_TH_ENG + s] = np.nan
        if not stance:
            buf[B_USED + s] = 0.0
        return 0.0
    if math.isnan(buf[B_TH_ENG + s]) and buf[B_USED + s] == 0.0 and ph >= buf[B_ENGAGE]:
        buf[B_TH_ENG + s] = theta          # engages slack, at foot flat
        buf[B_USED + s] = 1.0
    if math.isnan(buf[B_TH_ENG + s]):
        return 0.0
    if ratchet and theta < buf[B_TH_ENG + s]:
        buf[B_TH_ENG + s] = theta          # the ratchet takes up the slack
    return max(theta - buf[B_TH_ENG + s], 0.0)


@cached_njit(depends_on=("afo_mj.control.assistance", "afo_mj.control.impedance"),
             fastmath=False, _nrt=False)
def ideal_begin(t, angle2, velocity2, stance2, buf, meta):  # pragma: no cover - compiled
    """Begin a step at ``t`` (module docstring): per worn side the phase and the command,
    into the buffer's joint force (the damping stays 0). Arguments per walker side (length
    2, float64; stance 1.0/0.0)."""
    buf[B_T] = t
    lo = buf[B_LO]
    hi = buf[B_HI]
    ramp = buf[B_RAMP]
    mode = meta[M_MODE]
    ratchet = meta[M_RATCHET] != 0
    table = buf[B_TABLE:B_TABLE + meta[M_TABLE_N]]
    buf[B_FORCE] = 0.0
    buf[B_FORCE + 1] = 0.0
    for j in range(meta[M_NS]):
        s = meta[M_SIDES + j]
        on = stance2[s] != 0.0
        th = angle2[s]
        buf[B_ANGLE + s] = th
        buf[B_STANCE + s] = 1.0 if on else 0.0
        st = buf[B_PH + s * asst.N_PH:B_PH + (s + 1) * asst.N_PH]
        ph = asst.phase_update(st, t, on, lo, hi)
        buf[B_PHASE + s] = ph
        gain = 1.0
        if ramp != 0.0:
            gain = min(1.0, st[asst.PH_N] / ramp)
        if mode == MODE_SPRING:
            stretch = clutch_stretch(buf, ratchet, s, ph, on, th)
            if not math.isnan(buf[B_TH_ENG + s]):
                buf[B_FORCE + s] = -gain * buf[B_K] * stretch
        elif mode == MODE_PROFILE:
            # only while the foot switch reads stance: a stride estimate that lags a short
            # stride would otherwise push a swinging foot
            buf[B_FORCE + s] = gain * asst.table_lookup(table, ph) if on else 0.0
        elif mode == MODE_IMPEDANCE:
            buf[B_FORCE + s] = gain * impedance_torque(table, ph, th, velocity2[s])
    buf[B_CMD] = buf[B_FORCE]
    buf[B_CMD + 1] = buf[B_FORCE + 1]


@numba.njit(fastmath=False, _nrt=False, cache=True)
def ideal_end(velocity2, buf, meta, log, k, t):  # pragma: no cover - compiled
    """End step ``k`` at ``t`` with the ankle velocities MuJoCo produced (module docstring);
    ``log`` ``(n_log, fields, worn sides)``. Returns 0 (a non-finite torque), 1 or 2
    (logged)."""
    h = buf[B_H]
    buf[B_DELIV] = buf[B_FORCE]
    buf[B_DELIV + 1] = buf[B_FORCE + 1]
    logged = k < log.shape[0]
    ok = True
    for j in range(meta[M_NS]):
        s = meta[M_SIDES + j]
        v = velocity2[s]
        tau = buf[B_DELIV + s]
        if not math.isfinite(tau):
            ok = False
        # MuJoCo's semi-implicit Euler moves the ankle by h·q̇_{n+1} under this torque
        w = tau * v * h
        if w > 0.0:
            buf[B_POS + j] += w
        else:
            buf[B_NEG + j] += w
        buf[B_PEAK + j] = max(buf[B_PEAK + j], abs(tau))
        if logged:
            te = buf[B_TH_ENG + s]
            eng = not math.isnan(te)
            ang = buf[B_ANGLE + s]
            log[k, _T, j] = t
            log[k, _CMD, j] = buf[B_CMD + s]
            log[k, _DLV, j] = tau
            log[k, _MEAS, j] = tau
            log[k, _PH, j] = buf[B_PHASE + s]
            log[k, _ST, j] = buf[B_STANCE + s]
            log[k, _PW, j] = tau * v
            log[k, _VEL, j] = v
            log[k, _ANG, j] = ang + h * v
            log[k, _CANG, j] = ang
            log[k, _ENG, j] = 1.0 if eng else 0.0
            log[k, _EANG, j] = te if eng else 0.0
    if not ok:
        return 0
    return 2 if logged else 1


_F = types.CPointer(types.float64)
_I = types.CPointer(types.int64)
_DEPS = ("afo_mj.control.assistance", "afo_mj.control.impedance")


@cached_cfunc(types.void(types.float64, _F, _F, _F, _F, _I), depends_on=_DEPS,
              error_model="numpy")
def _begin_c(t, angle2, velocity2, stance2, buf, meta):  # pragma: no cover - compiled
    m = carray(meta, (N_META,))
    ideal_begin(t, carray(angle2, (2,)), carray(velocity2, (2,)), carray(stance2, (2,)),
                carray(buf, (m[M_END],)), m)


@cached_cfunc(types.int64(_F, _F, _I, _F, types.int64, types.int64, types.int64, types.int64,
                          types.float64), depends_on=_DEPS, error_model="numpy")
def _end_c(velocity2, buf, meta, log, n_log, n_fields, n_sides, k, t):  # pragma: no cover
    m = carray(meta, (N_META,))
    return ideal_end(carray(velocity2, (2,)), carray(buf, (m[M_END],)), m,
                     carray(log, (n_log, n_fields, n_sides)), k, t)


def entry_addresses() -> tuple[int, int]:
    """The ``begin`` and ``end`` C entry points' addresses (compiled or loaded on first use)."""
    return int(_begin_c.address), int(_end_c.address)
