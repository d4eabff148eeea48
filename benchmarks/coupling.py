"""Cost of the HAFO coupling: µs per 1 ms step, bare walker vs the full coupled run.

All from ``scenarios/gait_assist_hafo.toml`` (healthy 75 kg walker, 10 strides), in the same
process, alternated so that all see the same machine load:

* bare: :func:`afo_mj.gait.walk.run_walk` with no device (the walker with its controllers and
  the recording of the GaitRecord; model build included);
* coupled: the scenario's ``assist`` condition as
  :func:`afo_mj.experiments.device_walk.run_device_scenario` runs it: the
  :class:`~afo_mj.devices.hafo.HafoDevice` built, the walker (with the device's worn masses)
  stepped with the HAFO hydraulics coupled implicitly each step (phase estimate, assistance
  profile, torque controller, pump/hose/cylinder model, device log), then the gait analysis
  and the condition's summary metrics;
* the coupled walk's step alone (model build excluded, as ``benchmarks/gait_step.py`` does),
  with the compiled loop (default) and with the Python loop (``loop="python"``), against the
  native bare ``mj_step`` of the same walker (with the HAFO's worn masses), replayed from a
  compiled loop (``benchmarks/gait_step.py``'s method): issue 21's target is the coupled
  step ≤ 1.5 × that.

numba is warmed up (compiled or loaded from its cache) by one untimed run of each before the
timed repeats; the figures are medians over the repeats (the minimum is printed beside).
Targets: coupled run ≤ 1.5 × bare walker run (issue 18); coupled walk step ≤ 1.5 × bare
``mj_step`` (issue 21). Prints the figures; the last line is a JSON object.
Run: ``.venv/bin/python benchmarks/coupling.py [repeats]``
"""

from __future__ import annotations

import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from afo_mj.metrics.gait_metrics import GaitAnalysisError, analyse_gait  # noqa: E402
from afo_mj.devices.hafo import HafoDevice  # noqa: E402
from afo_mj.gait.walk import run_walk  # noqa: E402
from afo_mj.experiments.device_walk import condition_summary  # noqa: E402
from afo_mj.scenarios.device_scenario import device_config  # noqa: E402
from afo_mj.scenarios.walk_scenario import load_scenario  # noqa: E402
from afo_mj.human.walker import WalkerPhysics, build_walker  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from afo_mj.gait.native_step import call_mj_step  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "gait_assist_hafo.toml"
TARGET_RATIO = 1.5


def _setup():
    sc = load_scenario(SCENARIO)
    cfg = device_config(sc)
    ref = sc.load_reference()
    return sc, cfg, ref, sc.cycle_time_s(ref), sc.walker.timestep_s


def bare_run(sc, ref, T) -> tuple[float, int]:
    """Wall seconds and steps of the walker alone."""
    t0 = time.perf_counter()
    rec = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params())
    return time.perf_counter() - t0, len(rec.time_s)


def coupled_run(sc, cfg, ref, T, dt) -> tuple[float, float, int]:
    """Wall seconds of the whole assist condition, of its walk alone, and its steps."""
    t0 = time.perf_counter()
    steps = int(((sc.strides + 1.5) * T + 1.0) / dt) + 4
    dev = HafoDevice(cfg.params, sides=cfg.sides, profile=cfg.profile, timestep_s=dt,
                     max_steps=steps)
    rec = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
                   worn_masses=dev.worn_masses(), device=dev)
    t_walk = time.perf_counter() - t0
    try:
        analysis = analyse_gait(rec, ref, sc.analyse_strides)
    except GaitAnalysisError:
        analysis = None
    condition_summary(rec, analysis, dev, cfg, sc.analyse_strides)
    return time.perf_counter() - t0, t_walk, len(rec.time_s)


def coupled_step(sc, cfg, ref, T, dt, loop: str) -> tuple[float, int]:
    """µs per step of the coupled walk alone (model build excluded) and its steps."""
    steps = int(((sc.strides + 1.5) * T + 1.0) / dt) + 4
    dev = HafoDevice(cfg.params, sides=cfg.sides, profile=cfg.profile, timestep_s=dt,
                     max_steps=steps)
    worn = dev.worn_masses()
    # the build run_walk also does, subtracted: its fastest of three, so that a pause of the
    # machine while it is timed cannot make the step look cheaper than it is
    t_build = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        WalkerPhysics(build_walker(sc.walker, worn))
        t_build = min(t_build, time.perf_counter() - t0)
    t0 = time.perf_counter()
    rec = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(), worn_masses=worn,
                   device=dev, loop=loop)
    wall = time.perf_counter() - t0 - t_build
    return wall / len(rec.time_s) * 1e6, len(rec.time_s)


@numba.njit
def _native_replay_all(ctrls, ranges, qfrcs, damps, ctrl, rng, qfrc, damp, fn, m_addr, d_addr):
    """``mj_step`` from compiled code with every input the coupled walk handed it per step:
    controls, ankle torque ranges, applied device torques and ankle damping."""
    for i in range(ctrls.shape[0]):
        ctrl[:] = ctrls[i]
        rng[:, :] = ranges[i]
        qfrc[:] = qfrcs[i]
        damp[:] = damps[i]
        call_mj_step(fn, m_addr, d_addr)


def bare_native_step(sc, cfg, ref, T, dt) -> tuple[float, float]:
    """µs per native ``mj_step`` of the walker wearing the HAFO's masses, replaying every
    per-step input of a coupled walk (captured from the Python loop): the controls, ankle
    torque ranges, applied device torques and ankle damping. MuJoCo is deterministic, so the
    replay walks the coupled walk's own states (returned second: the largest difference of
    the replay's final ``qpos`` from the walk's). (Replaying the controls alone, with the
    device's torque and damping held at their last values, the walker fell after ~3 s and the
    rest was timed on a body lying on the ground.)"""
    import mujoco
    from afo_mj.gait.native_step import native_step
    steps = int(((sc.strides + 1.5) * T + 1.0) / dt) + 4
    dev = HafoDevice(cfg.params, sides=cfg.sides, profile=cfg.profile, timestep_s=dt,
                     max_steps=steps)
    captured, start = [], {}
    original = mujoco.mj_step

    def capture(model, data):
        if not start:
            start.update(qpos=data.qpos.copy(), qvel=data.qvel.copy(), model=model,
                         act=data.act.copy(), warm=data.qacc_warmstart.copy(),
                         time=data.time)
        captured.append((data.ctrl.copy(), model.jnt_actfrcrange.copy(),
                         data.qfrc_applied.copy(), model.dof_damping.copy()))
        original(model, data)
        start["end"] = data.qpos.copy()

    mujoco.mj_step = capture
    try:
        run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
                 worn_masses=dev.worn_masses(), device=dev, loop="python")
    finally:
        mujoco.mj_step = original
    model = start["model"]
    arrays = [np.array([c[j] for c in captured]) for j in range(4)]
    fn = native_step().mj_step_address

    def fresh():
        d = mujoco.MjData(model)
        d.qpos[:] = start["qpos"]
        d.qvel[:] = start["qvel"]
        d.act[:] = start["act"]
        d.time = start["time"]
        d.qacc_warmstart[:] = start["warm"]
        return d

    warm = fresh()                               # held: the call reads it by address
    _native_replay_all(*(a[:2] for a in arrays), warm.ctrl, model.jnt_actfrcrange,
                       warm.qfrc_applied, model.dof_damping, fn, model._address, warm._address)
    data = fresh()
    t0 = time.perf_counter()
    _native_replay_all(*arrays, data.ctrl, model.jnt_actfrcrange, data.qfrc_applied,
                       model.dof_damping, fn, model._address, data._address)
    us = (time.perf_counter() - t0) / len(captured) * 1e6
    return us, float(np.max(np.abs(data.qpos - start["end"])))


def main(repeats: int = 7) -> dict:
    sc, cfg, ref, T, dt = _setup()
    bare_run(sc, ref, T)                      # warm-up: numba compile / cache load
    coupled_run(sc, cfg, ref, T, dt)
    bare, coupled, walk_only = [], [], []
    n_bare = n_coupled = 0
    for _ in range(repeats):
        w, n_bare = bare_run(sc, ref, T)
        bare.append(w / n_bare * 1e6)
        w, w_walk, n_coupled = coupled_run(sc, cfg, ref, T, dt)
        coupled.append(w / n_coupled * 1e6)
        walk_only.append(w_walk / n_coupled * 1e6)
    b, c, cw = (statistics.median(x) for x in (bare, coupled, walk_only))
    ratio = c / b
    coupled_step(sc, cfg, ref, T, dt, "compiled")          # warm-up: the device's C entries
    step_c = min(coupled_step(sc, cfg, ref, T, dt, "compiled")[0] for _ in range(3))
    step_py = min(coupled_step(sc, cfg, ref, T, dt, "python")[0] for _ in range(3))
    natives = [bare_native_step(sc, cfg, ref, T, dt) for _ in range(3)]
    native = min(n[0] for n in natives)
    replay_diff = max(n[1] for n in natives)
    result = {
        "bare_us_per_step": round(b, 2),
        "coupled_us_per_step": round(c, 2),
        "ratio": round(ratio, 3),
        "target_ratio": TARGET_RATIO,
        "meets_target": ratio <= TARGET_RATIO,
        "coupled_walk_us_per_step": round(cw, 2),
        "coupled_metrics_us_per_step": round(c - cw, 2),
        "bare_min_us_per_step": round(min(bare), 2),
        "coupled_min_us_per_step": round(min(coupled), 2),
        "ratio_of_minima": round(min(coupled) / min(bare), 3),
        "bare_steps": n_bare,
        "coupled_steps": n_coupled,
        "repeats": repeats,
        "scenario": SCENARIO.name,
        "condition": "assist",
        "device_preset": cfg.preset,
        "bare_native_mj_step_us": round(native, 2),
        "bare_replay_final_qpos_diff": replay_diff,
        "coupled_walk_step_compiled_us": round(step_c, 2),
        "coupled_walk_step_python_loop_us": round(step_py, 2),
        "coupled_step_over_bare_mj_step": round(step_c / native, 3),
        "target_coupled_step_over_bare_mj_step": 1.5,
    }
    print(f"{SCENARIO.name}: {sc.strides} strides, 1 ms step, median of {repeats} repeats "
          f"(minimum in brackets)")
    print(f"  bare walker (no device):      {b:6.1f} us/step ({min(bare):5.1f}), "
          f"{n_bare} steps")
    print(f"  coupled HAFO run (assist):    {c:6.1f} us/step ({min(coupled):5.1f}), "
          f"{n_coupled} steps")
    print(f"    of which walk + device:     {cw:6.1f} us/step, metrics {c - cw:4.1f} us/step")
    print(f"  ratio coupled / bare:         {ratio:6.2f} (target <= {TARGET_RATIO})")
    print(f"  coupled walk step, build excluded (best of 3): compiled loop {step_c:5.1f} "
          f"us/step, Python loop {step_py:5.1f} us/step")
    print(f"  bare native mj_step, HAFO's worn masses:        {native:5.1f} us/step; "
          f"coupled / bare mj_step {step_c / native:.2f} (issue 21 target <= 1.5)")
    print(f"    (the walk's own states: the replay ends {replay_diff:.1e} from the walk's qpos)")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7)
