"""Minimum-weight hydraulic ankle actuation designed from requirements (the seed's ch. 3 tool).

:func:`compute_design` searches a grid of designs for the lightest one that meets the
requirements (:mod:`afo_mj.design.design_requirements`, :func:`read_requirements`), explains
which constraint binds when none does, derives the best design as scenarios that ``afo-mj run``
accepts (:mod:`afo_mj.design.design_scenarios`) and runs the design-guideline studies; it
writes nothing. ``afo-mj design REQUIREMENTS.toml --out DIR`` is :func:`afo_mj.app.design.design`,
which writes the results (:mod:`afo_mj.outputs.design_report`).

The modules, in order of the computation: :mod:`~afo_mj.design.design_requirements` (the
requirements file, the duty cycle), :mod:`~afo_mj.design.design_models` (the steady-state
chain and the sizing laws), :mod:`~afo_mj.design.design_evaluation` (a design evaluated
exactly), :mod:`~afo_mj.design.design_screening` and :mod:`~afo_mj.design.design_search` (the
search, infeasibility), :mod:`~afo_mj.design.design_device` (the written device, bench
prediction, walk check), :mod:`~afo_mj.design.design_studies` (design guidelines) and this
module (reading the requirements, the whole computation). Every public name of those modules
that this module has always offered is importable from here.
"""

from __future__ import annotations

import time

from afo_mj.design.design_device import (WALK_CHECK_SAMPLES, design_overrides, design_params,
                                          mass_check, predict_bench,
                                          quasi_static_device_torque_nm, walk_work_check)
from afo_mj.design.design_evaluation import (CONSTRAINTS, RE_LAMINAR, actuator_geometry,
                                              evaluate_designs)
from afo_mj.design.design_requirements import (DesignError, Requirements, load_requirements,
                                                 parse_requirements)
from afo_mj.design.design_search import BORE_WINDOW, DesignResult, explain, size_system
from afo_mj.design.design_studies import guideline_studies, hose_bore_study


__all__ = ["DesignError", "DesignResult", "load_requirements", "parse_requirements",
           "size_system", "evaluate_designs", "design_overrides", "design_params",
           "predict_bench", "mass_check", "guideline_studies", "hose_bore_study",
           "read_requirements", "compute_design", "CONSTRAINTS", "BORE_WINDOW",
           "quasi_static_device_torque_nm", "walk_work_check", "WALK_CHECK_SAMPLES",
           "actuator_geometry", "explain", "RE_LAMINAR"]


def read_requirements(requirements_path, overrides=()) -> tuple[Requirements, str]:
    """Read and validate a requirements file; returns ``(requirements, text as read)``.

    ``overrides``: ``key=value`` strings as for ``afo-mj run --set`` (e.g.
    ``requirement.runtime_h=3``), applied before validation (``text`` then holds the document
    with them applied). Raises :class:`DesignError` for an unreadable file, a bad override or
    invalid requirements."""
    from pathlib import Path

    path = Path(requirements_path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DesignError(f"{path}: cannot read the requirements file "
                          f"({exc.strerror or exc})") from None
    if overrides:
        import tomllib

        from afo_mj.design.design_requirements import toml_dumps
        from afo_mj.scenarios.walk_scenario import ScenarioError, apply_overrides
        try:
            doc = apply_overrides(tomllib.loads(text), overrides, str(path))
        except (ScenarioError, tomllib.TOMLDecodeError) as exc:
            raise DesignError(str(exc)) from None
        text = toml_dumps(doc)
    req = parse_requirements(text, origin=str(path), default_name=path.stem, source_path=path)
    return req, text


def compute_design(req: Requirements, *, studies: bool = True, verify: bool = False) -> dict:
    """Everything ``afo-mj design`` computes, nothing written (the files are written by
    :func:`afo_mj.app.design.design` through :mod:`afo_mj.outputs.design_report`).

    Searches the designs (:func:`size_system`); when feasible, runs the design-guideline
    studies (``studies``, :func:`guideline_studies`) and the hose-bore trade-off
    (:func:`hose_bore_study`); for a pump-controlled design, derives the written device
    (:func:`design_params`, :func:`predict_bench`, :func:`mass_check`), parses the scenarios
    about to be written as ``afo-mj run`` will and checks the walk (:func:`walk_work_check`,
    quasi-static, no simulation: a device that does net negative work on the ankle brakes the
    walker, reported as ``written["walk_check"]["warning"]``). ``verify=True`` also runs the
    torque–velocity bench on the written parameters.

    Returns ``{"result": DesignResult, "written": dict | None (row, overrides, params,
    predicted_bench, mass_check, walk_check), "study": dict | None, "hose": dict | None,
    "bench": dict | None (simulated stall torque, no-load speed, energy error), "wall_s":
    float}``. An infeasible requirement is not an error (``result.feasible`` False, with its
    explanation)."""
    t0 = time.perf_counter()
    result = size_system(req)
    study = guideline_studies(req) if studies and result.feasible else None
    hose = hose_bore_study(result) if result.feasible else None
    bench = None
    written = None
    if result.feasible and req.architecture == "pump":
        row = result.row(0)
        ov, params = design_params(row, req, result.assumptions)
        written = {"row": row, "overrides": ov, "params": params,
                   "predicted_bench": predict_bench(params),
                   "mass_check": mass_check(row, params)}
        _validate_written(req, written)
        if verify:
            from afo_mj.experiments.hafo_bench import torque_velocity
            s, _ = torque_velocity(params, velocities_deg_s=(0.0,))
            bench = {"stall_torque_nm": s["stall_torque_nm"],
                     "no_load_speed_deg_s": s["no_load_speed_deg_s"],
                     "energy_error_max": s["energy_error_max"]}
    return {"result": result, "written": written, "study": study, "hose": hose,
            "bench": bench, "wall_s": time.perf_counter() - t0}


def _validate_written(req: Requirements, written: dict) -> None:
    """Parse the scenarios about to be written as ``afo-mj run`` will (a failure here is a bug
    of the tool, reported as such, not a bad requirement)."""
    from afo_mj.design.design_requirements import toml_dumps
    from afo_mj.design.design_scenarios import bench_scenario, walk_scenario
    from afo_mj.scenarios.bench_scenario import parse_bench_scenario
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, parse_scenario
    ov = written["overrides"]
    try:
        parse_bench_scenario(toml_dumps(bench_scenario(req, ov)), origin="design_bench.toml")
        sc = parse_scenario(toml_dumps(walk_scenario(
            req, ov, written["predicted_bench"]["stall_torque_nm"])), origin="design_walk.toml")
        cfg = device_config(sc)
    except ScenarioError as exc:
        raise RuntimeError(f"afo-mj design wrote a scenario afo-mj run rejects: {exc}") from exc
    written["walk_check"] = walk_work_check(sc, cfg, written["predicted_bench"])
