"""``afo-mj export-osim``: the walker of a walking scenario as OpenSim models
(:mod:`afo_mj.outputs.opensim_model`), one per run the scenario walks, without walking.

The model of a run is the one its walk would step: the scenario's walker model
(``walker.model``: torque, muscle or a registered controller, :mod:`afo_mj.gait.walkers`) built
with the worn masses of the run's device, read from the compiled MuJoCo model. A scenario
without a ``[device]`` table has one run, ``walk``; a device scenario one per condition
(``no_device``, the device's, ``assist`` …), named as ``afo-mj run`` names them, so the files
are those its ``[output] opensim`` writes beside the storage files (``<run>.osim``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from afo_mj.app.errors import InvalidInput, RunFailed

__all__ = ["export_osim"]


def export_osim(scenario, out_dir, overrides: Sequence[str] = ()) -> list[dict]:
    """Write ``<run>.osim`` for every run of the walking scenario file ``scenario`` into
    ``out_dir``; returns per model ``{"run", "path", "mass_kg", "worn_mass_kg"}``.
    :class:`InvalidInput` for a scenario that is not a valid walking scenario (nothing
    written), :class:`RunFailed` when a file cannot be written."""
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.gait.muscle_scenario import MuscleScenarioError
    from afo_mj.gait.walkers import walk_duration_s, walker_model
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.outputs.opensim_model import OpenSimModelError, osim_model_xml
    from afo_mj.scenarios.bench_scenario import is_bench_document
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario
    p = Path(scenario)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        text = None                     # load_scenario reports it
    if text is not None and is_bench_document(text):
        raise InvalidInput(f"{p}: scenario = {p.name!r} is a bench scenario (a device on a test "
                           "stand, no walker); allowed: a walking scenario")
    try:
        s = load_scenario(p, overrides=tuple(overrides))
        cfg = device_config(s)
        model = walker_model(s, "export-osim")
        ref = s.load_reference()
        runs = []
        if cfg is None:
            runs.append(("walk", None))
        else:
            dt = s.walker.timestep_s
            n = int(walk_duration_s(s, ref) / dt) + 4
            for cond in cfg.conditions:
                runs.append((cond, None if cond == "no_device" else
                             make_device(cfg, cond, dt, n)))
        texts = []
        for name, dev in runs:
            worn = tuple(dev.worn_masses()) if dev is not None and hasattr(
                dev, "worn_masses") else ()
            phys = model.stepper(s, ref, dev, worn).phys
            texts.append((name, osim_model_xml(phys.model, name=f"{s.name}_{name}"),
                          float(phys.body_mass_kg), sum(w.mass_kg for w in worn)))
    except (ScenarioError, MuscleScenarioError, ParameterError, OpenSimModelError,
            ValueError) as exc:
        raise InvalidInput(f"invalid scenario: {exc}; nothing written") from None
    out = Path(out_dir)
    info = []
    try:
        out.mkdir(parents=True, exist_ok=True)
        for name, xml, mass, worn_kg in texts:
            path = out / f"{name}.osim"
            path.write_text(xml, encoding="utf-8")
            info.append({"run": name, "path": path, "mass_kg": mass, "worn_mass_kg": worn_kg})
    except OSError as exc:
        raise RunFailed(f"writing {out}: {exc}") from None
    return info
