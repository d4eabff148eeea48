"""Segment masses, lengths, centre-of-mass positions and inertias of a sagittal-plane human.

Source: P. de Leva (1996), "Adjustments to Zatsiorsky–Seluyanov's segment inertia parameters",
J. Biomech. 29(9):1223–1230, Table 4 (adult males; reference stature 1741 mm, mass 73.0 kg).
Each segment has a mass fraction of body mass, a length between its two end points, the
centre-of-mass (CoM) position as a fraction of that length from the proximal point and a
radius of gyration about the CoM for the sagittal axis as a fraction of the length. Lengths
scale with stature (H / 1.741 m) and masses with body mass; the moment of inertia is
I = m·(r·L)².

The planar model lumps head, trunk and both arms (hanging at the sides) into one HAT body
("head, arms and trunk", Winter's term) whose CoM and inertia about the hip axis follow from
the de Leva segments by the parallel-axis theorem. The ankle height above the sole and the heel
position come from Winter's height fractions (D. A. Winter, *Biomechanics and Motor Control of
Human Movement*, 4th ed., Fig. 4.1: ankle height 0.039 H, foot length 0.152 H).

Example
-------
>>> body = scale_body(75.0, 1.75)
>>> round(body.thigh.mass_kg, 2), round(body.thigh.length_m, 3)
(10.62, 0.424)
"""

from __future__ import annotations

import dataclasses
import math

from afo_mj.hydraulics.params import ParameterError, Parameters, param

__all__ = ["Segment", "BodySegments", "BodySize", "scale_body", "DE_LEVA_REFERENCE_STATURE_M"]

#: de Leva (1996) reference male stature [m], to which the segment lengths below belong.
DE_LEVA_REFERENCE_STATURE_M = 1.741

# de Leva (1996) Table 4, males: (mass fraction, length [m] at 1.741 m, CoM from proximal end
# as fraction of length, sagittal radius of gyration as fraction of length).
_DE_LEVA_MALE = {
    # head: vertex → cervicale (C7); CoM measured from the vertex
    "head": (0.0694, 0.2033, 0.5976, 0.362),
    # trunk: cervicale → mid-hip (hip joint centres); CoM from cervicale
    "trunk": (0.4346, 0.5319, 0.5138, 0.328),
    "upper_arm": (0.0271, 0.2817, 0.5772, 0.285),
    "forearm": (0.0162, 0.2689, 0.4574, 0.276),
    "hand": (0.0061, 0.0862, 0.7900, 0.628),
    "thigh": (0.1416, 0.4222, 0.4095, 0.329),
    "shank": (0.0433, 0.4340, 0.4459, 0.255),
    # foot: heel → toe tip; CoM from the heel
    "foot": (0.0137, 0.2581, 0.4415, 0.257),
}
# Shoulder joint centre below cervicale, fraction of stature (de Leva's upper-arm origin,
# Winter's shoulder height 0.818 H vs C7 ≈ 0.87 H gives ≈ 0.05 H).
_SHOULDER_BELOW_C7_FRACTION = 0.05 / 1.0
# Winter (Fig. 4.1): ankle joint height above the sole and heel-to-ankle distance, fractions of H.
_ANKLE_HEIGHT_FRACTION = 0.039
_HEEL_TO_ANKLE_FRACTION = 0.039


@dataclasses.dataclass(frozen=True)
class Segment:
    """One rigid segment: mass, length, CoM from its proximal joint, inertia about its CoM."""

    name: str
    mass_kg: float
    length_m: float
    com_from_proximal_m: float
    inertia_kg_m2: float


@dataclasses.dataclass(frozen=True)
class BodySegments:
    """The segments of the planar walker (one leg's segments; both legs are alike).

    ``hat`` is head + arms + trunk about the hip axis: ``com_from_proximal_m`` is its CoM height
    above the hip joint centres and ``length_m`` the hip-to-vertex height.
    ``ankle_height_m`` is the ankle axis above the sole, ``heel_to_ankle_m`` the horizontal
    distance from the back of the heel to the ankle axis, ``foot.length_m`` heel to toe tip.
    """

    body_mass_kg: float
    stature_m: float
    hat: Segment
    thigh: Segment
    shank: Segment
    foot: Segment
    ankle_height_m: float
    heel_to_ankle_m: float

    @property
    def hip_height_m(self) -> float:
        """Hip joint centre above the floor standing upright (ankle + shank + thigh)."""
        return self.ankle_height_m + self.shank.length_m + self.thigh.length_m

    @property
    def total_mass_kg(self) -> float:
        return self.hat.mass_kg + 2.0 * (self.thigh.mass_kg + self.shank.mass_kg
                                         + self.foot.mass_kg)


@dataclasses.dataclass(frozen=True)
class BodySize(Parameters):
    """Body mass and stature of the walker, with ranges that cover children to large adults."""

    body_mass_kg: float = param(75.0, unit="kg", lo=10.0, hi=200.0, doc="body mass")
    height_m: float = param(1.75, unit="m", lo=0.8, hi=2.2, doc="stature (standing height)")



def _segment(name: str, body_mass_kg: float, scale: float) -> Segment:
    frac, length, com, gyr = _DE_LEVA_MALE[name]
    length_m = length * scale
    m = frac * body_mass_kg
    return Segment(name, m, length_m, com * length_m, m * (gyr * length_m) ** 2)


def scale_body(body_mass_kg: float, height_m: float) -> BodySegments:
    """Scale de Leva's (1996) male segment table to a body mass and stature.

    Lengths scale as ``height_m / 1.741``, masses as ``body_mass_kg``; inertias follow as
    m·(r·L)². The HAT inertia about its own CoM is the parallel-axis sum of head, trunk and two
    hanging arms (upper arm, forearm, hand in a vertical line below the shoulder).
    """
    size = BodySize(body_mass_kg=body_mass_kg, height_m=height_m)  # range check
    mass, h = size.body_mass_kg, size.height_m
    s = h / DE_LEVA_REFERENCE_STATURE_M
    seg = {n: _segment(n, mass, s) for n in _DE_LEVA_MALE}

    # HAT parts as (mass, CoM height above hip axis, own inertia about its CoM).
    trunk, head = seg["trunk"], seg["head"]
    c7 = trunk.length_m
    parts = [
        (trunk.mass_kg, c7 - trunk.com_from_proximal_m, trunk.inertia_kg_m2),
        (head.mass_kg, c7 + head.length_m - head.com_from_proximal_m, head.inertia_kg_m2),
    ]
    shoulder = c7 - _SHOULDER_BELOW_C7_FRACTION * h
    z = shoulder
    for name in ("upper_arm", "forearm", "hand"):
        p = seg[name]
        parts.append((2 * p.mass_kg, z - p.com_from_proximal_m, 2 * p.inertia_kg_m2))
        z -= p.length_m
    m_hat = sum(m for m, _, _ in parts)
    z_hat = sum(m * zc for m, zc, _ in parts) / m_hat
    i_hat = sum(i + m * (zc - z_hat) ** 2 for m, zc, i in parts)
    hat = Segment("hat", m_hat, c7 + head.length_m, z_hat, i_hat)

    thigh, shank = seg["thigh"], seg["shank"]
    ankle_height = _ANKLE_HEIGHT_FRACTION * h
    heel_to_ankle = _HEEL_TO_ANKLE_FRACTION * h
    # de Leva's shank runs knee → lateral malleolus (≈ ankle axis), so hip height is
    # ankle height + shank + thigh ≈ 0.531 H, Winter's 0.530 H.
    foot = seg["foot"]
    if heel_to_ankle >= foot.length_m:
        raise ParameterError(f"heel_to_ankle_m = {heel_to_ankle} exceeds the foot length "
                             f"{foot.length_m}; allowed: shorter than the foot")
    result = BodySegments(mass, h, hat, thigh, shank, foot, ankle_height, heel_to_ankle)
    if not math.isclose(result.total_mass_kg, mass, rel_tol=1e-3):
        raise AssertionError("segment mass fractions do not sum to one")
    return result
