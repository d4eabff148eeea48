"""Rerun recordings (``.rrd``) of walking runs: the 3D body, the orthosis and every signal on
one timeline, laid out by a blueprint so the file opens ready to read.

One recording holds one or more *runs* (a plain walk is one run, ``walk``; a device scenario
records each of its conditions, e.g. ``no_device``, ``transparent``, ``assist``, walking side
by side in parallel lanes). Everything is logged column-wise (``send_columns``) after the
simulation, from the arrays the run already keeps, so recording adds no work to the physics
loop and costs little wall time (``benchmarks/recording_overhead.py``). Static data (geometry,
styles, units, the floor, the colour key) goes first, so a viewer reading the file draws each
series styled as it arrives; signals are thinned for display to within ``signal_tolerance`` of
their range (:mod:`afo_mj.outputs.series_thinning`), a sixth of the rows of a typical walk
(size and web-viewer load time: ``benchmarks/recording.py``).

The blueprint opens the file playing: the 3D view is set in ``world/follow``, a frame that
moves forward with the walkers (:func:`follow_track`), its eye fixed in that frame
(:func:`eye_placement`), so the walkers stay framed; the plots carry no legend over their data
(a ``key`` text panel names each run's colour, and each walker carries its run's name).

Timeline ``time`` (a duration, seconds of simulated time). Entity paths (``<run>`` = run
name, ``<side>`` = ``right`` / ``left``, ``<joint>`` = ``hip`` / ``knee`` / ``ankle``):

3D (``world``, metres, z up, x forward; transforms at ``transform_rate_hz``)

* ``world/floor`` -- the floor (static box), ``world/floor/metre_marks`` a line every metre;
* ``world/follow`` -- ``Transform3D`` (translation in x) of the frame the 3D view is set in;
* ``world/<run>/body/<body>`` -- ``Transform3D`` of each MuJoCo body (world pose, lane offset
  in y); its children ``world/<run>/body/<body>/<geom>`` are the body's geoms as rerun
  primitives (boxes, capsules, ellipsoids, cylinders) in the body frame;
* ``world/<run>/body/pelvis/label`` -- the run's name over the walker (static);
* ``world/<run>/body/shank_<r|l>/afo/cuff``, ``.../foot_<r|l>/afo/plate`` -- the orthosis
  shell on each worn side (static boxes);
* ``world/<run>/afo_torque/<side>`` -- ``Arrows3D``: the delivered orthosis torque, an arrow
  ending at the ball of the foot, :data:`AFO_ARROW_M_PER_NM` per N·m, pointing where a force
  there turns the foot the same way (down = plantarflexion);
* ``world/<run>/grf/<side>`` -- ``Arrows3D``: ground-reaction force at the foot's centre of
  pressure (heel/ball spheres weighted by their normal force), 1 m per :data:`GRF_M_PER_N`⁻¹ N;
* ``world/<run>/body/shank_<r|l>/afo/barrel_<a|b>`` and ``.../afo/oil_<a|b>`` -- the
  cylinder(s) on the worn ankle along the shank, one per chamber the circuit logs (two for a
  piston-cable pair, one, ``a``, for a single-acting cylinder): the barrel (static) and its oil
  column, whose length is the chamber's share of the stroke (the piston's position from the
  a-end as logged, ``<cylinder>.piston_position_m``) and whose colour is the chamber pressure
  (blue = 0 bar gauge, red = the highest relief valve's cracking pressure).

Signals (``Scalars``, sampled at ``signal_rate_hz`` and thinned; each entity carries a static
``unit`` value and a series name; display units as the path says)

==========================================================  =========================
``signals/angle_deg/<joint>/<side>/<run>``                  joint angle [deg] (+ flexion /
                                                            dorsiflexion)
``signals/angle_deg/<joint>/normative/<mean|minus_1sd|plus_1sd>``  reference band [deg], on the
                                                            last run's right-leg strides
``signals/moment_nm/<joint>/<side>/<run>``                  human joint moment [N·m]
``signals/joint_power_w/<joint>/<side>/<run>``              human joint power [W]
``signals/grf_n/<vertical|forward>/<side>/<run>``           ground reaction force [N]
``signals/gait_phase/<side>/<run>``                         gait phase [1], 0 at heel strike
``signals/ankle_torque_nm/human/<side>/<run>``              human ankle moment [N·m]
``signals/ankle_torque_nm/device_commanded/<side>/<run>``   orthosis torque command [N·m]
``signals/ankle_torque_nm/device_delivered/<side>/<run>``   orthosis torque delivered [N·m]
``signals/pressure_bar/<node>/<side>/<run>``                gauge pressure [bar] of every
                                                            pressure node of the circuit:
                                                            ``line_a``, ``line_b``,
                                                            ``chamber_a``, ``chamber_b``
                                                            (pump-controlled); ``pump``,
                                                            ``supply``, ``port_a``, ...
                                                            (valve circuits); a described
                                                            circuit's own node names
``signals/flow_l_min/<pump|cylinder>/<side>/<run>``         geometric pump flow D ω / 2π,
                                                            piston flow A_e r θ̇ [L/min]
``signals/piston_position_mm/<side>/<run>``                 piston travel r θ from its
                                                            position at θ = 0 (mid-stroke of
                                                            a piston-cable pair) [mm]
``signals/motor_current_a/<side>/<run>``                    motor current [A]
``signals/motor_speed_rpm/<side>/<run>``                    motor speed [rpm]
``signals/motor_voltage_v/<side>/<run>``                    motor voltage command [V]
``signals/valve/<position|command|unloading>/<side>/<run>`` valve spool position, command
                                                            (or PWM duty), unloading valve [1]
                                                            (each where the circuit has it)
``signals/fluid_temperature_c/<side>/<run>``                oil temperature [°C]
``signals/device_power_w/<stage>/<side>/<run>``             power at ``electrical``,
                                                            ``hydraulic``, ``ankle`` [W]
``signals/running_efficiency/<side>/<run>``                 ∫P_ankle⁺ / ∫P_el⁺ so far [1]
``events/<run>``                                            ``TextLog``: heel strikes, toe
                                                            offs, swing toe contacts, fall
==========================================================  =========================

The device signals are those its log holds: a signal is recorded when the log has its column
(or what follows from it: flows, powers) and left out when the circuit has no such part (a
valve circuit without an unloading valve has no ``valve/unloading``; a described circuit's
signals come from its components and node names).

Units: the physics is SI; the recording shows angles in degrees, pressures in bar (gauge),
flows in L/min and speeds in rpm, each stated in the path and in the entity's ``unit``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import uuid
from pathlib import Path
from typing import Sequence

import numpy as np

__all__ = ["RecordedRun", "RecordingError", "write_recording", "write_bench_recording",
           "read_recording_index", "check_recording_path", "RecordingTarget",
           "write_results_with_recording", "follow_track", "eye_placement",
           "GRF_M_PER_N", "SIGNAL_RATE_HZ", "SIGNAL_TOLERANCE", "TRANSFORM_RATE_HZ"]

#: default sample rate of the scalar signals (every k-th simulation step) [Hz], before the
#: tolerance-bound thinning of :func:`thin_series` (``SIGNAL_TOLERANCE``)
SIGNAL_RATE_HZ = 500.0
#: default tolerance of the signal thinning, as a fraction of each signal's range (max − min):
#: a sample is left out only when the straight line between the samples kept on either side
#: passes within this of it (0.002: under a pixel of a plot 500 pixels tall)
SIGNAL_TOLERANCE = 2.0e-3
#: default sample rate of body transforms, force arrows and orthosis cylinders [Hz]
TRANSFORM_RATE_HZ = 50.0
#: length of a ground-reaction-force arrow per newton [m/N]
GRF_M_PER_N = 1.0e-3
#: lateral distance between the lanes of the runs of one recording [m]
LANE_SPACING_M = 1.0
#: window of the moving average that smooths the forward position the 3D camera follows [s]
FOLLOW_SMOOTHING_S = 1.0
#: height of each run's name above its pelvis [m]
LABEL_HEIGHT_M = 0.95
#: length of the orthosis torque arrow per newton metre [m/(N·m)]
AFO_ARROW_M_PER_NM = 1.0e-2
#: colour of the orthosis shell (cuff and foot plate) and of its torque arrow (RGBA)
AFO_COLOUR = (25, 45, 80, 230)
AFO_TORQUE_COLOUR = (200, 0, 200, 255)
#: the 3D view's eye, in the frame that follows the walkers (``world/follow``): how far ahead
#: of the walkers, how far to their right of the middle lane and how high it stands [m]
EYE_SIDE_M = 2.5
EYE_HEIGHT_M = 1.8
EYE_AHEAD_M = 3.6
#: the point the eye looks at: height above the floor [m]
LOOK_HEIGHT_M = 0.8

_SIDES = ("right", "left")
_JOINTS = ("hip", "knee", "ankle")
_RUN_COLOURS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40),
                (148, 103, 189), (140, 86, 75), (227, 119, 194), (127, 127, 127))
_RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
_M3_S_TO_L_MIN = 6.0e4


class RecordingError(ValueError):
    """A recording could not be made (bad argument, unwritable path, non-finite data)."""


@dataclasses.dataclass
class RecordedRun:
    """One run to record: its gait record and, when an orthosis was worn, the device (with
    its log)."""

    name: str
    record: object                      # afo_mj.gait.record.GaitRecord
    device: object | None = None        # HafoDevice / ValveAfoDevice, or None
    #: more per-sample signals of the run: ``{entity path under signals/: (values (n,),
    #: unit, label)}`` (e.g. a muscle walk's activations and metabolic rates)
    extra_signals: dict = dataclasses.field(default_factory=dict)


# -- helpers ------------------------------------------------------------------------------------
def _run_colour(i: int, side: int = 0) -> tuple[int, int, int]:
    c = _RUN_COLOURS[i % len(_RUN_COLOURS)]
    if side == 1:                       # the left leg a lighter shade of the run's colour
        c = tuple(int(v + 0.5 * (255 - v)) for v in c)
    return c


def _pressure_colours(p_pa: np.ndarray, p_max_pa: float) -> np.ndarray:
    """RGBA (uint8) from blue (0 bar gauge) through white to red (``p_max_pa``)."""
    s = np.clip(np.asarray(p_pa, dtype=float) / max(p_max_pa, 1.0), 0.0, 1.0)
    lo = np.array([59.0, 76.0, 192.0])
    mid = np.array([221.0, 221.0, 221.0])
    hi = np.array([180.0, 4.0, 38.0])
    a = np.where(s[:, None] < 0.5, lo + (mid - lo) * (2 * s[:, None]),
                 mid + (hi - mid) * (2 * s[:, None] - 1))
    rgba = np.empty((len(s), 4), dtype=np.uint8)
    rgba[:, :3] = np.round(a).astype(np.uint8)
    rgba[:, 3] = 255
    return rgba


def _xyzw(q_wxyz: np.ndarray) -> np.ndarray:
    """MuJoCo quaternion(s) (w, x, y, z) → rerun's (x, y, z, w)."""
    q = np.asarray(q_wxyz, dtype=float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def _quat_rotate(q_wxyz: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vector ``v`` by unit quaternion ``q`` (w, x, y, z)."""
    w, u = q_wxyz[0], np.asarray(q_wxyz[1:], dtype=float)
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def _stride_phase(t: np.ndarray, strikes: Sequence[float]) -> np.ndarray:
    """Phase 0..1 between consecutive heel strikes; NaN outside the measured strides."""
    s = np.asarray(strikes, dtype=float)
    ph = np.full(len(t), np.nan)
    if len(s) < 2:
        return ph
    k = np.searchsorted(s, t, side="right") - 1
    ok = (k >= 0) & (k < len(s) - 1)
    kk = k[ok]
    ph[ok] = (t[ok] - s[kk]) / (s[kk + 1] - s[kk])
    return ph


class _Writer:
    """Column-wise logging into one recording stream, with the list of what was logged."""

    def __init__(self, rr, stream, tolerance: float = 0.0):
        self.rr, self.stream = rr, stream
        self.tolerance = tolerance          # of the signal thinning, fraction of the range
        self.index: dict[str, dict] = {}

    def scalars(self, path: str, t: np.ndarray, values: np.ndarray, unit: str, name: str,
                colour=None) -> None:
        """One signal: its style and unit (static, first, so that a viewer reading the file
        in order draws it styled at once), then its samples thinned by
        :func:`~afo_mj.outputs.series_thinning.thin_indices` to within ``tolerance`` × the
        signal's range."""
        from afo_mj.outputs.series_thinning import thin_indices
        rr = self.rr
        v = np.asarray(values, dtype=float)
        t = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(v)):
            raise RecordingError(f"signal {path!r} has non-finite values; nothing written")
        style = rr.SeriesLines(names=name, colors=None if colour is None else [colour])
        self.stream.log(path, style, rr.AnyValues(unit=unit), static=True)
        span = float(np.ptp(v)) if len(v) else 0.0
        # a constant signal: its two ends (any tolerance > 0 keeps only those)
        tol = self.tolerance * span if span > 0 else (1e-300 if self.tolerance > 0 else 0.0)
        keep = thin_indices(t, v, tol)
        self.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=t[keep])],
                                 columns=rr.Scalars.columns(scalars=v[keep]))
        self.index[path] = {"kind": "Scalars", "rows": int(len(keep)), "unit": unit,
                            "samples": int(len(v))}


def _log_gait_signals(w: _Writer, run: RecordedRun, i: int, step: int) -> None:
    rec = run.record
    t = rec.time_s[::step]
    ang = np.degrees(rec.joint_angle_rad[::step])
    mom = rec.joint_moment_nm[::step]
    pw = (rec.joint_moment_nm * rec.joint_velocity_rad_s)[::step]
    for s, side in enumerate(_SIDES):
        col = _run_colour(i, s)
        for j, joint in enumerate(_JOINTS):
            w.scalars(f"signals/angle_deg/{joint}/{side}/{run.name}", t, ang[:, s, j], "deg",
                      f"{joint} angle {side} ({run.name})", col)
            w.scalars(f"signals/moment_nm/{joint}/{side}/{run.name}", t, mom[:, s, j], "N*m",
                      f"{joint} moment {side} ({run.name})", col)
            w.scalars(f"signals/joint_power_w/{joint}/{side}/{run.name}", t, pw[:, s, j], "W",
                      f"{joint} power {side} ({run.name})", col)
        w.scalars(f"signals/grf_n/vertical/{side}/{run.name}", t, rec.grf_n[::step, s, 1], "N",
                  f"GRF vertical {side} ({run.name})", col)
        w.scalars(f"signals/grf_n/forward/{side}/{run.name}", t, rec.grf_n[::step, s, 0], "N",
                  f"GRF forward {side} ({run.name})", col)
        w.scalars(f"signals/gait_phase/{side}/{run.name}", t, rec.gait_phase[::step, s], "1",
                  f"gait phase {side} ({run.name})", col)
        w.scalars(f"signals/ankle_torque_nm/human/{side}/{run.name}", t, mom[:, s, 2], "N*m",
                  f"human ankle {side} ({run.name})", col)


def _log_normative(w: _Writer, run: RecordedRun, reference, step: int) -> None:
    """The reference mean ± 1 SD of each joint angle, mapped onto ``run``'s right strides."""
    from afo_mj.metrics.gait_metrics import reference_band
    if reference is None:
        return
    rec = run.record
    t = rec.time_s[::step]
    ph = _stride_phase(t, rec.events.heel_strikes_s[0])
    ok = np.isfinite(ph)
    if ok.sum() < 2:
        return
    grid = np.linspace(0.0, 1.0, 101)
    for joint in _JOINTS:
        band = reference_band(reference, f"{joint}_angle_rad")
        if band is None:
            continue
        mean, sd = band
        m = np.degrees(np.interp(ph[ok], grid, mean))
        w.scalars(f"signals/angle_deg/{joint}/normative/mean", t[ok], m, "deg",
                  f"{joint} normative mean", (0, 0, 0))
        if sd is not None:
            s = np.degrees(np.interp(ph[ok], grid, sd))
            w.scalars(f"signals/angle_deg/{joint}/normative/minus_1sd", t[ok], m - s, "deg",
                      f"{joint} normative −1 SD", (150, 150, 150))
            w.scalars(f"signals/angle_deg/{joint}/normative/plus_1sd", t[ok], m + s, "deg",
                      f"{joint} normative +1 SD", (150, 150, 150))


#: display names of circuit pressure nodes in the recording (the valve circuits' pump outlet and
#: supply rail); every other node keeps its circuit name (``line_a``, ``chamber_a``, ...)
_NODE_NAMES = {"pump_out": "pump", "rail": "supply"}
#: the valve signals and the log columns that may hold them (a preset's name first, then the
#: generic circuit names): a circuit without that valve has none of them and is not asked for it
_VALVE_COLUMNS = (("position", ("valve_position", "servo.spool", "release.position"),
                   "valve position"),
                  ("command", ("valve_command", "controller.valve_command"), "valve command"),
                  ("unloading", ("unloading_valve_position", "unloading.position",
                                 "switching.position"), "unloading valve"))


def _column(dev, L: dict, *names: str):
    """The first of ``names`` the device's log holds (each looked up under the device's renamed
    column, :attr:`~afo_mj.circuits.device.CircuitDevice.log_names`, then as given), or None."""
    renamed = getattr(dev, "log_names", None) or {}
    for name in names:
        for key in (renamed.get(name, name), name):
            if key in L:
                return L[key]
    return None


def _circuit(dev):
    return getattr(getattr(dev, "cc", None), "circuit", None)


def _joint_actuator(dev):
    """The circuit component on the joint (the cylinder(s) driving the ankle), or None."""
    c = _circuit(dev)
    if c is None:
        return None
    names = {ref.split(".")[0] for ref in c.nodes.get(c.joint, ())}
    return c.component(names.pop()) if len(names) == 1 else None


def _lever_m(dev) -> float | None:
    """Piston travel per radian of the joint: the pulley radius or lever arm [m]."""
    act = _joint_actuator(dev)
    for obj in (getattr(act, "params", None), getattr(dev, "params", None)):
        for key in ("pulley_radius_m", "moment_arm_m"):
            v = getattr(obj, key, None)
            if isinstance(v, (int, float)) and v > 0:
                return float(v)
    return None


def _derived(dev, L: dict) -> dict[str, np.ndarray]:
    """Flows and powers (SI, ``(n, sides)``) that follow from the log: a preset's from
    :func:`afo_mj.metrics.device_signals.device_signals` (its parameters), a described
    circuit's from its components: geometric pump flow ``D ω / 2π`` of its pump on the logged
    shaft speed, the pump's own hydraulic-power probe, piston flow ``n A r θ̇`` of the joint's
    cylinder(s); electrical power ``V_bus I_bat``, ankle power and the running efficiency
    from the log's header columns (the same definitions)."""
    from afo_mj.metrics.device_signals import device_signals
    if getattr(dev, "params", None) is not None:
        return {k: s.values for k, s in device_signals(dev).items()}
    out: dict[str, np.ndarray] = {}
    c = _circuit(dev)
    pumps = [x for x in (c.components if c is not None else ())
             if x.kind in ("pump", "variable_pump")]
    if len(pumps) == 1:
        pump = pumps[0]
        speed = _column(dev, L, c.port_node.get((pump.name, "shaft"), ""))
        disp = getattr(pump.params, "displacement_m3_rev", None)
        if speed is not None and disp is not None:
            out["pump_flow_m3_s"] = disp * speed / (2.0 * math.pi)
        hyd = _column(dev, L, f"{pump.name}.hydraulic_power_w")
        if hyd is not None:
            out["hydraulic_power_w"] = hyd
    act, lever = _joint_actuator(dev), _lever_m(dev)
    cyl = getattr(getattr(act, "params", None), "cylinder", None)
    vel = L.get("ankle_velocity_rad_s")
    if cyl is not None and lever is not None and vel is not None:
        count = float(getattr(act.params, "count", 1.0))
        out["cylinder_flow_m3_s"] = count * cyl.area_a_m2 * lever * vel
    if "bus_voltage_v" in L and "battery_current_a" in L and "mechanical_power_w" in L:
        p_el, p_mech = L["bus_voltage_v"] * L["battery_current_a"], L["mechanical_power_w"]
        t = L["time_s"][:, 0]
        dt = np.diff(t, prepend=t[0] if len(t) else 0.0)[:, None]
        e_in = np.cumsum(np.maximum(p_el, 0.0) * dt, axis=0)
        e_out = np.cumsum(np.maximum(p_mech, 0.0) * dt, axis=0)
        out["electrical_power_w"] = p_el
        out["mechanical_power_w"] = p_mech
        out["running_efficiency"] = np.where(e_in > 1e-9, e_out / np.where(e_in > 1e-9, e_in,
                                                                           1.0), 0.0)
    return out


def _device_series(run: RecordedRun) -> list[tuple[str, np.ndarray, str, str]]:
    """Every device signal the run's device log holds: ``(path under signals/ without side
    and run, values (n, sides) at the log rows, unit, label)``. A signal is recorded when the
    log (or what follows from it and the device's parameters) has it, and only then."""
    dev = run.device
    if dev is None or getattr(dev, "log", None) is None or dev.log.n == 0:
        return []
    L = dev.log.arrays()
    cc = getattr(dev, "cc", None)
    c = _circuit(dev)
    series: list[tuple[str, np.ndarray, str, str]] = []

    def add(path, values, unit, label, scale=1.0, offset=0.0):
        if values is not None:
            series.append((path, np.asarray(values, dtype=float) * scale + offset, unit, label))

    add("ankle_torque_nm/device_commanded", L.get("commanded_torque_nm"), "N*m",
        "device commanded")
    add("ankle_torque_nm/device_delivered", L.get("delivered_torque_nm"), "N*m",
        "device delivered")
    nodes = ([s for s, k in zip(cc.state_names, cc.state_kinds) if k == "pressure"]
             if cc is not None else ["line_a", "line_b", "pump_out", "rail", "port_a", "port_b",
                                     "chamber_a", "chamber_b"])
    for node in nodes:
        name = _NODE_NAMES.get(node, node)
        add(f"pressure_bar/{name}", _column(dev, L, node), "bar (gauge)", name, 1e-5)
    d = _derived(dev, L)
    add("flow_l_min/pump", d.get("pump_flow_m3_s"), "L/min", "pump flow", _M3_S_TO_L_MIN)
    add("flow_l_min/cylinder", d.get("cylinder_flow_m3_s"), "L/min", "piston flow",
        _M3_S_TO_L_MIN)
    motors = [x for x in (c.components if c is not None else ()) if x.kind == "motor"]
    motors.sort(key=lambda x: not getattr(x, "actuated", False))     # the actuated one first
    m = motors[0].name if motors else "motor"
    shaft = c.port_node.get((m, "shaft"), "shaft") if c is not None else "shaft"
    add("motor_current_a", _column(dev, L, f"{m}.current_a"), "A", "motor current")
    add("motor_speed_rpm", _column(dev, L, shaft), "rpm", "motor speed", _RAD_S_TO_RPM)
    if not motors or getattr(motors[0], "actuated", False):
        add("motor_voltage_v", _column(dev, L, "actuated_input"), "V", "motor voltage")
    for key, names, label in _VALVE_COLUMNS:
        add(f"valve/{key}", _column(dev, L, *names), "1", label)
    lever = _lever_m(dev)
    if lever is not None:
        angle = L.get("ankle_angle_rad")
        if angle is None:
            rec = run.record
            angle = np.column_stack([np.interp(L["time_s"][:, 0], rec.time_s,
                                               rec.joint_angle_rad[:, _SIDES.index(sd), 2])
                                     for sd in dev.sides])
        add("piston_position_mm", angle * lever, "mm", "piston r*theta", 1e3)
    add("fluid_temperature_c", L.get("oil_temperature_k"), "degC", "oil temperature",
        offset=-273.15)
    add("device_power_w/electrical", d.get("electrical_power_w"), "W", "electrical")
    add("device_power_w/hydraulic", d.get("hydraulic_power_w"), "W", "hydraulic")
    add("device_power_w/ankle", d.get("mechanical_power_w"), "W", "ankle")
    add("running_efficiency", d.get("running_efficiency"), "1", "running efficiency")
    return series


def _log_device_signals(w: _Writer, run: RecordedRun, i: int, step: int,
                        series: list) -> None:
    if not series:
        return
    dev = run.device
    t = dev.log.arrays()["time_s"][::step, 0]
    for k, side in enumerate(dev.sides):
        col = _run_colour(i, _SIDES.index(side))
        for path, values, unit, label in series:
            w.scalars(f"signals/{path}/{side}/{run.name}", t, values[::step, k], unit,
                      f"{label} {side} ({run.name})", col)


def _log_events(w: _Writer, run: RecordedRun) -> None:
    rr = w.rr
    ev = run.record.events
    items: list[tuple[float, str, str]] = []
    for s, side in enumerate(_SIDES):
        items += [(t, f"{side} heel strike", "INFO") for t in ev.heel_strikes_s[s]]
        items += [(t, f"{side} toe off", "INFO") for t in ev.toe_offs_s[s]]
    items += [(t, f"{_SIDES[s]} swing toe contact (scuff)", "WARN")
              for t, s in ev.swing_toe_contacts]
    if ev.fall_time_s is not None:
        items.append((ev.fall_time_s, "FALL", "ERROR"))
    if not items:
        return
    items.sort()
    path = f"events/{run.name}"
    w.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=[x[0] for x in items])],
                          columns=rr.TextLog.columns(text=[x[1] for x in items],
                                                     level=[x[2] for x in items]))
    w.index[path] = {"kind": "TextLog", "rows": len(items), "unit": ""}


# -- 3D -----------------------------------------------------------------------------------------
def _geom_archetype(rr, model, g: int):
    """The rerun primitive of MuJoCo geom ``g`` in its body's frame (None for planes)."""
    import mujoco
    typ = int(model.geom_type[g])
    size = model.geom_size[g]
    pos = model.geom_pos[g].copy()
    quat = model.geom_quat[g].copy()
    rgba = model.geom_rgba[g]
    if model.geom_matid[g] >= 0:
        rgba = model.mat_rgba[model.geom_matid[g]]
    colour = tuple(int(round(255 * c)) for c in rgba)
    T = mujoco.mjtGeom
    q = _xyzw(quat)
    if typ == T.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], centers=[pos], colors=[colour],
                               fill_mode="solid")
    if typ == T.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size[:3]], centers=[pos], quaternions=[q],
                               colors=[colour], fill_mode="solid")
    if typ == T.mjGEOM_CAPSULE:
        start = pos - _quat_rotate(quat, np.array([0.0, 0.0, size[1]]))
        return rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[start],
                             quaternions=[q], colors=[colour])
    if typ == T.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[pos],
                              quaternions=[q], colors=[colour], fill_mode="solid")
    if typ == T.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size[:3]], centers=[pos], quaternions=[q],
                          colors=[colour], fill_mode="solid")
    return None


def _kinematics(run: RecordedRun, step: int, lane_y: float) -> dict:
    """World poses of every body and geom of one run at every ``step``-th sample (MuJoCo's
    forward kinematics of the recorded ``qpos``), its lane offset in y added."""
    import mujoco
    rec = run.record
    if rec.qpos is None or rec.model_xml is None:
        raise RecordingError(f"run {run.name!r}: the record kept no qpos/model for 3D replay")
    model = mujoco.MjModel.from_xml_string(rec.model_xml)
    data = mujoco.MjData(model)
    idx = np.arange(0, len(rec.time_s), step)
    n = len(idx)
    xpos = np.empty((n, model.nbody, 3))
    xquat = np.empty((n, model.nbody, 4))
    gpos = np.empty((n, model.ngeom, 3))
    for k, i in enumerate(idx):
        data.qpos[:] = rec.qpos[i]
        mujoco.mj_kinematics(model, data)
        xpos[k] = data.xpos
        xquat[k] = data.xquat
        gpos[k] = data.geom_xpos
    xpos[:, :, 1] += lane_y
    gpos[:, :, 1] += lane_y
    names = [model.body(b).name for b in range(model.nbody)]
    return {"model": model, "idx": idx, "t": rec.time_s[idx], "xpos": xpos, "xquat": xquat,
            "gpos": gpos, "body_names": names, "lane_y": lane_y,
            "pelvis": names.index("pelvis") if "pelvis" in names else 1}


def follow_track(kins: Sequence[dict], smoothing_s: float = FOLLOW_SMOOTHING_S
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The forward position the 3D camera follows: ``(t, x)`` on the longest run's transform
    times, the midpoint of the runs' pelvis positions (lowest and highest x; a run that
    ended, e.g. by a fall, stays where it ended) smoothed by a centred moving average over
    ``smoothing_s`` (about a stride, so the camera glides instead of surging with each step).
    Every walker is within half the runs' spread (plus what the smoothing lags) of it."""
    t = max((k["t"] for k in kins), key=len)
    xs = np.array([np.interp(t, k["t"], k["xpos"][:, k["pelvis"], 0]) for k in kins])
    mid = 0.5 * (xs.min(axis=0) + xs.max(axis=0))
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    half = int(round(0.5 * smoothing_s / dt)) if dt > 0 else 0
    if half < 1 or len(mid) < 3:
        return t, mid
    pad = np.pad(mid, half, mode="edge")
    kernel = np.full(2 * half + 1, 1.0 / (2 * half + 1))
    return t, np.convolve(pad, kernel, mode="valid")


def _log_body(w: _Writer, run: RecordedRun, kin: dict, i: int) -> None:
    """Geoms (static, first), the run's name over the walker, transforms of every body,
    force arrows and the orthosis of one run."""
    rr = w.rr
    rec = run.record
    model, idx, t = kin["model"], kin["idx"], kin["t"]
    xpos, xquat, gpos = kin["xpos"], kin["xquat"], kin["gpos"]
    n = len(idx)
    root = f"world/{run.name}"
    body_names = kin["body_names"]
    for g in range(model.ngeom):
        b = int(model.geom_bodyid[g])
        if b == 0:
            continue                                     # the floor is drawn once for all runs
        arch = _geom_archetype(rr, model, g)
        if arch is None:
            continue
        name = model.geom(g).name or f"geom_{g}"
        w.stream.log(f"{root}/body/{body_names[b]}/{name}", arch, static=True)
    # the run's name above the walker's head, in the run's colour: the key to every plot
    w.stream.log(f"{root}/body/{body_names[kin['pelvis']]}/label",
                 rr.Points3D(positions=[[0.0, 0.0, LABEL_HEIGHT_M]], radii=[0.015],
                             colors=[_run_colour(i)], labels=[run.name], show_labels=True),
                 static=True)
    if run.device is not None and getattr(run.device, "log", None) is not None:
        _log_afo_shapes(w, run, model, root, body_names)
    for b in range(1, model.nbody):
        path = f"{root}/body/{body_names[b]}"
        w.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=t)],
                              columns=rr.Transform3D.columns(translation=xpos[:, b],
                                                             quaternion=_xyzw(xquat[:, b])))
        w.index[path] = {"kind": "Transform3D", "rows": n, "unit": "m"}
    # ground reaction force arrows at the centre of pressure of heel/ball contact spheres
    gid = {model.geom(g).name: g for g in range(model.ngeom)}
    for s, side in enumerate(_SIDES):
        heel, ball = gid.get(f"heel_{side[0]}"), gid.get(f"ball_{side[0]}")
        if heel is None or ball is None:
            continue
        fn = rec.contact_force_n[idx, s]                   # (n, 2) heel, ball
        wsum = fn.sum(axis=1)
        wh = np.where(wsum > 1e-9, fn[:, 0] / np.where(wsum > 1e-9, wsum, 1.0), 0.5)
        origin = wh[:, None] * gpos[:, heel] + (1 - wh[:, None]) * gpos[:, ball]
        origin[:, 2] = 0.0
        vec = np.zeros((n, 3))
        vec[:, 0] = rec.grf_n[idx, s, 0] * GRF_M_PER_N
        vec[:, 2] = rec.grf_n[idx, s, 1] * GRF_M_PER_N
        path = f"{root}/grf/{side}"
        w.stream.log(path, rr.Arrows3D.from_fields(radii=0.008, colors=[(230, 60, 30)]),
                     static=True)
        w.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=t)],
                              columns=rr.Arrows3D.columns(origins=origin, vectors=vec))
        w.index[path] = {"kind": "Arrows3D", "rows": n, "unit": "N"}
    if run.device is not None and getattr(run.device, "log", None) is not None:
        _log_afo(w, run, kin, root)


def _orthosis(dev, L: dict) -> dict | None:
    """What the 3D orthosis is drawn from: the cylinder(s) on the joint (bore, stroke), each
    chamber's logged pressure and oil column (``a``: the piston's position from the a-end, the
    log's ``<cylinder>.piston_position_m`` where it has it, else ``x_0 − r θ``; ``b``: the
    rest of the stroke) and the pressure of full colour (the highest relief valve's cracking
    pressure). None for a device without a cylinder on the joint or a logged chamber."""
    act, lever, c = _joint_actuator(dev), _lever_m(dev), _circuit(dev)
    cyl = getattr(getattr(act, "params", None), "cylinder", None)
    if cyl is None or lever is None or c is None:
        return None
    stroke = float(cyl.stroke_m)
    x = _column(dev, L, f"{act.name}.piston_position_m")
    if x is None:
        x0 = float(getattr(act.params, "neutral_position_m", stroke / 2))
        x = x0 - lever * L["ankle_angle_rad"]
    chambers = []
    for name, length in (("a", x), ("b", stroke - x)):
        node = c.port_node.get((act.name, name))
        p = _column(dev, L, node) if node is not None else None
        if p is not None:
            chambers.append((name, p, length))
    if not chambers:
        return None
    reliefs = [float(r.params.cracking_dp_pa) for r in c.components if r.kind == "relief_valve"]
    p_max = max(reliefs) if reliefs else max(max(float(np.max(p)) for _n, p, _l in chambers),
                                             1e5)
    return {"bore_radius_m": math.sqrt(cyl.area_a_m2 / math.pi),
            "stroke_m": stroke, "p_max_pa": p_max, "chambers": chambers}


def _log_afo_shapes(w: _Writer, run: RecordedRun, model, root: str, body_names) -> None:
    """The orthosis's shell on each worn side (static, in the body frames): a cuff around
    the lower shank and a foot plate from heel to ball, in :data:`AFO_COLOUR`."""
    rr = w.rr
    for side in run.device.sides:
        shank, foot = f"shank_{side[0]}", f"foot_{side[0]}"
        gid = {model.geom(g).name: g for g in range(model.ngeom)}
        if shank in body_names and shank in gid:
            g = gid[shank]
            gq = model.geom_quat[g]
            axis = _quat_rotate(gq, np.array([0.0, 0.0, 1.0]))
            half, r = float(model.geom_size[g, 1]), float(model.geom_size[g, 0])
            centre = model.geom_pos[g] - axis * 0.55 * half       # the lower half of the shank
            w.stream.log(f"{root}/body/{shank}/afo/cuff", rr.Boxes3D(
                half_sizes=[[r + 0.012, r + 0.012, 0.35 * half]], centers=[centre],
                quaternions=[_xyzw(gq)], colors=[AFO_COLOUR], fill_mode="solid"),
                static=True)
        heel, ball = gid.get(f"heel_{side[0]}"), gid.get(f"ball_{side[0]}")
        if foot in body_names and heel is not None and ball is not None:
            ph, pb = model.geom_pos[heel], model.geom_pos[ball]
            rad = float(model.geom_size[heel, 0])
            d = pb - ph
            length = float(np.hypot(d[0], d[2])) + 2 * rad
            a = -math.atan2(d[2], d[0])                  # rotation about y: x onto heel→ball
            q = [0.0, math.sin(a / 2), 0.0, math.cos(a / 2)]
            w.stream.log(f"{root}/body/{foot}/afo/plate", rr.Boxes3D(
                half_sizes=[[length / 2, 0.045, 0.006]], centers=[0.5 * (ph + pb)],
                quaternions=[q], colors=[AFO_COLOUR], fill_mode="solid"), static=True)


def _log_afo(w: _Writer, run: RecordedRun, kin: dict, root: str) -> None:
    """The worn orthosis over time: its delivered torque as an arrow ending at the ball of each
    worn foot (:data:`AFO_ARROW_M_PER_NM`; pointing where a force there turns the foot the way
    the torque does: down for plantarflexion, up for dorsiflexion), and
    its cylinders along each worn shank (barrel + oil column per chamber: two for a
    double-acting pair, one for a single-acting cylinder), at the log rows nearest to the
    body-transform times."""
    rr = w.rr
    dev = run.device
    if dev.log.n == 0:
        return
    model, body_names, t_body = kin["model"], kin["body_names"], kin["t"]
    L = dev.log.arrays()
    t_all = L["time_s"][:, 0]
    rows = np.clip(np.searchsorted(t_all, t_body), 0, len(t_all) - 1)
    tau = L.get("delivered_torque_nm")
    gid = {model.geom(g).name: g for g in range(model.ngeom)}
    if tau is not None:
        for k, side in enumerate(dev.sides):
            foot, ball = f"foot_{side[0]}", gid.get(f"ball_{side[0]}")
            jid = [j for j in range(model.njnt) if model.jnt_bodyid[j] == body_names.index(foot)
                   and model.jnt_type[j] == 3] if foot in body_names else []
            if not jid or ball is None:
                continue
            b, j = body_names.index(foot), jid[0]
            ankle = kin["xpos"][:, b] + np.array([_quat_rotate(q, model.jnt_pos[j])
                                                  for q in kin["xquat"][:, b]])
            axis = np.array([_quat_rotate(q, model.jnt_axis[j]) for q in kin["xquat"][:, b]])
            r = kin["gpos"][:, ball] - ankle
            # the direction in which a force at the ball of the foot turns the foot the way
            # the torque does (axis × r̂): down for plantarflexion, up for dorsiflexion; the
            # arrow ends at the ball (a downward one would start there and sink into the floor)
            d = np.cross(axis, r / np.linalg.norm(r, axis=1)[:, None])
            vec = d * (np.asarray(tau, dtype=float)[rows, k] * AFO_ARROW_M_PER_NM)[:, None]
            path = f"{root}/afo_torque/{side}"
            w.stream.log(path, rr.Arrows3D.from_fields(radii=0.012, colors=[AFO_TORQUE_COLOUR]),
                         static=True)
            w.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=t_body)],
                                  columns=rr.Arrows3D.columns(
                                      origins=kin["gpos"][:, ball] - vec, vectors=vec))
            w.index[path] = {"kind": "Arrows3D", "rows": int(len(t_body)), "unit": "N*m"}
    geo = _orthosis(dev, L)
    if geo is None:
        return
    rows = np.unique(rows)
    t = t_all[rows]
    bore_r, stroke, p_max = geo["bore_radius_m"], geo["stroke_m"], geo["p_max_pa"]
    for k, side in enumerate(dev.sides):
        shank = f"shank_{side[0]}"
        if shank not in body_names:
            continue
        b = body_names.index(shank)
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == b
                 and model.geom(g).name == shank]
        if not geoms:
            continue
        g = geoms[0]
        gq = model.geom_quat[g]
        axis = _quat_rotate(gq, np.array([0.0, 0.0, 1.0]))
        perp = np.cross(np.array([0.0, 1.0, 0.0]), axis)
        perp /= max(np.linalg.norm(perp), 1e-12)
        radius = float(model.geom_size[g, 0])
        q = _xyzw(gq)
        base = f"{root}/body/{shank}/afo"
        for name, pressure, oil in geo["chambers"]:
            sign = 1.0 if name == "a" else -1.0
            centre = model.geom_pos[g] + sign * perp * (radius + 1.5 * bore_r + 0.004)
            w.stream.log(f"{base}/barrel_{name}",
                         rr.Cylinders3D(lengths=[stroke], radii=[bore_r * 1.25],
                                        centers=[centre], quaternions=[q],
                                        colors=[(120, 120, 130, 90)], fill_mode="solid"),
                         static=True)
            length = np.clip(oil[rows, k], 0.02 * stroke, stroke)
            # oil column from the barrel's lower end up to the piston
            low_end = centre - axis * stroke / 2
            centres = low_end[None, :] + axis[None, :] * (length / 2)[:, None]
            path = f"{base}/oil_{name}"
            w.stream.log(path, rr.Cylinders3D.from_fields(radii=[bore_r], quaternions=[q],
                                                          fill_mode="solid"), static=True)
            w.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=t)],
                                  columns=rr.Cylinders3D.columns(
                                      lengths=length, centers=centres,
                                      colors=_pressure_colours(pressure[rows, k], p_max)))
            w.index[path] = {"kind": "Cylinders3D", "rows": int(len(t)), "unit": "m"}


#: grey of a schematic's components and of its nodes that carry no pressure (bus, shaft, joint)
SCHEMATIC_GREY = (150, 150, 150, 255)


def _log_schematic(w: _Writer, run: RecordedRun, t_body: np.ndarray) -> str | None:
    """The worn circuit's schematic (:func:`afo_mj.outputs.schematic.schematic_svg`) as 2D
    geometry under ``schematic/<run>``: each component's box and name (static), each node's
    lines and port stubs, a pressure node coloured by its logged pressure over time
    (:func:`_pressure_colours`, blue at 0 through white to red at the highest relief valve's
    cracking pressure or the run's peak), the other nodes grey. Sampled at the body
    transforms' times. Returns the entity root, or None for a device that is no circuit or
    has no log."""
    from afo_mj.outputs.schematic import schematic_geometry, schematic_svg
    rr, dev = w.rr, run.device
    c = _circuit(dev)
    if c is None or dev.log is None or dev.log.n == 0:
        return None
    geo = schematic_geometry(schematic_svg(c, title=run.name))
    root = f"schematic/{run.name}"
    names = sorted(geo["components"])
    boxes = np.array([geo["components"][n] for n in names], dtype=float).reshape(-1, 4)
    w.stream.log(f"{root}/components", rr.Boxes2D(
        mins=boxes[:, :2], sizes=boxes[:, 2:], labels=names, colors=[SCHEMATIC_GREY],
        show_labels=True), static=True)
    w.index[f"{root}/components"] = {"kind": "Boxes2D", "rows": 1, "unit": "-"}
    L = dev.log.arrays()
    t_all = L["time_s"][:, 0]
    rows = np.unique(np.clip(np.searchsorted(t_all, t_body), 0, len(t_all) - 1))
    t = t_all[rows]
    kinds = dict(zip(dev.cc.state_names, dev.cc.state_kinds))
    pressures = {n: _column(dev, L, n) for n in geo["nodes"] if kinds.get(n) == "pressure"}
    pressures = {n: np.asarray(p, dtype=float)[rows, 0] for n, p in pressures.items()
                 if p is not None}
    reliefs = [float(r.params.cracking_dp_pa) for r in c.components if r.kind == "relief_valve"]
    p_max = max(reliefs) if reliefs else max([float(np.max(p)) for p in pressures.values()]
                                             + [1e5])
    for node, strips in geo["nodes"].items():
        path = f"{root}/nodes/{node}"
        if node not in pressures:
            w.stream.log(path, rr.LineStrips2D(strips, colors=[SCHEMATIC_GREY], radii=[1.0],
                                               labels=[node]), static=True)
            w.index[path] = {"kind": "LineStrips2D", "rows": 1, "unit": "-"}
            continue
        w.stream.log(path, rr.LineStrips2D(strips, radii=[1.6], labels=[node]), static=True)
        w.stream.send_columns(path, indexes=[rr.TimeColumn("time", duration=t)],
                              columns=rr.LineStrips2D.columns(
                                  colors=_pressure_colours(pressures[node], p_max)))
        w.index[path] = {"kind": "LineStrips2D", "rows": int(len(t)), "unit": "Pa"}
    return root


# -- blueprint ----------------------------------------------------------------------------------
def eye_placement(n_runs: int) -> dict:
    """The 3D view's eye for ``n_runs`` lanes, in the frame that follows the walkers
    (``world/follow``: x forward with the walkers, y across the lanes, z up; the lanes at
    y = −(n−1)·:data:`LANE_SPACING_M` … 0): ``{"position", "look_target", "eye_up"}``. The eye
    stands ahead of the walkers and to their right (:data:`EYE_AHEAD_M`, :data:`EYE_SIDE_M`
    from the middle lane), above them, and looks at the middle lane at hip height: a
    three-quarter view, in which walkers of neighbouring lanes stand apart on screen unless
    one is over a metre ahead of the other."""
    y_mid = -0.5 * (n_runs - 1) * LANE_SPACING_M
    return {"position": (EYE_AHEAD_M, y_mid - EYE_SIDE_M, EYE_HEIGHT_M),
            "look_target": (0.0, y_mid, LOOK_HEIGHT_M), "eye_up": (0.0, 0.0, 1.0)}


def _key_text(names: Sequence[str], has_normative: bool) -> str:
    """The colour key (markdown) that the plots' hidden legends would have given."""
    lines = ["**Colours** (each plot; hover a line for its name)", ""]
    for i, name in enumerate(names):
        c = _run_colour(i)
        lines.append(f"- `{name}`: RGB {c[0]}, {c[1]}, {c[2]} (right leg); the left leg is "
                     f"the lighter shade")
    if has_normative:
        lines.append("- normative reference: black (mean), grey (±1 SD)")
    lines += ["", "**3D**: each walker carries its run's name; the camera follows the walkers "
              "(view origin `world/follow`). Red arrows: ground reaction force "
              f"({1 / GRF_M_PER_N:.0f} N per metre). Orthosis: dark-blue cuff and foot plate; "
              f"magenta arrow at the ball of the foot = the torque it delivers at the ankle "
              f"({1 / AFO_ARROW_M_PER_NM:.0f} N·m per metre, down = plantarflexion); oil "
              f"columns coloured by chamber pressure (blue 0 bar → red relief pressure)."]
    return "\n".join(lines)


def _blueprint(has_device: bool, has_valve: bool, n_runs: int = 1,
               schematics: Sequence[str] = ()):
    import rerun.blueprint as rrb

    def ts(origin, name):
        # no legend over the data: the key is its own panel, and hovering names a line
        return rrb.TimeSeriesView(origin=origin, name=name,
                                  plot_legend=rrb.PlotLegend(visible=False))

    gait = rrb.Grid(ts("signals/angle_deg/hip", "hip angle [deg]"),
                    ts("signals/angle_deg/knee", "knee angle [deg]"),
                    ts("signals/angle_deg/ankle", "ankle angle [deg]"),
                    ts("signals/ankle_torque_nm", "ankle torque: human, device cmd / delivered "
                                                  "[N·m]"),
                    ts("signals/joint_power_w/ankle", "ankle power, human [W]"),
                    ts("signals/grf_n/vertical", "vertical GRF [N]"),
                    name="gait", grid_columns=2)
    tabs = [gait]
    if has_device:
        hyd = [ts("signals/pressure_bar", "pressures [bar gauge]"),
               ts("signals/flow_l_min", "flows [L/min]"),
               ts("signals/motor_current_a", "motor current [A]"),
               ts("signals/motor_speed_rpm", "motor speed [rpm]")]
        if has_valve:
            hyd.append(ts("signals/valve", "valve position / command [1]"))
        hyd.append(ts("signals/piston_position_mm", "piston from mid-stroke [mm]"))
        tabs.append(rrb.Grid(*hyd, name="hydraulics", grid_columns=2))
        tabs.append(rrb.Grid(ts("signals/device_power_w", "device power by stage [W]"),
                             ts("signals/running_efficiency", "running efficiency [1]"),
                             ts("signals/fluid_temperature_c", "oil temperature [°C]"),
                             ts("signals/gait_phase", "gait phase [1]"),
                             name="energy", grid_columns=2))
        for root in schematics:
            tabs.append(rrb.Spatial2DView(origin=root, name=f"circuit {root.split('/', 1)[1]} "
                                          "(pressure: blue 0 → red relief)"))
    else:
        tabs.append(rrb.Grid(ts("signals/moment_nm", "joint moments [N·m]"),
                             ts("signals/joint_power_w", "joint powers [W]"),
                             ts("signals/gait_phase", "gait phase [1]"),
                             ts("signals/grf_n/forward", "fore-aft GRF [N]"),
                             name="joints", grid_columns=2))
    eye = eye_placement(n_runs)
    walker = rrb.Spatial3DView(
        origin="world/follow", contents="world/**", name="walkers (camera follows)",
        eye_controls=rrb.EyeControls3D(kind="orbital", **eye))
    left = rrb.Vertical(walker,
                        rrb.Horizontal(rrb.TextDocumentView(origin="key", name="key"),
                                       rrb.TextLogView(origin="events", name="gait events")),
                        row_shares=[3, 1])
    return rrb.Blueprint(rrb.Horizontal(left, rrb.Tabs(*tabs), column_shares=[2, 3]),
                         rrb.TimePanel(timeline="time", play_state="playing", loop_mode="all"),
                         collapse_panels=False)


# -- public -------------------------------------------------------------------------------------
def write_recording(path, runs: Sequence[RecordedRun], reference=None,
                    title: str = "afo_mj run", signal_rate_hz: float = SIGNAL_RATE_HZ,
                    transform_rate_hz: float = TRANSFORM_RATE_HZ,
                    signal_tolerance: float = SIGNAL_TOLERANCE) -> dict:
    """Write ``runs`` into one rerun recording at ``path`` (written to a temporary file and
    renamed, so a failure leaves nothing half-written). Returns ``{"path", "recording_id",
    "entities": {entity path: {"kind", "rows", "unit"(, "samples")}}}`` (a signal's
    ``samples``: at ``signal_rate_hz``; its ``rows``: those kept by the thinning).

    Signals are sampled at ``signal_rate_hz`` and thinned
    (:func:`~afo_mj.outputs.series_thinning.thin_indices`) to within ``signal_tolerance`` ×
    each signal's range (0: every sample kept). Static data (geometry, styles, units, the
    floor) is written before the time series, so a viewer reading the file draws each
    series finished as it arrives.

    Raises :class:`RecordingError` for a bad rate or tolerance, a run without 3D data,
    non-finite signals or an unwritable path.
    """
    import rerun as rr
    if not runs:
        raise RecordingError("no runs to record")
    for key, v, lo, hi in (("signal_rate_hz", signal_rate_hz, 1.0, 1e5),
                           ("transform_rate_hz", transform_rate_hz, 1.0, 1e4)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
            raise RecordingError(f"{key} = {v!r}; allowed: a number in [{lo:g}, {hi:g}] Hz")
    if not (isinstance(signal_tolerance, (int, float)) and math.isfinite(signal_tolerance)
            and 0.0 <= signal_tolerance <= 0.1):
        raise RecordingError(f"signal_tolerance = {signal_tolerance!r}; allowed: a number in "
                             f"[0, 0.1] (fraction of each signal's range; 0 keeps every sample)")
    names = [r.name for r in runs]
    if len(set(names)) != len(names):
        raise RecordingError(f"run names must be unique, got {names}")
    out = Path(path)
    if out.suffix != ".rrd":
        raise RecordingError(f"recording path = {str(out)!r}; allowed: a file name ending "
                             f"in .rrd")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f"recording path = {str(out)!r}: {exc}") from None
    tmp = out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.tmp")
    # every run's device signals, from what its log holds, and its 3D poses, before anything
    # is written
    series = {r.name: _device_series(r) for r in runs}
    has_device = any(r.device is not None for r in runs)
    has_valve = any(path.startswith("valve/") for sr in series.values() for path, *_ in sr)
    kins = []
    for i, run in enumerate(runs):
        t_step = max(1, int(round(1.0 / (transform_rate_hz * run.record.sample_period_s))))
        kins.append(_kinematics(run, t_step, (i - (len(runs) - 1)) * LANE_SPACING_M))
    t_follow, x_follow = follow_track(kins)
    x_lo = min(0.0, min(float(k["xpos"][:, 1:, 0].min()) for k in kins))
    x_hi = max(1.0, max(float(k["xpos"][:, 1:, 0].max()) for k in kins))
    recording_id = uuid.uuid4().hex
    stream = rr.RecordingStream("afo_mj", recording_id=recording_id)
    try:
        schematics = [f"schematic/{r.name}" for r in runs
                      if _circuit(r.device) is not None and r.device.log is not None
                      and r.device.log.n > 0]
        stream.save(str(tmp), default_blueprint=_blueprint(has_device, has_valve, len(runs),
                                                           schematics))
        stream.send_recording_name(title)
        w = _Writer(rr, stream, signal_tolerance)
        # static first: floor with a mark every metre (the camera follows the walkers, the
        # marks show them moving), the key
        y_lo = -(len(runs) - 1) * LANE_SPACING_M - 0.5
        stream.log("world/floor", rr.Boxes3D(
            mins=[[x_lo - 1.0, y_lo, -0.01]], sizes=[[x_hi - x_lo + 2.0, -y_lo + 0.5, 0.01]],
            colors=[(205, 205, 195)], fill_mode="solid"), static=True)
        marks = [[[x, y_lo, 0.001], [x, 0.5, 0.001]]
                 for x in np.arange(math.floor(x_lo - 1.0), math.ceil(x_hi + 1.0) + 1)]
        stream.log("world/floor/metre_marks", rr.LineStrips3D(
            marks, colors=[(120, 120, 110)], radii=[0.004]), static=True)
        stream.log("key", rr.TextDocument(_key_text(names, reference is not None),
                                          media_type="text/markdown"), static=True)
        stream.send_columns("world/follow", indexes=[rr.TimeColumn("time", duration=t_follow)],
                            columns=rr.Transform3D.columns(
                                translation=np.column_stack([x_follow, np.zeros_like(x_follow),
                                                             np.zeros_like(x_follow)])))
        w.index["world/follow"] = {"kind": "Transform3D", "rows": int(len(t_follow)),
                                   "unit": "m"}
        for i, run in enumerate(runs):
            dt = run.record.sample_period_s
            s_step = max(1, int(round(1.0 / (signal_rate_hz * dt))))
            _log_body(w, run, kins[i], i)
            if run.device is not None:
                _log_schematic(w, run, kins[i]["t"])
            _log_gait_signals(w, run, i, s_step)
            t_sig = run.record.time_s[::s_step]
            for key, (values, unit, label) in run.extra_signals.items():
                w.scalars(f"signals/{key}/{run.name}", t_sig, np.asarray(values)[::s_step],
                          unit, f"{label} ({run.name})", _run_colour(i))
            _log_device_signals(w, run, i, s_step, series[run.name])
            _log_events(w, run)
        last = runs[-1]
        _log_normative(w, last, reference,
                       max(1, int(round(1.0 / (signal_rate_hz * last.record.sample_period_s)))))
        stream.flush()
        stream.disconnect()
        os.replace(tmp, out)
    except BaseException:
        try:
            stream.disconnect()
        except Exception:                                # pragma: no cover
            pass
        tmp.unlink(missing_ok=True)
        raise
    return {"path": str(out), "recording_id": recording_id, "entities": w.index}


#: unit of a bench series entry by the suffix of its key (SI as simulated)
_SUFFIX_UNITS = (("_rad_s", "rad/s"), ("_deg_s", "deg/s"), ("_m3_s", "m^3/s"), ("_nm", "N*m"),
                 ("_deg", "deg"), ("_rad", "rad"), ("_pa", "Pa"), ("_a", "A"), ("_v", "V"),
                 ("_w", "W"), ("_k", "K"), ("_m", "m"), ("_s", "s"))
#: pause between consecutive bench experiments on the recording's timeline [s]
BENCH_GAP_S = 0.5


def _suffix_unit(key: str) -> str:
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return "1"


def write_bench_recording(path, series: dict, title: str = "afo_mj bench") -> dict:
    """A bench run's time-domain experiments (every ``series`` entry with a ``time_s`` array:
    torque steps, position steps, stiffness sweeps, …) as one recording: the experiments one
    after another on the ``time`` timeline (each shifted to start :data:`BENCH_GAP_S` after
    the previous one ended), every array of the experiment's length as
    ``bench/<experiment>/<key>`` with its unit (from the key's suffix, SI as simulated), and
    a ``bench/experiments`` text log marking where each begins. Frequency sweeps (no
    ``time_s``) are left to the Bode figure. Written atomically, like
    :func:`write_recording`."""
    import rerun as rr
    import rerun.blueprint as rrb
    out = Path(path)
    if out.suffix != ".rrd":
        raise RecordingError(f"recording path = {str(out)!r}; allowed: a file name ending "
                             f"in .rrd")
    timed = {}
    for name, entry in series.items():
        if isinstance(entry, dict) and "time_s" in entry:
            timed[name] = entry
        elif isinstance(entry, dict):       # nested (e.g. per stiffness level)
            for sub, e in entry.items():
                if isinstance(e, dict) and "time_s" in e:
                    timed[f"{name}/{sub}"] = e
    if not timed:
        raise RecordingError("the bench produced no time-domain series to record")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.tmp")
    stream = rr.RecordingStream("afo_mj", recording_id=uuid.uuid4().hex)
    ents = {name: "bench/" + "/".join(rr.escape_entity_path_part(p) for p in name.split("/"))
            for name in timed}
    views = [rrb.TimeSeriesView(origin=ent, name=name) for name, ent in ents.items()]
    try:
        stream.save(str(tmp), default_blueprint=rrb.Blueprint(
            rrb.Vertical(rrb.Grid(*views, grid_columns=2),
                         rrb.TextLogView(origin="bench/experiments", name="experiments"),
                         row_shares=[5, 1]), rrb.TimePanel(timeline="time")))
        stream.send_recording_name(title)
        w = _Writer(rr, stream)
        offset = 0.0
        marks_t, marks = [], []
        for i, (name, e) in enumerate(timed.items()):
            t = np.asarray(e["time_s"], dtype=float).ravel()
            ent = ents[name]
            marks_t.append(offset)
            marks.append(f"start of {name}")
            for key, v in e.items():
                if key.endswith("time_s"):
                    continue
                a = np.asarray(v, dtype=float) if np.ndim(v) else None
                if a is None or a.ndim != 1 or len(a) != len(t):
                    continue
                w.scalars(f"{ent}/{key}", t - t[0] + offset, a, _suffix_unit(key),
                          f"{name}: {key}", _run_colour(i))
            offset += float(t[-1] - t[0]) + BENCH_GAP_S
        stream.send_columns("bench/experiments",
                            indexes=[rr.TimeColumn("time", duration=marks_t)],
                            columns=rr.TextLog.columns(text=marks))
        w.index["bench/experiments"] = {"kind": "TextLog", "rows": len(marks), "unit": ""}
        stream.flush()
        stream.disconnect()
        os.replace(tmp, out)
    except BaseException:
        try:
            stream.disconnect()
        except Exception:                                # pragma: no cover
            pass
        tmp.unlink(missing_ok=True)
        raise
    return {"path": str(out), "entities": w.index}


#: the first bytes of a rerun recording file
_RRD_MAGIC = b"RRF"


def _missing_dirs(path: Path) -> list[Path]:
    """The folders above ``path`` that do not exist yet, nearest first."""
    out = []
    for d in path.parents:
        if d.exists():
            break
        out.append(d)
    return out


def check_recording_path(path, out_dir=None) -> Path:
    """Raise :class:`RecordingError` unless ``path`` can take a recording, before any work: a
    name ending in ``.rrd``; not a directory, nor an existing file other than a rerun
    recording (which it replaces); its folder an existing writable directory or one that can
    be made in one; not the results directory ``out_dir`` itself (inside it is allowed: the
    recording is then written with the results). Returns the path."""
    p = Path(path)
    what = f"--rrd {str(p)!r}"
    if p.is_dir():
        raise RecordingError(f"{what} is a directory; allowed: a file name ending in .rrd")
    if p.suffix != ".rrd":
        raise RecordingError(f"{what} does not end in .rrd; allowed: a file name ending in "
                             f".rrd")
    if p.exists():
        try:
            with open(p, "rb") as f:
                head = f.read(len(_RRD_MAGIC))
        except OSError as exc:
            raise RecordingError(f"{what}: {exc.strerror or exc}") from None
        if head and head != _RRD_MAGIC:
            raise RecordingError(f"{what} exists and is not a rerun recording; allowed: a new "
                                 f"file or a recording to replace")
    missing = _missing_dirs(p.absolute())
    base = (missing[-1] if missing else p.absolute()).parent
    if not base.is_dir():
        raise RecordingError(f"{what}: {str(base)!r} is not a directory; allowed: a file in "
                             f"an existing writable directory (or one that can be made)")
    if not os.access(base, os.W_OK | os.X_OK):
        raise RecordingError(f"{what}: directory {str(base)!r} is not writable")
    if out_dir is not None and p.resolve() == Path(out_dir).resolve():
        raise RecordingError(f"{what} is the results directory --out; allowed: a file "
                             f"inside it or elsewhere")
    return p


class RecordingTarget:
    """Where a ``--rrd`` recording goes, written as part of a results directory's atomic write
    (:func:`afo_mj.outputs.result_dir.write_atomically`).

    Inside ``out_dir`` the recording is one of the results: :meth:`writer` writes it into the
    directory being filled, so it is listed in the manifest and the same command can run
    again. Elsewhere it goes to a temporary file beside ``path`` while the results are written,
    renamed by :meth:`commit` once they are in place. :meth:`discard` removes what an
    unfinished write left: the temporary file and the folders (above ``out_dir`` or the
    recording) that did not exist when the target was made, if empty.
    """

    def __init__(self, path, out_dir):
        self.path = Path(path)
        out, rec = Path(out_dir).resolve(), self.path.resolve()
        self._rel = rec.relative_to(out) if rec != out and rec.is_relative_to(out) else None
        made = _missing_dirs(out) + ([] if self._rel else _missing_dirs(rec))
        self._made = sorted(set(made), key=lambda d: len(d.parts), reverse=True)  # deepest first
        self._tmp: Path | None = None
        self.info: dict | None = None

    def writer(self, record):
        """A results-directory writer (``writer(tmp_dir)``) that calls ``record(file)`` to write
        the recording (its info, ``path`` and ``entities``, or None: no recording)."""
        def write(tmp_dir: Path) -> None:
            if self._rel is not None:
                dest = Path(tmp_dir) / self._rel
                dest.parent.mkdir(parents=True, exist_ok=True)
            else:
                self.path.absolute().parent.mkdir(parents=True, exist_ok=True)
                dest = self._tmp = self.path.absolute().with_name(
                    f".{self.path.name}.{uuid.uuid4().hex[:8]}.part.rrd")
            info = record(dest)
            self.info = None if info is None else {**info, "path": str(self.path)}
            if info is None and self._rel is not None:
                for d in self._rel.parents:          # no empty folder among the results
                    if d.name:
                        try:
                            (Path(tmp_dir) / d).rmdir()
                        except OSError:
                            break
        return write

    def commit(self) -> dict | None:
        """After the results are in place: the recording at its path; returns its info (None:
        no recording was written, and no folder is left for it)."""
        if self.info is None:
            self.discard()
        elif self._tmp is not None:
            os.replace(self._tmp, self.path)
            self._tmp = None
        return self.info

    def discard(self) -> None:
        """Remove the temporary recording and the folders made for this write, if empty."""
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
            self._tmp = None
        for d in self._made:
            try:
                d.rmdir()
            except OSError:
                pass


def write_results_with_recording(out_dir, rrd_path, write_results, record) -> dict | None:
    """A results directory and its recording, written together or not at all, for a results
    writer that cannot take more files (``write_results(path)`` writes the whole results
    directory at a new ``path``, e.g. :func:`afo_mj.outputs.comparison_report.write_comparison`).

    The results are written to a staging directory beside ``out_dir``, then moved, together
    with the recording that ``record(file)`` writes (see :class:`RecordingTarget`), into
    ``out_dir`` by one atomic swap. Anything that fails (an exception, Ctrl-C) leaves nothing
    behind: no staging directory, temporary file or folder made by this call. Returns the
    recording's info (``path``, ``entities``) or None (``record`` wrote none).
    """
    import shutil
    import tempfile

    from afo_mj.outputs.result_dir import MANIFEST, check_result_dir, write_atomically
    out = check_result_dir(out_dir)
    target = RecordingTarget(rrd_path, out)
    stage = None
    try:
        out.absolute().parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.stage-", dir=out.absolute().parent))
        write_results(stage / "results")
        put_recording = target.writer(record)

        def writer(tmp: Path) -> None:
            for entry in (stage / "results").iterdir():
                if entry.name != MANIFEST:
                    os.replace(entry, tmp / entry.name)
            put_recording(tmp)

        write_atomically(out, writer)
        info = target.commit()
    except BaseException:
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        target.discard()                     # the folders made, the staging one removed
        raise
    shutil.rmtree(stage, ignore_errors=True)
    return info


def read_recording_index(path) -> dict[str, dict]:
    """What a ``.rrd`` file holds, read back with rerun's own reader: ``{entity path:
    {"rows": temporal rows, "components": [...], "unit": static unit or None}}``."""
    import rerun as rr
    store = rr.chunk.RrdReader(str(path)).stream().collect()
    out: dict[str, dict] = {}
    for ch in store.stream():
        e = out.setdefault(ch.entity_path.lstrip("/"), {"rows": 0, "components": set(),
                                                         "unit": None})
        rb = ch.to_record_batch()
        cols = [c for c in rb.schema.names if c not in ("rerun.controls.RowId", "time")]
        e["components"].update(cols)
        if ch.is_static:
            if "unit" in rb.schema.names:
                e["unit"] = rb.column("unit").to_pylist()[-1]
                if isinstance(e["unit"], list):
                    e["unit"] = e["unit"][0] if e["unit"] else None
        else:
            e["rows"] += ch.num_rows
    for e in out.values():
        e["components"] = sorted(e["components"])
    return out
