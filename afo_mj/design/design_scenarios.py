"""The best design as scenario documents that ``afo-mj run`` accepts (dicts; no file written).

:func:`bench_scenario` (the torque–velocity bench, ``afo_mj.scenarios.bench_scenario``) and
:func:`walk_scenario` (walking with the design, based on ``scenarios/gait_assist_hafo.toml``).
:func:`afo_mj.design.system_design.compute_design` parses both as ``afo-mj run`` will before
anything is written; :func:`afo_mj.outputs.design_report.write_design_report` writes them as
``design_bench.toml`` and ``design_walk.toml``.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

__all__ = ["bench_scenario", "walk_scenario"]

_WALK_TEMPLATE = Path(__file__).resolve().parents[2] / "scenarios" / "gait_assist_hafo.toml"
#: used when the repository's walking scenario is not at hand (an installed package)
_WALK_FALLBACK = {
    "walker": {"body_mass_kg": 75.0, "height_m": 1.75},
    "gait": {"reference": "winter", "condition": "normal", "strides": 10,
             "analyse_strides": [4, 10]},
    "device": {"preset": "hafo", "sides": ["right"],
               "conditions": ["no_device", "transparent", "assist"]},
    "assistance": {"profile": "zhang", "peak_torque_nm": 40.0, "peak_time_pct": 52.9,
                   "rise_time_pct": 26.2, "fall_time_pct": 9.8},
}


def bench_scenario(req, overrides: dict) -> dict:
    """The torque–velocity bench scenario of the design (``afo_mj.scenarios.bench_scenario``)."""
    mass = req.body_mass_kg if 20.0 <= req.body_mass_kg <= 200.0 else 75.0
    return {"name": f"{req.name}_bench",
            "description": f"Designed by afo-mj design from {req.name}: the lightest "
                           f"pump-controlled design on the ankle test stand, torque-velocity "
                           f"test (stall torque, no-load speed).",
            "device": {"preset": "hafo", "params": dict(overrides)},
            "bench": {"protocols": ["torque_velocity"], "body_mass_kg": mass,
                      "height_m": 1.75}}


def walk_scenario(req, overrides: dict, stall_torque_nm: float,
                  warning: str | None = None) -> dict:
    """Walking with the design: ``scenarios/gait_assist_hafo.toml`` with the design's device
    parameters, the wearer's mass, and the Zhang assistance capped at 80 % of the design's
    stall torque (the torque loop needs headroom above its command). ``warning`` (the
    :func:`~afo_mj.design.system_design.walk_work_check` warning) is appended to the
    description, so whoever runs the file reads it."""
    try:
        doc = tomllib.loads(_WALK_TEMPLATE.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        doc = json.loads(json.dumps(_WALK_FALLBACK))
    doc["name"] = f"{req.name}_walk"
    doc["description"] = (f"Designed by afo-mj design from {req.name}: a "
                          f"{req.body_mass_kg:g} kg walker wearing the lightest "
                          f"pump-controlled design on the right ankle (no device, "
                          f"transparent, Zhang assistance)."
                          + (f" WARNING: {warning}" if warning else ""))
    doc.setdefault("walker", {})["body_mass_kg"] = req.body_mass_kg
    dev = doc.setdefault("device", {})
    dev["preset"] = "hafo"
    dev["params"] = dict(overrides)
    dev.pop("variants", None)
    ass = doc.setdefault("assistance", dict(_WALK_FALLBACK["assistance"]))
    if "peak_torque_nm" in ass:
        ass["peak_torque_nm"] = round(min(float(ass["peak_torque_nm"]),
                                          0.8 * stall_torque_nm), 3)
    return doc
