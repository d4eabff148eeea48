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
* ``flag`` (:func:`check_pressure_reference`): a pressure channel whose low level sits one
  atmosphere (≈ 101 kPa) above the rig's declared charge looks absolute, while afo_mj's
  pressures are gauge; one atmosphere below it, the declared charge looks absolute. The unit
  check of the loader catches an absolute record of a vented circuit (its minimum at 1 atm);
  on a pre-charged circuit (the HAFO's 1.5 MPa reservoir) the shifted record passes it.
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

from afo_mj.calibration.measured_data import ATMOSPHERE_PA

__all__ = ["RecordFinding", "check_record", "check_signs", "check_pressure_reference",
           "declared_charge_pa", "PRESSURE_CHANNELS", "SIGN_FLIP_CORRELATION"]

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


#: a low level within this fraction of one atmosphere of "charge ± 1 atm" is flagged; the
#: gauge records of the presets sit within -0.3 atm of their charge (check-valve dips)
ATMOSPHERE_MATCH = 0.5
#: the low level of a channel: this percentile of its moving average over LOW_LEVEL_WINDOW_S
LOW_LEVEL_PERCENTILE = 1.0
LOW_LEVEL_WINDOW_S = 0.01


def declared_charge_pa(circuit) -> float | None:
    """The gauge pressure [Pa] the declared ``circuit`` holds its lines at when idle: the
    lowest of its reservoirs' pressures (the HAFO's charge reservoir, a valve circuit's tank),
    else the pressure its nodes start at (``options.initial_pressure_pa``); None without a
    circuit."""
    if circuit is None:
        return None
    res = [float(c.params.pressure_pa) for c in getattr(circuit, "components", ())
           if getattr(c, "kind", "") == "reservoir"]
    if res:
        return min(res)
    opts = getattr(circuit, "options", None)
    p0 = getattr(opts, "initial_pressure_pa", None)
    return None if p0 is None else float(p0)


def _low_level(x: np.ndarray, n_window: int) -> float:
    """A channel's low level: the :data:`LOW_LEVEL_PERCENTILE` percentile of its moving
    average over ``n_window`` samples (the average takes the sensor noise out, the percentile
    leaves out the deepest transients)."""
    n = max(1, min(int(n_window), len(x)))
    smooth = np.convolve(x, np.ones(n) / n, mode="valid")
    return float(np.percentile(smooth, LOW_LEVEL_PERCENTILE))


def check_pressure_reference(channels: Mapping[str, np.ndarray], charge_pa: float,
                             sample_period_s: float) -> list[RecordFinding]:
    """Flags for pressure channels logged against the wrong reference (absolute vs gauge).

    What it tests: afo_mj's pressures are gauge, and an idle pre-charged circuit holds its
    lines at the declared charge ``charge_pa`` (gauge; :func:`declared_charge_pa`), so a
    gauge record's low level (:func:`_low_level`) sits at or a little below it. A low level
    ``charge + 1 atm`` (within :data:`ATMOSPHERE_MATCH` atm) is a record logged in absolute
    pressure; ``charge − 1 atm`` is a gauge record against a charge declared in absolute
    pressure. The loader's unit check catches the first case only when the charge is ≈ 0
    (the minimum then sits at 1 atm); on a charged circuit this check is what notices. A line
    that truly never falls to the charge by about an atmosphere is flagged too: the message
    says so. Example: the HAFO (charge 1.5 MPa) with its record shifted by +101325 Pa gives
    a low level ≈ 1.59 MPa, flagged with an offset of ≈ +0.9e5 Pa (one atmosphere less the
    record's dips below the charge)."""
    out: list[RecordFinding] = []
    n_window = int(round(LOW_LEVEL_WINDOW_S / sample_period_s)) if sample_period_s > 0 else 1
    tol = ATMOSPHERE_MATCH * ATMOSPHERE_PA
    for name in PRESSURE_CHANNELS:
        p = channels.get(name)
        if p is None or not len(p):
            continue
        low = _low_level(np.asarray(p, dtype=float), n_window)
        offset = low - charge_pa
        if abs(offset - ATMOSPHERE_PA) <= tol:
            out.append(RecordFinding(
                "flag", "pressure_reference", name,
                f"{name}'s low level is {low:.4g} Pa, {offset:+.3g} Pa above the declared "
                f"charge of {charge_pa:.4g} Pa (gauge), about one atmosphere "
                f"({ATMOSPHERE_PA:g} Pa): the record looks like absolute pressure, and "
                f"afo_mj's pressures are gauge. Subtract {ATMOSPHERE_PA:g} Pa (or the "
                f"sensor's reading at rest, vented) from {name}; if the record is gauge, the "
                f"rig's charge is about one atmosphere above the declared one (or this line "
                f"never falls to it): correct the declared charge"))
        elif abs(offset + ATMOSPHERE_PA) <= tol and charge_pa >= ATMOSPHERE_PA - tol:
            out.append(RecordFinding(
                "flag", "pressure_reference", name,
                f"{name}'s low level is {low:.4g} Pa, {offset:+.3g} Pa below the declared "
                f"charge of {charge_pa:.4g} Pa, about one atmosphere ({ATMOSPHERE_PA:g} "
                f"Pa): the declared charge looks like an absolute pressure, and afo_mj's "
                f"pressures (a reservoir's pressure_pa, a circuit's initial_pressure_pa) are "
                f"gauge. Declare the charge {ATMOSPHERE_PA:g} Pa lower, or check the "
                f"record's reference"))
    return out


def check_record(channels: Mapping[str, np.ndarray], params,
                 noise: Mapping[str, float] | None = None,
                 inputs: tuple = (), charge_pa: float | None = None,
                 sample_period_s: float | None = None) -> list[RecordFinding]:
    """Compare the record's ``channels`` (SI, gauge pressures; ``noise``: declared sensor σ;
    ``inputs``: the channels imposed on the model) with the declared rig ``params`` (a HAFO or
    valve-circuit parameter set); returns the findings, refusals first. With ``charge_pa``
    (the rig's declared charge, gauge) and ``sample_period_s`` the pressure channels' reference
    is checked too (:func:`check_pressure_reference`). Example: an angle logged in degrees
    (±10 "rad") on the HAFO (±0.56 rad) is refused."""
    out: list[RecordFinding] = []
    if charge_pa is not None and sample_period_s is not None:
        out += check_pressure_reference(channels, charge_pa, sample_period_s)
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
