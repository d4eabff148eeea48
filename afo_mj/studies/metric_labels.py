"""Units and labels of the metrics and parameters of a study, read from their dotted names.

:func:`unit_of` (``_nm`` → N·m, ``_j_per_stride`` → J/stride, ``_deg`` → deg, ...) and
:func:`label_of` (the name without ``param:`` and its unit in parentheses), used by the study
tables (:mod:`afo_mj.studies.study_analysis`) and figures (:mod:`afo_mj.outputs.study_figures`).
"""

from __future__ import annotations

__all__ = ["unit_of", "label_of"]

_STAT_SUFFIXES = ("mean", "sd", "over_analysed_span")

# name suffix → unit (checked longest first)
_SUFFIX_UNITS = {
    "_j_per_stride": "J/stride", "_j_per_kg": "J/kg", "_w_per_kg": "W/kg",
    "_nm_per_kg": "N·m/kg", "_n_per_kg": "N/kg", "_nm_per_rad": "N·m/rad",
    "_nm_per_deg": "N·m/deg", "_steps_per_min": "steps/min", "_cc_per_rev": "cc/rev",
    "_percent_body_weight": "% body weight", "_fraction": "1", "_rel": "1", "_pct": "%",
    "_mpa": "MPa", "_pa": "Pa", "_bar": "bar", "_nm": "N·m", "_deg": "deg", "_rad": "rad",
    "_rad_s": "rad/s", "_deg_s": "deg/s", "_m_s": "m/s", "_rpm": "rpm", "_kg": "kg",
    "_j": "J", "_wh": "Wh", "_w": "W", "_h": "h", "_s": "s", "_k": "K", "_m": "m",
    "_mm": "mm", "_n": "N", "_a": "A", "_v": "V", "_ohm": "Ω", "_m3": "m³", "_m2": "m²",
    "_l_min": "L/min", "_hz": "Hz",
}
_SUFFIXES_BY_LENGTH = sorted(_SUFFIX_UNITS, key=len, reverse=True)


def _strip_param(k: str) -> str:
    return k[len("param:"):] if str(k).startswith("param:") else str(k)


def unit_of(name: str) -> str:
    """The unit of a metric or parameter from its dotted name ('' when not known):
    statistics suffixes (``.mean``, ``.sd``) are looked through, ``.n`` is a count, anything
    under ``energy_per_stride`` is J/stride, otherwise the innermost name component with a
    known suffix decides (``energy.losses_j.line`` → J)."""
    parts = _strip_param(name).split(".")
    if parts and parts[-1] == "n" and len(parts) > 1:
        return "count"
    while len(parts) > 1 and parts[-1] in _STAT_SUFFIXES:
        parts = parts[:-1]
    if "energy_per_stride" in parts[:-1]:
        return "J/stride"
    for comp in reversed(parts):
        c = comp.lower()
        for suf in _SUFFIXES_BY_LENGTH:
            if c.endswith(suf) and len(c) > len(suf):
                return _SUFFIX_UNITS[suf]
    return ""


def label_of(name: str) -> str:
    """An axis label: the name (without ``param:``) and its unit in parentheses."""
    u = unit_of(name)
    n = _strip_param(name)
    return f"{n} ({u})" if u else n
