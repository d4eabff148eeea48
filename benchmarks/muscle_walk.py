"""Speed of the muscle-driven walker (issues 22 and 39): its step against a bare native
``mj_step`` of the same model, the real-time factor of a walk and the cost of one optimiser
evaluation.

Run: ``.venv/bin/python benchmarks/muscle_walk.py [reflex_params.json]`` (default: the
shipped 1.25 m/s set, ``afo_mj/data/reflex_params_1.25.json``, or Geyer & Herr's gains when
it is missing). In one process, after a warm-up, the best of :data:`REPEATS` runs of the
compiled walk and of the bare steps (of 3 for the Python loop), since the minimum is the
figure least moved by the machine's other work (2026-11-28: best of 3 read 1.32 … 1.42 over
five runs of this script):

* the compiled walk (:mod:`afo_mj.gait.controller_loop`, the reflex controller's compiled
  step): µs per 1 ms step of a 10 s walk (fewer seconds if it falls), the walk's stepping
  only (:meth:`MuscleWalkStepper.run` on a built stepper, its record's assembly included),
  and the real-time factor of the whole ``run_muscle_walk`` call (model build included;
  target ≥ 20 on one core);
* the Python loop (``loop="python"``, the reference step) over the same walk;
* a bare ``mj_step`` of the same walk: the walk's own steps replayed from its start with the
  controls and joint damping it wrote (checked to end where the walk ended, bit for bit),
  through the same native call the loop uses in a small compiled loop (no Python per step),
  and through the bindings' ``mujoco.mj_step`` from a Python loop for reference;
* the reflex law alone (:func:`afo_mj.gait.reflex_law.reflex_step` on the states the walk
  met, in a compiled loop), so that the compiled step splits into ``mj_step``, the law and
  the loop's own work;
* ``muscle_over_bare``: the compiled walk's step over the bare native step (issue 39 target:
  at most 1.3);
* one evaluation of :func:`afo_mj.studies.gait_optimization.gait_cost` (a 12 s walk and its
  gait quality).

The last line is a JSON object.
"""

from __future__ import annotations

import copy
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

for _v in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_v] = "1"
os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]
#: runs of the compiled walk and of the bare steps; the best is reported
REPEATS = 7


def _replay_loops():
    import numba

    from afo_mj.gait import reflex_law as rl
    from afo_mj.gait.native_step import call_mj_step

    @numba.njit(cache=False)
    def replay_steps(fn, m_addr, d_addr, ctrl, damping, ctrl_rows, damping_rows):
        # the walk's own mj_steps: its controls and joint damping written, then the step
        for i in range(ctrl_rows.shape[0]):
            for j in range(ctrl.shape[0]):
                ctrl[j] = ctrl_rows[i, j]
            for j in range(damping.shape[0]):
                damping[j] = damping_rows[i, j]
            call_mj_step(fn, m_addr, d_addr)

    @numba.njit(cache=False)
    def replay_law(h, times, qpos_rows, qvel_rows, sens_rows, lq, lv, touch, pt_q, pt_v, P, T,
                   X, ring, mg):
        # the walk's own reflex-law calls, on the states it met
        for i in range(times.shape[0]):
            rl.reflex_step(times[i], h, qpos_rows[i], qvel_rows[i], sens_rows[i], lq, lv,
                           touch, pt_q, pt_v, P, T, X, ring, mg)
    return replay_steps, replay_law


def bare_step_us(params, duration_s: float) -> dict:
    """What one step of the compiled walk is made of, on the walk's own trajectory, best of
    3 each: ``mj_step`` alone (the walk's steps replayed from its start with the controls and
    joint damping it wrote, through the native call the loop uses in a compiled loop, and
    through the bindings' ``mujoco.mj_step`` from Python) and the reflex law alone
    (:func:`afo_mj.gait.reflex_law.reflex_step` on the states the walk met). Each replay is
    checked to end where the walk ended, bit for bit. µs per step."""
    import mujoco

    from afo_mj.gait import reflex_law as rl
    from afo_mj.gait.muscle_walk import GRAVITY_M_S2, MuscleWalkStepper, muscle_table_scaled
    from afo_mj.gait.native_step import native_step
    fn = native_step().mj_step_address
    replay_steps, replay_law = _replay_loops()
    w = MuscleWalkStepper(params=params, duration_s=duration_s)
    m, phys = w.model, w.phys
    d0 = copy.copy(w.data)
    X0 = w._X.copy()
    ctrl_rows = np.zeros((w.n_max, m.nu))
    damping_rows = np.zeros((w.n_max, m.nv))
    while not w.done:
        k = w.steps
        w.step()
        ctrl_rows[k], damping_rows[k] = w.data.ctrl, m.dof_damping
    n = w.steps
    ctrl_rows, damping_rows = ctrl_rows[:n], damping_rows[:n]
    walk = w.record()
    damping0 = m.dof_damping.copy()
    out = {"native": float("inf"), "bindings": float("inf"), "law": float("inf")}
    try:
        for _ in range(REPEATS):
            d = copy.copy(d0)               # held: the compiled loop gets only its address
            t0 = time.perf_counter()
            replay_steps(fn, m._address, d._address, d.ctrl, m.dof_damping, ctrl_rows,
                         damping_rows)
            out["native"] = min(out["native"], time.perf_counter() - t0)
            if not np.array_equal(d.qpos, walk.record.qpos[-1]):
                raise AssertionError("the native replay left the walk's trajectory")
            d = copy.copy(d0)
            ctrl, damping = d.ctrl, m.dof_damping
            t0 = time.perf_counter()
            for i in range(n):
                ctrl[:] = ctrl_rows[i]
                damping[:] = damping_rows[i]
                mujoco.mj_step(m, d)
            out["bindings"] = min(out["bindings"], time.perf_counter() - t0)
            if not np.array_equal(d.qpos, walk.record.qpos[-1]):
                raise AssertionError("the bindings' replay left the walk's trajectory")
    finally:
        m.dof_damping[:] = damping0
    # the law's inputs at step i: the state after step i − 1 (the start for step 0)
    rows = {key: np.vstack([start[None], walk_rows[:n - 1]]) for key, start, walk_rows in (
        ("qpos", d0.qpos, walk.record.qpos),
        ("qvel", d0.qvel, w._buf["qvel"][:n]), ("sens", d0.sensordata, w._buf["sens"][:n]))}
    times = np.concatenate([[d0.time], walk.record.time_s[:n - 1]])
    T = muscle_table_scaled(float(m.opt.timestep), None, w.walker.height_m)
    for _ in range(REPEATS):
        X = X0.copy()
        ring = np.zeros((rl.RING_LEN, rl.RING_COLS))
        t0 = time.perf_counter()
        replay_law(float(m.opt.timestep), times, rows["qpos"], rows["qvel"], rows["sens"],
                   phys.leg_qpos, phys.leg_dof, phys.touch_adr, int(phys.pelvis_qpos[2]),
                   int(phys.pelvis_dof[2]), w.params, T, X, ring,
                   phys.body_mass_kg * GRAVITY_M_S2)
        out["law"] = min(out["law"], time.perf_counter() - t0)
        if not np.array_equal(X[rl.X_ACT:rl.X_ACT + 14].reshape(2, 7), walk.activation[-1]):
            raise AssertionError("the reflex-law replay left the walk's states")
    return {key: v / n * 1e6 for key, v in out.items()}


def main() -> None:
    from afo_mj.gait.muscle_walk import MuscleWalkStepper, reflex_params, run_muscle_walk
    from afo_mj.studies.gait_optimization import GaitObjective, gait_cost, load_reflex_set
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "afo_mj/data/reflex_params_1.25.json"
    params = load_reflex_set(path) if path.exists() else reflex_params()
    run_muscle_walk(params=params, duration_s=0.5)              # compile / load
    run_muscle_walk(params=params, duration_s=0.5, loop="python")
    per_step = {}
    for loop in ("compiled", "python"):
        best = None
        for _ in range(REPEATS if loop == "compiled" else 3):
            w = MuscleWalkStepper(params=params, duration_s=10.0, loop=loop)
            t0 = time.perf_counter()
            walk = w.run()
            wall = time.perf_counter() - t0
            n = len(walk.record.time_s)
            if best is None or wall / n < best[0] / best[1]:
                best = (wall, n)
        per_step[loop] = best[0] / best[1] * 1e6
    n = best[1]
    best_call = None
    for _ in range(3):
        t0 = time.perf_counter()
        walk = run_muscle_walk(params=params, duration_s=10.0)
        wall = time.perf_counter() - t0
        best_call = wall if best_call is None else min(best_call, wall)
    rtf = len(walk.record.time_s) * 1e-3 / best_call
    parts = bare_step_us(params, 10.0)
    bare_native, bare_binding, law = parts["native"], parts["bindings"], parts["law"]
    us = per_step["compiled"]
    ratio = us / bare_native
    t0 = time.perf_counter()
    cost, _ = gait_cost(params, GaitObjective())
    t_eval = time.perf_counter() - t0
    name = path.name if path.exists() else "Geyer & Herr gains"
    print(f"muscle walker ({name}), {n} steps: compiled loop {us:.1f} us/step, Python loop "
          f"{per_step['python']:.1f} us/step; run_muscle_walk {rtf:.0f}x real time "
          f"(model build included; target >= 20)")
    print(f"bare mj_step of the same walk: native {bare_native:.1f} us, bindings "
          f"{bare_binding:.1f} us; compiled muscle step / bare native step = {ratio:.2f} "
          f"(target <= 1.3)")
    print(f"of the compiled step: mj_step {bare_native:.1f} us, reflex law {law:.1f} us, "
          f"the loop's own work (events, writes, device, recording, checks) "
          f"{us - bare_native - law:.1f} us")
    print(f"one optimiser evaluation (12 s walk + gait quality): {t_eval:.2f} s, cost {cost:.2f}")
    print(json.dumps({"benchmark": "muscle_walk", "steps": n, "us_per_step": round(us, 2),
                      "python_loop_us_per_step": round(per_step["python"], 2),
                      "bare_mj_step_native_us": round(bare_native, 2),
                      "bare_mj_step_bindings_us": round(bare_binding, 2),
                      "reflex_law_us": round(law, 2),
                      "muscle_over_bare": round(ratio, 3), "target_muscle_over_bare": 1.3,
                      "real_time_factor": round(rtf, 1), "target_real_time_factor": 20,
                      "evaluation_s": round(t_eval, 3), "cost": cost}))


if __name__ == "__main__":
    main()
