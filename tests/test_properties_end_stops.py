"""Property-based test (hypothesis): a piston driven past its stroke end is reported as end-stop
contact, and one that stays inside its stroke is not, for strokes, lever arms, stop stiffnesses
and motions drawn within their documented ranges.

The reference is the cylinders' geometry alone, written here from their documented kinematics,
not from the stop law: a pulley drive's piston sits at ``x = s/2 − r θ`` and a lever's at
``x = x₀ − r θ``; it is past a stroke end where ``x < 0`` or ``x > s``. The joint's motion is
imposed (``θ = θ₀ + A sin ωt``), so where the piston is at every sample is known without the
circuit. Checked through the summary's own path (the circuit log's ``*.end_stop_torque_nm``
probes → :func:`~afo_mj.metrics.device_flags.end_stop_contact` →
:func:`~afo_mj.metrics.device_flags.device_flags`):

* the ``end_stop_contact`` flag is raised iff the piston goes past a stroke end (draws keep
  clear of the borderline: either at least 5 % of the way short of a stop, or past it by a
  penetration at which the stop's spring alone carries 100× the contact threshold);
  the piston's place is taken from the angle the log holds for each sample;
* stop torque appears only at samples where the geometry has the piston past an end, and at
  the sample of deepest penetration (where the piston is momentarily still, so the stop's
  damping adds nothing) it is there;
* the peak torque reported outside stop contact never exceeds the whole joint's.
"""

from __future__ import annotations

import copy
import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.codegen import build
from afo_mj.circuits.device import CircuitDevice
from afo_mj.metrics.device_flags import (END_STOP_CONTACT_MIN_NM, device_flags,
                                         end_stop_contact, end_stop_torque)
from afo_mj.scenarios.circuit_scenario import library_spec

DT_S = 1e-3
N = 800                      # 0.8 s of imposed motion, one 1.25 Hz cycle
OMEGA = 2 * math.pi * 1.25
#: (library description, cylinder component, lever kind)
CASES = (("lab_bench", "cylinder", "pulley"), ("pump_accumulator", "cylinders", "pulley"),
         ("spring_return", "cylinder", "lever"))


def _stop_angles(kind: str, stroke: float, r: float, x0: float) -> tuple[float, float]:
    """Joint angles at which the piston reaches ``x = s`` (low) and ``x = 0`` (high)."""
    if kind == "pulley":                      # x = s/2 − r θ
        return -stroke / (2 * r), stroke / (2 * r)
    return (x0 - stroke) / r, x0 / r          # x = x0 − r θ


@st.composite
def drawn_motion(draw):
    name, comp, kind = draw(st.sampled_from(CASES))
    stroke = draw(st.floats(0.01, 0.08))
    r = draw(st.floats(0.02, 0.08))
    k = min(math.exp(draw(st.floats(math.log(1e5), math.log(1e11)))), 1e11)  # stop, N/m
    x0 = draw(st.floats(0.2, 0.8)) * stroke if kind == "lever" else 0.5 * stroke
    lo, hi = _stop_angles(kind, stroke, r, x0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    beyond = draw(st.booleans())
    if beyond:
        # past a stop by a penetration whose spring force is ≥ 100× the contact threshold
        pen_min = max(1e-4, 100 * END_STOP_CONTACT_MIN_NM / (r * k))
        pen = draw(st.floats(pen_min, max(pen_min, 3e-3)))
        amplitude = half + pen / r
    else:
        amplitude = draw(st.floats(0.2, 0.95)) * half
    phase = draw(st.floats(0.0, 2 * math.pi))
    return dict(name=name, comp=comp, kind=kind, stroke=stroke, r=r, k=k, x0=x0,
                centre=centre, amplitude=amplitude, phase=phase, beyond=beyond)


def _spec(m: dict) -> dict:
    spec = copy.deepcopy(library_spec(m["name"]))
    p = spec["components"][m["comp"]].setdefault("params", {})
    p["cylinder.stroke_m"] = m["stroke"]
    p["cylinder.end_stop_stiffness_n_m"] = m["k"]
    if m["kind"] == "pulley":
        p["pulley_radius_m"] = m["r"]
    else:
        p["moment_arm_m"] = m["r"]
        p["neutral_position_m"] = m["x0"]
    return spec


@settings(max_examples=24, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(drawn_motion())
@example({'name': 'lab_bench', 'comp': 'cylinder', 'kind': 'pulley',
          'stroke': 0.013125891509670105, 'r': 0.0625, 'k': 442413.3920089205,
          'x0': 0.006562945754835053, 'centre': 0.0, 'amplitude': 0.11376984940687546,
          'phase': 4.3203125, 'beyond': True})
def test_stop_contact_is_reported_iff_the_piston_passes_a_stroke_end(m):
    # N + 1 imposed samples for N intervals: each logged sample is the state at its
    # interval's end, the next imposed angle (with N angles the last interval would have no
    # end angle: the draw below found its log holding the start angle beside the stop torque
    # of the predicted end, 13 µm inside the stroke)
    t = np.arange(N + 1) * DT_S
    th = m["centre"] + m["amplitude"] * np.sin(OMEGA * t + m["phase"])
    thd = m["amplitude"] * OMEGA * np.cos(OMEGA * t + m["phase"])
    dev = CircuitDevice(build(Circuit.from_dict(_spec(m))))
    log = dev.run_imposed(np.zeros(N), th, thd)
    stop = end_stop_torque(log)
    assert stop is not None and np.all(np.isfinite(stop))
    torque = np.asarray(log["torque_nm"], dtype=float)
    assert np.all(np.isfinite(torque))

    # the geometric reference, at the joint angle the log holds for each sample (the state at
    # the end of the sample's interval: the next imposed angle)
    th_log = np.asarray(log["angle_rad"], dtype=float)
    assert np.max(np.abs(th_log - th[1:])) < 1e-9 * max(1.0, m["amplitude"])
    x = (0.5 * m["stroke"] if m["kind"] == "pulley" else m["x0"]) - m["r"] * th_log
    pen = np.maximum(-x, 0.0) + np.maximum(x - m["stroke"], 0.0)

    contact = end_stop_contact(stop, torque, DT_S, 1)
    flags = device_flags(contact, "actuator", False)
    in_contact = np.abs(stop) > END_STOP_CONTACT_MIN_NM
    assert flags["end_stop_contact"] is m["beyond"], (m, float(pen.max()), contact)
    assert ("end_stop_contact" in flags["flags"]) is m["beyond"]
    assert not np.any(in_contact & (pen <= 0.0)), "stop torque while inside the stroke"
    if m["beyond"]:
        assert in_contact[int(np.argmax(pen))], "no stop torque at the deepest penetration"
        assert contact["contact_time_s"] > 0.0 and contact["impulse_nm_s_per_stride"] > 0.0
    else:
        assert contact["contact_time_s"] == 0.0 and contact["peak_torque_nm"] == 0.0
    free = contact["delivered_peak_outside_contact_nm"]
    assert math.isnan(free) or free <= float(np.max(np.abs(torque))) + 1e-12
