"""Every entry point that takes a walking scenario either walks the walker model the scenario
names or refuses it (issue 38 item 1, issue 39 item 2). ``afo-mj run``, device walks,
``compare``, ``walk_batch`` and ``render`` walk the scenario's own walker (through
:data:`afo_mj.gait.walkers.WALKER_MODELS`): on ``walk_muscle_healthy.toml`` their cadence
and speed are ``afo-mj run``'s (125/min), not the torque walker's (104/min), which
``walk_batch`` and ``render`` used to walk in its place. The gymnasium environment and
``simulate_walk`` walk the scenario's walker too (the same registry); ``Walk.from_scenario``
builds the torque walker's own steppable class and refuses a muscle scenario (one error naming
the model and ``afo-mj run``).

A census of the package's calls keeps the list honest: a new caller of the torque walk (or of
a scenario loader outside the listed modules) fails here until it is added to the matrix."""

from __future__ import annotations

import ast
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = {"torque": ROOT / "scenarios" / "walk_healthy.toml",
             "muscle": ROOT / "scenarios" / "walk_muscle_healthy.toml"}
SHORT = ["gait.strides=1", "gait.analyse_strides=[1, 1]"]
#: what every refusal says: the key and value, and the command that runs it
REFUSAL = r"walker\.model = 'muscle'(.|\n)*afo-mj run"


def _load(model: str):
    from afo_mj.scenarios.walk_scenario import load_scenario
    return load_scenario(SCENARIOS[model], overrides=SHORT)


def _assert_refused(excinfo) -> None:
    from afo_mj.gait.walk import WalkerModelError
    assert isinstance(excinfo.value, ValueError)
    msg = str(excinfo.value)
    assert "muscle" in msg and "afo-mj run" in msg and "torque" in msg, msg
    # the scenario file is named
    assert "walk_muscle_healthy" in msg, msg
    # the refusal comes from the one check, whatever wraps it
    chain = [excinfo.value, excinfo.value.__cause__, excinfo.value.__context__]
    assert isinstance(excinfo.value, WalkerModelError) or "walker.model" in msg, chain


# --- simulate_walk ------------------------------------------------------------------------------

def test_simulate_walk_torque_runs():
    from afo_mj.gait.walk import simulate_walk
    rec = simulate_walk(_load("torque"))
    # one right stride plus the start: at least two right heel strikes and no fall
    assert len(rec.events.heel_strikes_s[0]) >= 2 and rec.events.fall_time_s is None
    assert np.all(np.isfinite(rec.qpos))


def test_simulate_walk_walks_the_muscle_walker(muscle_run):
    """simulate_walk on a muscle scenario walks the muscle walker (afo-mj run's cadence and
    speed), and its record carries the muscles' signals beside the joints'."""
    from afo_mj.gait.walk import simulate_walk
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(SCENARIOS["muscle"], overrides=SHORT2)
    rec = simulate_walk(sc)
    g = _gait(rec, sc)
    for key in ("cadence_steps_per_min", "speed_m_s"):
        assert g[key]["mean"] == muscle_run[key]["mean"], key
    n = len(rec.time_s)
    assert set(rec.signals) == {"excitation", "activation", "force_n", "ce_velocity_m_s",
                                "metabolic_umberger_w", "metabolic_bhargava_w"}
    assert all(v.shape == (n, 2, 7) for v in rec.signals.values())
    # an independent check of the activations: bounded by Geyer & Herr's [0.01, 1]
    assert rec.signals["activation"].min() >= 0.0 and rec.signals["activation"].max() <= 1.0


# --- walk_batch ---------------------------------------------------------------------------------

def test_walk_batch_torque_runs():
    from afo_mj.experiments.batch import walk_batch
    (rec,) = walk_batch([_load("torque")], workers=1)
    assert len(rec.events.heel_strikes_s[0]) >= 2


@pytest.fixture(scope="module")
def muscle_run():
    """``afo-mj run``'s walk of the muscle scenario (the reference the other entry points
    must reproduce): its summary."""
    from afo_mj.app.run import run_scenario
    return run_scenario(SCENARIOS["muscle"], overrides=SHORT2).summary.to_json()


#: two analysed strides, so that cadence and speed are measured
SHORT2 = ["gait.strides=3", "gait.analyse_strides=[2, 3]"]


def _gait(record, scenario) -> dict:
    from afo_mj.metrics.gait_metrics import analyse_gait
    return analyse_gait(record, scenario.load_reference(), scenario.analyse_strides).summary


def test_walk_batch_walks_the_muscle_walker(muscle_run):
    """walk_batch on a muscle scenario walks the muscle walker: its cadence and speed are
    afo-mj run's (125/min), not the torque walker's (104/min)."""
    from afo_mj.experiments.batch import walk_batch
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(SCENARIOS["muscle"], overrides=SHORT2)
    (rec,) = walk_batch([sc], workers=1)
    g = _gait(rec, sc)
    for key in ("cadence_steps_per_min", "speed_m_s"):
        assert g[key]["mean"] == muscle_run[key]["mean"], key
    torque = load_scenario(SCENARIOS["torque"], overrides=SHORT2)
    (trec,) = walk_batch([torque], workers=1)
    assert abs(_gait(trec, torque)["cadence_steps_per_min"]["mean"]
               - g["cadence_steps_per_min"]["mean"]) > 10.0


def test_walk_batch_refuses_an_unknown_walker_model_before_any_worker(monkeypatch):
    import dataclasses

    from afo_mj.experiments import batch

    def no_run(*a, **k):
        raise AssertionError("a walk was started for a batch with an unknown walker model")
    monkeypatch.setattr(batch, "run_batch", no_run)
    bad = dataclasses.replace(_load("torque"), walker_model="hill")
    with pytest.raises(ValueError, match=r"scenarios\[1\]: walker.model = 'hill'; allowed: "
                                         r"'torque', 'muscle'"):
        batch.walk_batch([_load("torque"), bad], workers=1)


# --- Walk ---------------------------------------------------------------------------------------

def test_walk_from_scenario_torque_steps_as_walk():
    from afo_mj.gait.walk import Walk
    sc = _load("torque")
    ref = sc.load_reference()
    w = Walk.from_scenario(sc)
    # the same walk built by hand from the scenario's parts
    hand = Walk(sc.walker, ref, sc.cycle_time_s(ref), sc.strides, sc.controller_params())
    for _ in range(20):
        w.step()
        hand.step()
    assert np.array_equal(w.record().qpos, hand.record().qpos)
    assert not w.done


def test_walk_from_scenario_muscle_refused():
    from afo_mj.gait.walk import Walk, WalkerModelError
    with pytest.raises(WalkerModelError, match=REFUSAL) as ei:
        Walk.from_scenario(_load("muscle"))
    _assert_refused(ei)


# --- gymnasium environment ----------------------------------------------------------------------

def test_gym_env_torque_steps():
    from afo_mj.experiments import walk_env as we
    env = we.AnkleAssistEnv(str(SCENARIOS["torque"]), overrides=SHORT)
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        obs, reward, terminated, truncated, _ = env.step(np.zeros(2))
    assert np.all(np.isfinite(obs)) and np.isfinite(reward) and not terminated


def test_gym_env_walks_the_muscle_walker(muscle_run):
    """gym.make of the environment on a muscle scenario steps the muscle walker: a zero-action
    episode has afo-mj run's cadence and speed (125/min, not the torque walker's 104/min)."""
    import gymnasium as gym

    from afo_mj.experiments import walk_env as we
    from afo_mj.scenarios.walk_scenario import load_scenario
    env = gym.make(we.ENV_ID, scenario=str(SCENARIOS["muscle"]), overrides=SHORT2)
    env.reset(seed=0)
    while True:
        *_, term, trunc, _info = env.step(np.zeros(2))
        if term or trunc:
            break
    assert trunc and not term
    rec = env.unwrapped.walk.record().record
    g = _gait(rec, load_scenario(SCENARIOS["muscle"], overrides=SHORT2))
    for key in ("cadence_steps_per_min", "speed_m_s"):
        assert g[key]["mean"] == muscle_run[key]["mean"], key


# --- render (Python and afo-mj render) ----------------------------------------------------------

@pytest.fixture(scope="module")
def gl():
    """Skip when no offscreen OpenGL context can be created here."""
    import mujoco
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='sphere' size='0.1'/></worldbody></mujoco>")
    try:
        r = mujoco.Renderer(model, 16, 16)
    except Exception as exc:  # noqa: BLE001
        pytest.skip(f"no offscreen OpenGL context (MUJOCO_GL="
                    f"{os.environ.get('MUJOCO_GL')}): {exc}")
    r.close()


def _render_argv(model: str, out: Path) -> list[str]:
    argv = ["render", str(SCENARIOS[model]), "--mp4", str(out), "--fps", "10", "--width", "64",
            "--height", "48", "--max-seconds", "0.3"]
    for s in SHORT:
        argv += ["--set", s]
    return argv


def test_render_cli_torque_writes_the_video(gl, tmp_path):
    from afo_mj import cli
    out = tmp_path / "walk.mp4"
    assert cli.main(_render_argv("torque", out)) == 0
    assert out.is_file() and out.stat().st_size > 0


def test_render_walks_the_muscle_walker(tmp_path, monkeypatch, muscle_run):
    """afo-mj render of a muscle scenario renders the muscle walker's walk: the record it
    draws has afo-mj run's cadence and speed."""
    from afo_mj import cli
    from afo_mj.outputs import video
    from afo_mj.scenarios.walk_scenario import load_scenario
    drawn = []

    def fake_render(rec, path, **kw):
        drawn.append(rec)
        return {"frames": 1, "fps": kw.get("fps"), "width": kw.get("width"),
                "height": kw.get("height"), "duration_s": 0.1, "codec": "h264",
                "path": str(path)}
    monkeypatch.setattr(video, "render_record", fake_render)
    argv = ["render", str(SCENARIOS["muscle"]), "--mp4", str(tmp_path / "m.mp4")]
    for s_ in SHORT2:
        argv += ["--set", s_]
    assert cli.main(argv) == 0
    (rec,) = drawn
    g = _gait(rec, load_scenario(SCENARIOS["muscle"], overrides=SHORT2))
    for key in ("cadence_steps_per_min", "speed_m_s"):
        assert g[key]["mean"] == muscle_run[key]["mean"], key


# --- compare: a device on the muscle walker is refused by the scenario parser -------------------

def test_compare_loads_device_scenarios_on_either_walker(tmp_path):
    """A device scenario on the muscle walker is compared on the muscle walker (the device
    walk steps the scenario's walker, afo_mj.gait.walkers.WALKER_MODELS), not refused
    and not swapped."""
    from afo_mj.experiments.device_comparison import load_compare_items
    items = load_compare_items([str(ROOT / "scenarios" / "gait_assist_hafo.toml")], strides=1)
    assert items and all(it.scenario.walker_model == "torque" for it in items)
    p = tmp_path / "walk_muscle_healthy_hafo.toml"
    shutil.copy(SCENARIOS["muscle"], p)
    p.write_text(p.read_text() + '\n[device]\npreset = "hafo"\n')
    items = load_compare_items([str(p)], strides=1)
    assert items and all(it.scenario.walker_model == "muscle" for it in items)


# --- census: every caller of the torque walk is in the matrix above -----------------------------

#: module -> what it does with a muscle scenario
TORQUE_WALK_CALLERS = {
    "afo_mj/gait/walk.py": "Walk.from_scenario refuses it; simulate_walk goes through "
                           "walkers.walk_scenario",
    "afo_mj/gait/walkers.py": "WALKER_MODELS: run_walk and Walk for torque only; every "
                              "walk of a scenario (run, device walks, compare, simulate_walk, "
                              "walk_batch, render, the environment) goes through it",
}
SCENARIO_LOADERS = {
    "afo_mj/app/render.py", "afo_mj/app/run.py", "afo_mj/experiments/walk_env.py",
    "afo_mj/experiments/device_comparison.py",       # compare: [device] only
    "afo_mj/studies/sweep.py",                       # key check only; points are afo-mj run
    "afo_mj/design/system_design.py",                # its own device scenario, no walk run
    "afo_mj/studies/gait_optimization.py",           # optimize-gait --scenario: muscle only
    "afo_mj/scenarios/walk_scenario.py",
    "afo_mj/app/osim.py",                            # export-osim: the walker model, no walk
    "afo_mj/scenarios/device_source.py",             # schematic / export-fmu: the device only
}


def _calls(names) -> set[str]:
    found = set()
    for p in sorted((ROOT / "afo_mj").rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.id if isinstance(f, ast.Name) else getattr(f, "attr", None)
                if name in names:
                    found.add(p.relative_to(ROOT).as_posix())
    return found


def test_every_torque_walk_caller_is_listed():
    assert _calls({"Walk", "run_walk", "simulate_walk", "from_scenario"}) \
        == set(TORQUE_WALK_CALLERS)
    assert _calls({"load_scenario", "parse_scenario"}) == SCENARIO_LOADERS
