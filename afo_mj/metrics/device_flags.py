"""What an orthosis did to the ankle besides following its command: end-stop contact, net
braking and poor torque tracking, each a number in the summary and a flag a study can
constrain on; and the steps its circuit's solver accepted unconverged or its battery could
not supply.

A device's "peak torque" is only a figure of the device when the torque came from its
actuator. A piston driven past its stroke end meets a stop (a stiff spring–damper,
:func:`afo_mj.hydraulics.laws.end_stop_force_n`) and the joint then carries the stop's
reaction, which can be several times the commanded torque; a pump back-driven by the ankle
against its relief valve brakes the walk. Neither is assistance, and both used to pass as a
large "device peak torque". The figures here are computed from the device log's columns
(``delivered_torque_nm``, ``commanded_torque_nm`` and every ``*.end_stop_torque_nm`` probe the
circuit's cylinders write) over the analysed strides.

Classification (module constants, SI):

* **end-stop contact**: a sample where the stops' share of the joint torque exceeds
  :data:`END_STOP_CONTACT_MIN_NM` in magnitude. Reported: contact time per stride and as a
  fraction of the analysed time, the number of contacts (onsets) per stride, the stops'
  torque impulse ``∫|τ_stop| dt`` per stride and their peak torque. ``peak_torque_nm`` is then
  the largest delivered torque over the samples *outside* stop contact.
* **brake**: the device's net mechanical work on the ankle per stride is negative
  (:func:`mechanical_role`, the classification the device comparison ranks by).
* **poor tracking**: the torque-tracking RMS error exceeds :data:`TRACKING_POOR_FRACTION` of
  the commanded peak (and :data:`TRACKING_POOR_MIN_NM`): the device did not deliver what its
  controller asked for, so its figures describe another assistance than the one named.
* **unconverged solver steps** (``newton_unconverged``): the circuit's Newton iteration did not
  converge in some (sub-)steps even at the smallest sub-step, and they were accepted as they
  stood (``newton_unconverged_steps`` of the device ledger). Those steps are not the model's
  backward-Euler steps: the figures of the run, and its energy ledger, are not the model's.
* **battery overload** (``battery_overload``): in some (sub-)steps the bus drew more than the
  battery's matched-load power ``V_oc²/(4R)``, the most a pack of that internal resistance can
  deliver (``battery_overload_steps`` of the device ledger; the excess is booked as its store
  ``battery_overload``, energy no part of the model supplied,
  :class:`afo_mj.circuits.components.Battery`): the run's figures are not a real pack's.

Example::

    >>> import numpy as np
    >>> stop = np.array([0.0, 0.0, 50.0, 80.0, 0.0, 0.0])
    >>> c = end_stop_contact(stop, np.array([10., 20., 70., 100., 20., 5.]), 1e-3, 1)
    >>> c["contact_time_s_per_stride"], c["contacts_per_stride"], c["peak_torque_nm"]
    (0.002, 1.0, 80.0)
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["END_STOP_CONTACT_MIN_NM", "TRACKING_POOR_FRACTION", "TRACKING_POOR_MIN_NM",
           "NET_WORK_MIN_J_PER_STRIDE", "NET_WORK_MIN_FRACTION", "END_STOP_PROBE",
           "end_stop_torque", "end_stop_contact", "mechanical_role", "tracking_flag",
           "device_flags"]

#: Stop contact: the stops carry more than this torque at the joint [N·m]. The stops are a
#: 5e7 N/m spring on a 40 mm pulley (~80 kN·m/rad), so 0.1 N·m is ~1 µrad of penetration:
#: any real contact, and no numerical grazing.
END_STOP_CONTACT_MIN_NM = 0.1
#: Tracking is poor when the RMS torque error exceeds this fraction of the commanded peak ...
TRACKING_POOR_FRACTION = 0.25
#: ... and this absolute error [N·m] (a transparent device commands 0: its RMS error is the
#: torque it fails to cancel, judged against this floor alone).
TRACKING_POOR_MIN_NM = 5.0
#: An actuator adds at least this net mechanical work to the ankle per stride [J]; below it a
#: device does not assist measurably (a healthy 75 kg walker's ankle does ~20 J/stride of
#: positive work, Winter 2009, so 1 J is ~5 %, well below any assistance worth comparing).
NET_WORK_MIN_J_PER_STRIDE = 1.0
#: ... and its net work is at least this fraction of its positive output, i.e. it absorbs back
#: at most half of what it puts out (otherwise it is mostly a damper that also pushes).
NET_WORK_MIN_FRACTION = 0.5
#: The suffix of a cylinder component's end-stop probe in a circuit device's log.
END_STOP_PROBE = ".end_stop_torque_nm"


def _num(x) -> float:
    if x is None:
        return math.nan
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def end_stop_torque(log: dict) -> np.ndarray | None:
    """The stops' share of the joint torque per sample and worn side [N·m]: the sum of every
    ``<component>.end_stop_torque_nm`` column of a device log (``None`` when the device has
    no cylinder with end stops)."""
    cols = [v for k, v in log.items() if k.endswith(END_STOP_PROBE)]
    if not cols:
        return None
    return np.sum(cols, axis=0)


def end_stop_contact(stop_torque_nm, delivered_torque_nm, dt_s: float,
                     n_strides: int) -> dict:
    """End-stop contact over one side's samples (already cut to the analysed strides).

    ``stop_torque_nm``: the stops' share of the joint torque per sample; ``delivered_torque_nm``
    the device's whole joint torque; ``dt_s`` the sample period; ``n_strides`` the strides the
    samples span (per-stride figures divide by it). Returns ``contact_time_s_per_stride``,
    ``contact_fraction``, ``contacts_per_stride`` (onsets), ``impulse_nm_s_per_stride``
    (``∫|τ_stop| dt``, rectangle rule at the log's period), ``peak_torque_nm`` (the stops'
    largest |torque|), ``contact_time_s`` (the whole span's) and
    ``delivered_peak_outside_contact_nm`` (largest |delivered| where the
    stops carry no torque; NaN when every sample is in contact)."""
    stop = np.abs(np.asarray(stop_torque_nm, dtype=float))
    dlv = np.abs(np.asarray(delivered_torque_nm, dtype=float))
    contact = stop > END_STOP_CONTACT_MIN_NM
    n = max(int(n_strides), 1)
    onsets = int(np.count_nonzero(contact[1:] & ~contact[:-1]) + (1 if contact[:1].any()
                                                                  else 0))
    free = dlv[~contact]
    return {
        "contact_time_s": float(np.count_nonzero(contact) * dt_s),
        "contact_time_s_per_stride": float(np.count_nonzero(contact) * dt_s / n),
        "contact_fraction": float(np.mean(contact)) if contact.size else 0.0,
        "contacts_per_stride": onsets / n,
        "impulse_nm_s_per_stride": float(np.sum(stop[contact]) * dt_s / n),
        "peak_torque_nm": float(np.max(stop)) if stop.size else 0.0,
        "delivered_peak_outside_contact_nm": float(np.max(free)) if free.size else math.nan,
    }


def mechanical_role(net_j: float, positive_j: float) -> tuple[str, str]:
    """``(role, reason)`` of a device from its net and positive mechanical work on the ankle
    per stride [J]: ``("actuator", "")`` when ``net >= NET_WORK_MIN_J_PER_STRIDE`` and
    ``net >= NET_WORK_MIN_FRACTION × positive``; ``"brake"`` when ``net < 0`` (it takes energy
    out of the ankle, e.g. a back-driven pump or a damper); ``"near_zero"`` otherwise; the
    reason says why efficiency and battery runtime are not given. Unknown (non-finite) work
    gives ``("", reason)``."""
    net, pos = _num(net_j), _num(positive_j)
    what = "efficiency_total, battery_runtime_h and the efficiency ranks are not given"
    if not (math.isfinite(net) and math.isfinite(pos)):
        return "", f"net mechanical work unknown: {what}"
    work = f"net {net:.2f} J/stride, positive {pos:.2f} J/stride"
    if net >= NET_WORK_MIN_J_PER_STRIDE and net >= NET_WORK_MIN_FRACTION * pos:
        return "actuator", ""
    if net < 0:
        return "brake", (f"brake: absorbs net work from the ankle ({work}); its low energy "
                         f"draw is not efficiency: {what}")
    if net >= NET_WORK_MIN_J_PER_STRIDE:
        return "near_zero", (f"absorbs back more than {1 - NET_WORK_MIN_FRACTION:.0%} of "
                             f"what it puts out ({work}): {what}")
    return "near_zero", (f"net work below {NET_WORK_MIN_J_PER_STRIDE:g} J/stride ({work}): "
                         f"no measurable assistance: {what}")


def tracking_flag(rmse_nm: float, commanded_peak_nm: float) -> bool:
    """True when the RMS torque error is above :data:`TRACKING_POOR_MIN_NM` and above
    :data:`TRACKING_POOR_FRACTION` of the commanded peak |torque|."""
    e, c = _num(rmse_nm), abs(_num(commanded_peak_nm))
    if not math.isfinite(e):
        return False
    return e > TRACKING_POOR_MIN_NM and (not math.isfinite(c) or e > TRACKING_POOR_FRACTION * c)


def device_flags(contact: dict | None, role: str, tracking_poor: bool,
                 newton_unconverged_steps: int = 0, battery_overload_steps: int = 0) -> dict:
    """The summary's flags (booleans, so that a study constrains on them as 0/1) and the
    list of what was flagged (``flags``, for the console and the reader).
    ``newton_unconverged_steps``: the device ledger's count of (sub-)steps accepted with their
    Newton iteration unconverged; ``battery_overload_steps``: its count of (sub-)steps whose
    bus power exceeded the battery's matched-load power."""
    stop = bool(contact and contact["contact_time_s"] > 0.0)
    out = {"end_stop_contact": stop, "brake": role == "brake",
           "tracking_poor": bool(tracking_poor),
           "newton_unconverged": int(newton_unconverged_steps) > 0,
           "battery_overload": int(battery_overload_steps) > 0}
    out["flags"] = [k for k, v in out.items() if v]
    return out
