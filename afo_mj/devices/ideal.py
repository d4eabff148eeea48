"""An ideal ankle orthosis: it delivers exactly the torque it commands.

No actuator, no hydraulics, no controller dynamics: each step the joint torque on every worn
ankle is the command, set from the state at the step's start (``begin_step``), and
``end_step`` returns that same torque. What it commands (:class:`IdealDevice`):

* a tabulated torque profile against the gait phase (``profile``: the Zhang et al. 2017
  profile of ``[assistance]``, :func:`afo_mj.control.assistance.zhang_profile`, or a spline),
  applied only while the foot switch reads stance;
* an emulated spring/damper (``impedance``: rows of
  :func:`afo_mj.control.impedance.impedance_table`, torque by
  :func:`~afo_mj.control.impedance.impedance_torque`), over the whole stride as the circuit
  devices emulate it;
* a clutched spring (``spring``, :class:`ClutchedSpring`; Collins, Wiggin & Sawicki 2015,
  *Nature* 522:212): the clutch engages once per stance, at ``engage_phase`` of the stride,
  with the spring slack at the ankle angle of that moment; it then resists dorsiflexion past
  that angle with ``stiffness_nm_per_rad`` and opens at toe off or past ``release_phase``.
  With ``ratchet`` the engaged clutch takes up slack as a ratchet and pawl does: an ankle
  that plantarflexes further moves the slack angle down with it, so the spring stretches
  from the stance's lowest angle after engagement (a clutch engaged early, before foot flat,
  then still catches the whole loaded dorsiflexion; :mod:`afo_mj.experiments.
  spring_mechanics` measures what a fixed-phase engagement misses);
* nothing (transparent): zero torque, the worn mass alone.

The gait phase comes from the foot switch exactly as on the circuit devices (the HAFO's
controller): :func:`afo_mj.control.assistance.phase_update` per side (heel strike = rising
edge of stance, phase = time since heel strike / mean of the last measured strides within
``[min_stride_s, max_stride_s]``, −1 until a stride has been measured: no torque), and
:func:`afo_mj.control.assistance.table_lookup` on the profile.

The optional worn mass (``IdealAnkleParams.mass_kg``) sits at the ankle axis of each worn side.

The ledger is that of an ideal source (100 % efficient both ways, no store, no loss): the
electrical energy drawn is the positive mechanical work delivered to the ankle, the energy
regenerated the negative work absorbed from it, so input = mechanical output and the balance
error is zero; no pressure, no temperature, no battery, no Newton iterations. For a clutched
spring the same book applies: what the spring absorbs counts as regenerated and what it
returns as drawn.

Each law is written once, in compiled code (:mod:`afo_mj.devices.ideal_step`): ``begin_step``
and ``end_step`` call those kernels from Python, and :meth:`IdealDevice.native_coupling` gives
their C entry points to the compiled walk loops (the muscle walker's
:mod:`afo_mj.gait.controller_loop`, the torque walker's :mod:`afo_mj.gait.walk_loop`), which
step the device as they step a worn circuit, with no Python per step.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from afo_mj.circuits.device import CircuitLog
from afo_mj.control import assistance as asst
from afo_mj.control.impedance import impedance_table
from afo_mj.devices import ideal_step as kern
from afo_mj.hydraulics.params import (ParameterError, Parameters, effect, param,
                                       replace_named)
from afo_mj.human.walker import WornMass

__all__ = ["IdealAnkleParams", "ClutchedSpring", "IdealDevice", "IDEAL", "PRESETS",
           "ideal_params", "LOG_FIELDS"]

SIDE_NAMES = ("right", "left")


@dataclasses.dataclass(frozen=True)
class IdealAnkleParams(Parameters):
    """The ideal orthosis: its worn mass and the limits of its gait-phase estimator."""

    mass_kg: float = param(0.0, unit="kg", lo=0.0, hi=10.0,
                           doc="mass worn at the ankle axis, per worn side")
    min_stride_s: float = param(0.4, unit="s", lo=0.05, hi=10.0,
                                doc="shortest stride the phase estimator averages in")
    max_stride_s: float = param(3.0, unit="s", lo=0.05, hi=10.0,
                                doc="longest stride the phase estimator averages in")

    def check(self) -> None:
        if self.min_stride_s >= self.max_stride_s:
            self.fail("min_stride_s", f"must be below max_stride_s = {self.max_stride_s!r}")


@dataclasses.dataclass(frozen=True)
class ClutchedSpring(Parameters):
    """A spring in parallel with the calf behind a clutch (module docstring). Phases are
    fractions of the stride (0 = heel strike)."""

    stiffness_nm_per_rad: float = param(180.0, unit="N·m/rad", lo=0.0, hi=2000.0,
                                        doc="spring stiffness at the ankle")
    engage_phase: float = param(0.10, unit="-", lo=0.0, hi=0.5,
                                doc="stride phase at which the clutch engages (foot flat)")
    release_phase: float = param(0.62, unit="-", lo=0.3, hi=1.0,
                                 doc="stride phase past which the clutch opens")
    ratchet: bool = effect(False, doc="while engaged, the clutch takes up slack: an ankle "
                           "that plantarflexes below the engagement angle moves the spring's "
                           "slack angle with it (a ratchet and pawl), so the spring stretches "
                           "from the lowest angle of the stance, wherever foot flat falls")

    def check(self) -> None:
        if self.engage_phase >= self.release_phase:
            self.fail("engage_phase", f"must be below release_phase = {self.release_phase!r}")


IDEAL = IdealAnkleParams()
#: Device presets by scenario name (``[device] preset = "ideal"``).
PRESETS = {"ideal": IDEAL}


def ideal_params(overrides: dict | None = None, preset: str = "ideal") -> IdealAnkleParams:
    """A preset (:data:`PRESETS`) with dotted-name overrides (``{"mass_kg": 0.97}``),
    validated."""
    if preset not in PRESETS:
        raise ParameterError(f"device.preset = {preset!r}; allowed: {', '.join(PRESETS)}")
    base = PRESETS[preset]
    return replace_named(base, overrides) if overrides else base


#: the device log's columns (per worn side): the first ones as on the circuit devices
#: (:data:`afo_mj.circuits.stepper.LOG_HEADER`), then the clutch (written by
#: :func:`afo_mj.devices.ideal_step.ideal_end`)
LOG_FIELDS = kern.LOG_FIELDS


class IdealDevice:
    """The ideal orthosis on ``sides`` (module docstring), stepped with MuJoCo through the
    coupled-device protocol: ``begin_step(t, angle2, velocity2, stance2)`` → ``(force2,
    damping2)`` per walker side (damping always 0), ``end_step(velocity_new2)`` → the
    delivered torque (= ``force2``). At most one of ``profile`` (+dorsiflexion N·m vs phase,
    :mod:`afo_mj.control.assistance`), ``impedance`` (rows) and ``spring``
    (:class:`ClutchedSpring`); none: transparent. ``ramp_strides`` > 0 scales the torque by
    (strides measured)/``ramp_strides`` until that many strides have been measured.
    ``max_steps`` > 0 keeps a log of that many steps (:data:`LOG_FIELDS`)."""

    coupled = True

    def __init__(self, params: IdealAnkleParams = IDEAL, sides=("right",), profile=None,
                 impedance=None, spring: ClutchedSpring | None = None,
                 timestep_s: float = 1e-3, max_steps: int = 0, ramp_strides: int = 0):
        if not isinstance(params, IdealAnkleParams):
            raise ParameterError(f"device params = {type(params).__name__}; allowed: "
                                 "IdealAnkleParams")
        sides = tuple(sides)
        if not sides or len(set(sides)) != len(sides) or any(s not in SIDE_NAMES
                                                             for s in sides):
            raise ParameterError(f"device.sides = {list(sides)!r}; allowed: a non-empty subset "
                                 "of ['right', 'left']")
        given = [n for n, v in (("profile", profile), ("impedance", impedance),
                                ("spring", spring)) if v is not None]
        if len(given) > 1:
            raise ParameterError(f"ideal device: {' and '.join(given)} given; allowed: one")
        if spring is not None and not isinstance(spring, ClutchedSpring):
            raise ParameterError(f"device spring = {spring!r}; allowed: a ClutchedSpring")
        if not (isinstance(timestep_s, (int, float)) and math.isfinite(timestep_s)
                and timestep_s > 0):
            raise ParameterError(f"device timestep_s = {timestep_s!r}; allowed: > 0")
        if isinstance(ramp_strides, bool) or not isinstance(ramp_strides, int) \
                or not 0 <= ramp_strides <= 100:
            raise ParameterError(f"device ramp_strides = {ramp_strides!r}; allowed: an "
                                 "integer 0 … 100")
        if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 0:
            raise ParameterError(f"device max_steps = {max_steps!r}; allowed: an integer >= 0")
        self.params = params
        self.sides = sides
        self.side_index = np.array([SIDE_NAMES.index(s) for s in sides], dtype=np.int64)
        self.timestep_s = float(timestep_s)
        self.profile = (None if profile is None
                        else np.ascontiguousarray(profile, dtype=float))
        if self.profile is not None and (self.profile.ndim != 1 or self.profile.size < 2
                                         or not np.all(np.isfinite(self.profile))):
            raise ParameterError(f"device profile: shape {self.profile.shape}; allowed: a "
                                 "finite 1-D table of at least 2 points")
        self.impedance = impedance
        imp_table = None if impedance is None else impedance_table(impedance)
        self.spring = spring
        self.transparent = not given
        self.ramp_strides = ramp_strides
        self.stride_limits = (params.min_stride_s, params.max_stride_s)
        if spring is not None:
            mode, table = kern.MODE_SPRING, None
        elif self.profile is not None:
            mode, table = kern.MODE_PROFILE, self.profile
        elif imp_table is not None:
            mode, table = kern.MODE_IMPEDANCE, imp_table
        else:
            mode, table = kern.MODE_TRANSPARENT, None
        sp = spring or ClutchedSpring()
        #: the device's whole state (:mod:`afo_mj.devices.ideal_step`), stepped by its
        #: compiled kernels from Python or from a compiled walk loop
        self._buf, self._meta = kern.new_buffer(
            self.side_index, mode, table, self.timestep_s, params.min_stride_s,
            params.max_stride_s, ramp_strides, sp.stiffness_nm_per_rad, sp.engage_phase,
            sp.release_phase, sp.ratchet)
        b = self._buf
        #: phase-estimator state per walker side (:func:`afo_mj.control.assistance.
        #: new_phase_state`; only the worn sides' rows move)
        self.phase = b[kern.B_PH:kern.B_POS].reshape(2, asst.N_PH)
        #: per walker side: the clutch's engagement angle (rad), NaN while open
        self.theta_engaged = b[kern.B_TH_ENG:kern.B_TH_ENG + 2]
        self.force2 = b[kern.B_FORCE:kern.B_FORCE + 2]
        self.damping2 = b[kern.B_DAMP:kern.B_DAMP + 2]
        self.delivered2 = b[kern.B_DELIV:kern.B_DELIV + 2]
        self.commanded2 = b[kern.B_CMD:kern.B_CMD + 2]
        self.phase2 = b[kern.B_PHASE:kern.B_PHASE + 2]
        ns = len(sides)
        self._pos_j = b[kern.B_POS:kern.B_POS + ns]
        self._neg_j = b[kern.B_NEG:kern.B_NEG + ns]
        self._peak_nm = b[kern.B_PEAK:kern.B_PEAK + ns]
        # the kernels' inputs when stepped from Python: angle, velocity, stance (1/0) per side
        self._in = np.zeros((3, 2))
        self.log = CircuitLog(max_steps, ns, LOG_FIELDS) if max_steps else None
        self._log_data = (self.log.data if self.log is not None
                          else np.zeros((0, len(LOG_FIELDS), ns)))
        self.steps = 0
        self.t_s = 0.0

    # -- masses ----------------------------------------------------------------------------
    def worn_masses(self) -> list[WornMass]:
        """The worn mass at the ankle axis of each worn side (none at 0 kg)."""
        m = self.params.mass_kg
        if m == 0.0:
            return []
        return [WornMass(f"ankle_axis_{'r' if s == 'right' else 'l'}", m, f"ideal_{s}")
                for s in self.sides]

    @property
    def mass_total_kg(self) -> float:
        return len(self.sides) * self.params.mass_kg

    @property
    def mass_at_ankle_kg(self) -> float:
        """Per worn side."""
        return self.params.mass_kg

    # -- coupled protocol --------------------------------------------------------------------
    def begin_step(self, t: float, angle_rad, velocity_rad_s, stance):
        """The command of every worn side from the state at the step's start; returns the
        joint force and the extra damping per walker side (views, length 2; damping 0).
        The compiled :func:`afo_mj.devices.ideal_step.ideal_begin`."""
        self.t_s = float(t)
        x = self._in
        x[0] = angle_rad
        x[1] = velocity_rad_s
        x[2] = stance
        kern.ideal_begin(self.t_s, x[0], x[1], x[2], self._buf, self._meta)
        return self.force2, self.damping2

    def end_step(self, velocity_new_rad_s):
        """Close the step with the joint velocity MuJoCo produced; returns the delivered
        torque per walker side (the command, exactly). The compiled
        :func:`afo_mj.devices.ideal_step.ideal_end`; a non-finite torque raises
        FloatingPointError."""
        v = self._in[1]
        v[:] = velocity_new_rad_s
        n = self.steps
        code = kern.ideal_end(v, self._buf, self._meta, self._log_data, n,
                              self.t_s + self.timestep_s)
        if not code:
            raise self._non_finite()
        if code == 2:
            self.log.n = n + 1
        self.steps = n + 1
        return self.delivered2

    def native_coupling(self):
        """The C entry points and buffers a compiled walk loop steps this device with
        (:class:`afo_mj.circuits.native_entry.NativeCoupling`; the kernels of
        :mod:`afo_mj.devices.ideal_step`, the same that :meth:`begin_step`/:meth:`end_step`
        call). The loop reports back with :meth:`native_finished`."""
        from afo_mj.circuits.native_entry import NativeCoupling
        begin, end = kern.entry_addresses()
        return NativeCoupling(begin, end, self._buf, self._meta, self._log_data, self.force2,
                              self.damping2, self.delivered2)

    def native_finished(self, steps: int, last_t_s: float, failed: bool = False) -> None:
        """A compiled loop stepped this device ``steps`` times, the last one beginning at
        ``last_t_s``: the step counter, the log's length and the time move on as
        :meth:`end_step` would have moved them; ``failed`` (a torque went non-finite in the
        last step) raises the error :meth:`end_step` raises."""
        if steps:
            self.t_s = float(last_t_s)
        self.steps += steps - 1 if failed else steps
        if self.log is not None:
            self.log.n = min(self.steps, self.log.data.shape[0])
        if failed:
            raise self._non_finite()

    def _non_finite(self) -> FloatingPointError:
        return FloatingPointError(f"ideal device: a non-finite torque at t = {self.t_s:.4f} s "
                                  f"(command {self.commanded2.tolist()} N·m, angle "
                                  f"{self._buf[kern.B_ANGLE:kern.B_ANGLE + 2].tolist()} rad)")

    # -- ledger ----------------------------------------------------------------------------
    def ledger(self, k: int = 0) -> dict:
        """Energy ledger of worn side ``k`` (J), that of an ideal source (module docstring):
        drawn = positive mechanical work, regenerated = negative work absorbed, no losses,
        no stores, zero balance error; the hydraulic and electrical figures a circuit
        device reports are zero or None (``hydraulic_j``, ``battery_energy_wh``: none)."""
        if not 0 <= k < len(self.sides):
            raise ParameterError(f"ledger side index {k!r}; allowed: 0 … {len(self.sides) - 1}")
        pos, neg = float(self._pos_j[k]), float(self._neg_j[k])
        drawn, regen = pos, 0.0 - neg        # 0.0 - : no negative zero
        e_in = drawn - regen
        e_out = pos + neg
        resid = e_in - e_out
        scale = max(pos - neg, 1e-12)
        return {"source": "ideal torque source (100 % efficient both ways, no store, no loss)",
                "input_j": e_in, "input_drawn_j": drawn, "electrical_in_j": e_in,
                "electrical_drawn_j": drawn, "electrical_regenerated_j": regen,
                "mechanical_out_j": e_out, "mechanical_positive_out_j": pos,
                "mechanical_negative_out_j": neg, "hydraulic_j": None,
                "losses_j": {}, "stored_change_j": {}, "residual_j": resid,
                "balance_error_rel": resid / scale, "energy_throughput_j": scale,
                "heat_to_oil_j": 0.0, "peak_pressure_pa": 0.0, "temperature_rise_k": 0.0,
                "peak_torque_nm": float(self._peak_nm[k]), "battery_energy_wh": None,
                "monitors": {}, "state_peaks": {}, "probe_integrals": {},
                "newton_iterations": 0, "jacobian_builds": 0, "newton_unconverged_steps": 0,
                "substepped_steps": 0, "pressure_floor_steps": 0, "battery_overload_steps": 0,
                "coupling_torque_error_rms_nm": 0.0}
