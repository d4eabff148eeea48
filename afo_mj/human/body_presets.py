"""Named body sizes (stature, mass) for the walker: children by age and two adult examples.

Source: the CDC 2000 growth charts for the United States (R. J. Kuczmarski et al., "2000 CDC
Growth Charts for the United States: Methods and Development", *Vital Health Stat.* 11(246),
National Center for Health Statistics, 2002), data files ``statage.csv`` (stature-for-age,
2–20 years) and ``wtage.csv`` (weight-for-age, 2–20 years), column ``P50`` (= the LMS ``M``,
the median), from https://www.cdc.gov/growthcharts/percentile_data_files.htm. These are works of
the US government and in the public domain. The files list each month of age at its half-month
point; the row ``Agemos = 12·N + 0.5`` (the month after the N-th birthday) is used for "N years"
and ``Agemos = 240`` for the adult examples. Values below are those medians rounded to 0.01 cm
and 0.01 kg (the files give 7–10 significant digits).

Presets (:data:`BODY_PRESETS`)
------------------------------
* ``child_4y`` … ``child_14y``: the mean of the boys' and girls' medians at that age (equal
  weight: a sex-neutral child); ``child_8y_boy``, ``child_8y_girl`` etc.: one sex's medians.
* ``adult_male`` / ``adult_female``: the CDC 2000 medians at 20 years (240 months), young
  adults: 176.85 cm / 70.60 kg and 163.34 cm / 58.22 kg. (These are medians of the growth
  reference, lighter than the means of today's US adults; the walker's own default is the
  75 kg, 1.75 m body of de Leva's reference male.)

The stature and the mass of a preset are two separate medians of the same age (the charts give
no joint distribution), the usual way of naming "a typical N-year-old" in gait studies.

Time step
---------
:func:`default_timestep_s`: walkers shorter than :data:`SMALL_BODY_HEIGHT_M` (1.3 m) need a
0.5 ms MuJoCo step (their dynamics are faster by √(1.75 m / stature), see
``afo_mj.human.walker.WalkerParams.timestep_s`` and ``scenarios/walk_child_healthy.toml``); the
scenario parser applies it when a scenario sets no ``timestep_s``.

>>> p = body_preset("child_8y")
>>> round(p.height_m, 3), round(p.body_mass_kg, 1)
(1.28, 25.8)
>>> default_timestep_s(p.height_m)
0.0005
"""

from __future__ import annotations

import dataclasses
from types import MappingProxyType
from typing import Mapping

from afo_mj.hydraulics.params import ParameterError

__all__ = ["BodyPreset", "BODY_PRESETS", "CDC2000_MEDIANS", "body_preset", "preset_names",
           "default_timestep_s", "SMALL_BODY_HEIGHT_M", "SMALL_BODY_TIMESTEP_S",
           "DEFAULT_TIMESTEP_S", "CHILD_AGES_YEARS"]

#: Below this stature [m] the walker needs :data:`SMALL_BODY_TIMESTEP_S`.
SMALL_BODY_HEIGHT_M = 1.3
#: MuJoCo time step [s] for walkers below :data:`SMALL_BODY_HEIGHT_M`.
SMALL_BODY_TIMESTEP_S = 5e-4
#: MuJoCo time step [s] otherwise (the WalkerParams default).
DEFAULT_TIMESTEP_S = 1e-3

#: Ages [years] with ``child_<N>y`` presets.
CHILD_AGES_YEARS = tuple(range(4, 15))

# CDC 2000 growth charts, P50 at Agemos = 12*N + 0.5 (N = age in years) and at 240 months:
# age_years: (boys stature cm, girls stature cm, boys weight kg, girls weight kg).
CDC2000_MEDIANS: Mapping[int, tuple[float, float, float, float]] = MappingProxyType({
    4: (102.51, 101.03, 16.32, 15.88),
    5: (109.18, 107.96, 18.49, 18.02),
    6: (115.66, 115.01, 20.78, 20.34),
    7: (122.03, 121.76, 23.17, 22.87),
    8: (128.12, 127.83, 25.75, 25.76),
    9: (133.73, 133.13, 28.68, 29.14),
    10: (138.82, 138.21, 32.09, 33.06),
    11: (143.73, 144.26, 36.07, 37.39),
    12: (149.31, 151.49, 40.67, 41.83),
    13: (156.41, 157.34, 45.81, 45.98),
    14: (164.14, 160.48, 51.23, 49.49),
    20: (176.85, 163.34, 70.60, 58.22),
})
"""Medians (P50) of the CDC 2000 growth charts by age [years]: (boys' stature [cm], girls'
stature [cm], boys' weight [kg], girls' weight [kg]); 20 years is the charts' last month
(240 months), used for the adult examples."""


@dataclasses.dataclass(frozen=True)
class BodyPreset:
    """One named body size: ``height_m`` stature [m], ``body_mass_kg`` [kg], the age [years]
    and sex ("male", "female" or "both" = mean of the two medians) it stands for, and its
    source."""

    name: str
    height_m: float
    body_mass_kg: float
    age_years: float
    sex: str
    source: str = "CDC 2000 growth charts, P50 (Kuczmarski et al. 2002)"


def _build() -> dict[str, BodyPreset]:
    out: dict[str, BodyPreset] = {}
    for age in CHILD_AGES_YEARS:
        h_boy, h_girl, m_boy, m_girl = CDC2000_MEDIANS[age]
        out[f"child_{age}y"] = BodyPreset(f"child_{age}y", 0.5 * (h_boy + h_girl) / 100.0,
                                          0.5 * (m_boy + m_girl), float(age), "both")
        out[f"child_{age}y_boy"] = BodyPreset(f"child_{age}y_boy", h_boy / 100.0, m_boy,
                                              float(age), "male")
        out[f"child_{age}y_girl"] = BodyPreset(f"child_{age}y_girl", h_girl / 100.0, m_girl,
                                               float(age), "female")
    h_m, h_f, m_m, m_f = CDC2000_MEDIANS[20]
    out["adult_male"] = BodyPreset("adult_male", h_m / 100.0, m_m, 20.0, "male")
    out["adult_female"] = BodyPreset("adult_female", h_f / 100.0, m_f, 20.0, "female")
    return out


BODY_PRESETS: Mapping[str, BodyPreset] = MappingProxyType(_build())
"""All presets by name (see the module docstring)."""


def preset_names() -> tuple[str, ...]:
    """The preset names, in table order."""
    return tuple(BODY_PRESETS)


def body_preset(name: str) -> BodyPreset:
    """The preset called ``name``; :class:`ParameterError` naming the value and the allowed
    names if there is none."""
    if not isinstance(name, str) or name not in BODY_PRESETS:
        raise ParameterError(f"body_preset = {name!r} is not a known body preset; allowed: "
                             f"{', '.join(BODY_PRESETS)}")
    return BODY_PRESETS[name]


def default_timestep_s(height_m: float) -> float:
    """The MuJoCo time step [s] a walker of stature ``height_m`` [m] needs: 0.5 ms below
    1.3 m, else 1 ms (the walker's dynamics are faster by √(1.75 m / stature); see
    ``WalkerParams.timestep_s``)."""
    return SMALL_BODY_TIMESTEP_S if height_m < SMALL_BODY_HEIGHT_M else DEFAULT_TIMESTEP_S
