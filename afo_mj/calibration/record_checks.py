"""Checks of a measured record against the rig it is said to come from, before anything is fitted.

A record can be well formed (units, channels, sidecar: :mod:`afo_mj.calibration.measured_data`)
and still not fit the declared rig: an angle that would drive the piston past its end stops, or
pressures above the relief valve's cracking setting. Fitted as they are, such records give a
confident verdict on a mistake. :func:`check_record` returns what it finds:

* ``refuse``: the record cannot come from the declared rig. The piston travel implied by the
  measured ankle angle exceeds the cylinder's stroke: a piston-cable cylinder on a pulley of
  radius ``r`` moves ``x = r θ`` from mid-stroke (the HAFO's actuator, Neubauer 2017 ch. 5),
  so ``|θ| ≤ stroke / (2 r)``. An angle logged in degrees, a flipped zero or a wrong
  declared pulley or stroke all show up here.
* ``refuse`` after the first replay (:func:`check_signs`): an output that the declared rig,
  replayed with the record's inputs, reproduces with the opposite sign (correlation below
  :data:`SIGN_FLIP_CORRELATION`) is a flipped sign convention on that channel or on an
  imposed input (dorsiflexion positive, torque and angle alike), not a missing effect: no fit
  can turn an anti-correlated channel into a good one, and an effect search on it would name
  whatever reduces the misfit most.
* ``flag``: the record may be right but the declared rig cannot reproduce it. A gauge pressure
  at or above the relief valve's cracking pressure means the relief valve opened in the record
  (or its declared setting is too low), and the lean model relieves there too. An imposed
  ankle angle whose declared sensor noise σθ, through the oil's stiffness K with the pump held
  (Merritt, *Hydraulic Control Systems*, §5.3; :meth:`hydraulic_stiffness_nm_per_rad`),
  becomes a torque noise K σθ well above the torque sensor's own: replaying the noisy angle
  swamps the outputs.
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np

__all__ = ["RecordFinding", "check_record", "check_signs", "PRESSURE_CHANNELS",
           "SIGN_FLIP_CORRELATION"]

#: gauge-pressure channels compared with the relief setting
PRESSURE_CHANNELS = ("pressure_a_pa", "pressure_b_pa", "chamber_a_pa", "chamber_b_pa",
                     "pump_pressure_pa", "supply_pressure_pa")


@dataclasses.dataclass(frozen=True)
class RecordFinding:
    """One finding: ``severity`` ``"refuse"`` or ``"flag"``, the check, the channel and the
    message (the channel, the value and what the declared rig allows)."""

    severity: str
    check: str
    channel: str
    message: str


def _stroke_limit_rad(params) -> float | None:
    """Largest |ankle angle| of a centred piston-cable cylinder: ``stroke / (2 r)``."""
    cyl = getattr(params, "cylinder", None)
    r = getattr(params, "pulley_radius_m", None)
    if cyl is None or r is None or getattr(cyl, "kind", "") != "piston_cable":
        return None
    return 0.5 * float(cyl.stroke_m) / float(r)


#: an imposed angle's noise is flagged when K σθ exceeds this many torque-sensor σ
NOISE_SWAMP_RATIO = 3.0


def check_record(channels: Mapping[str, np.ndarray], params,
                 noise: Mapping[str, float] | None = None,
                 inputs: tuple = ()) -> list[RecordFinding]:
    """Compare the record's ``channels`` (SI, gauge pressures; ``noise``: declared sensor σ;
    ``inputs``: the channels imposed on the model) with the declared rig ``params`` (a HAFO or
    valve-circuit parameter set); returns the findings, refusals first. Example: an angle
    logged in degrees (±10 "rad") on the HAFO (±0.56 rad) is refused."""
    out: list[RecordFinding] = []
    lim = _stroke_limit_rad(params)
    ang = channels.get("ankle_angle_rad")
    if lim is not None and ang is not None and len(ang):
        peak = float(np.max(np.abs(ang)))
        if peak > lim:
            out.append(RecordFinding(
                "refuse", "stroke", "ankle_angle_rad",
                f"ankle_angle_rad reaches {peak:.3g} rad ({np.degrees(peak):.3g} deg), past the "
                f"declared cylinder's end stops at ±{lim:.3g} rad (stroke "
                f"{params.cylinder.stroke_m:g} m on a {params.pulley_radius_m:g} m pulley, "
                f"centred); allowed: |angle| <= {lim:.3g} rad. Check the angle's unit (rad, "
                f"not deg), its zero (mid-stroke) and the declared stroke and pulley radius"))
    relief = getattr(getattr(params, "relief", None), "cracking_dp_pa", None)
    if relief is not None:
        for name in PRESSURE_CHANNELS:
            p = channels.get(name)
            if p is None or not len(p):
                continue
            peak = float(np.max(p))
            if peak >= relief:
                frac = float(np.mean(p >= relief))
                out.append(RecordFinding(
                    "flag", "relief", name,
                    f"{name} reaches {peak / 1e6:.3g} MPa (gauge), at or above the declared "
                    f"relief cracking pressure {relief / 1e6:.3g} MPa for {100 * frac:.2g} % "
                    f"of the record: the relief valve opened (or its declared setting is "
                    f"below the rig's); the fit there measures the relief, not the effect "
                    f"sought. Check relief.cracking_dp_pa and that the pressures are gauge"))
    noise = noise or {}
    sig_th = noise.get("ankle_angle_rad")
    stiff = getattr(params, "hydraulic_stiffness_nm_per_rad", None)
    if "ankle_angle_rad" in inputs and sig_th and stiff is not None:
        k = float(stiff())
        tau = k * float(sig_th)
        sig_tau = noise.get("ankle_torque_nm")
        ref = float(sig_tau) if sig_tau else None
        if ref is not None and tau > NOISE_SWAMP_RATIO * ref:
            dp = tau / float(params.torque_per_pressure_m3)
            out.append(RecordFinding(
                "flag", "input_noise", "ankle_angle_rad",
                f"the imposed ankle_angle_rad has a declared noise σ = {float(sig_th):.3g} rad; "
                f"through the oil's stiffness with the pump held ({k:.3g} N*m/rad) that is "
                f"~{tau:.3g} N*m of ankle torque (~{dp / 1e6:.2g} MPa of line pressure "
                f"difference), {tau / ref:.2g}x the torque sensor's σ = {ref:.3g} N*m: the "
                f"replayed outputs will be dominated by the angle's noise. Filter the angle "
                f"(or use a finer encoder) before calibrating"))
    out.sort(key=lambda f: f.severity != "refuse")
    return out


#: an output whose correlation with the declared rig's replay is below this is refused
SIGN_FLIP_CORRELATION = -0.5


def check_signs(measured: Mapping[str, np.ndarray], replayed: Mapping[str, np.ndarray],
                inputs: tuple = ()) -> list[RecordFinding]:
    """Refusals for outputs anti-correlated with the replay of the declared rig (Pearson
    correlation below :data:`SIGN_FLIP_CORRELATION` over the samples given). Example: a
    torque channel logged plantarflexion-positive gives ρ ≈ −1 against the replay."""
    out = []
    for name, m in measured.items():
        r = replayed.get(name)
        if r is None or len(m) < 3 or np.std(m) == 0 or np.std(r) == 0:
            continue
        rho = float(np.corrcoef(m, r)[0, 1])
        if rho < SIGN_FLIP_CORRELATION:
            imposed = ", ".join(i for i in inputs if i.endswith(("_rad", "_nm")))
            out.append(RecordFinding(
                "refuse", "sign", name,
                f"{name} is anti-correlated with the declared rig's replay of this record "
                f"(correlation {rho:.2f}; allowed: >= {SIGN_FLIP_CORRELATION:g}): a flipped "
                f"sign convention on {name}"
                + (f" or on the imposed {imposed}" if imposed else "")
                + " (afo_mj: dorsiflexion positive for angles and torques, positive motor "
                  "voltage drives plantarflexion, pressures gauge). Fix the record's sign; "
                  "no effect is searched on a flipped channel"))
    return out
