"""Tune an ankle assistance controller through the gymnasium environment (issue 23).

The controller is a small policy: a Zhang et al. (2017) torque-vs-phase profile on both ankles
(peak torque, peak time, rise and fall, as fractions of the stride), read at each leg's phase
estimate from the environment's observation. CMA-ES (the ``cma`` package, seeded) searches
those four numbers to maximise the environment's return, i.e. to minimise the stated objective
``Σ over 100 Hz control steps of [Σ (human ankle moment / (m g L))² + 0.02 × positive
assistance power / (m g v)]`` (the terms of :func:`afo_mj.experiments.walk_env.default_reward`
with no tracking term and device energy weighted as cheaper than the wearer's effort), on
``scenarios/walk_healthy.toml`` (4 strides; a fall scores 1e3). The start and the baseline is
the generic profile at the published timing (peak 52.9 %, rise 26.2 %, fall 9.8 % of the
stride) with a 0.2 N·m/kg peak (this tracking walker, which does not anticipate an external
torque, falls with 0.4 N·m/kg on both ankles).

Run: ``.venv/bin/python examples/tune_assistance_env.py [generations]`` (default 8, popsize 8:
~1 min on 2 cores). Prints the generic and the tuned profile with their objective; the last
line is a JSON object.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cma
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.control.assistance import table_lookup, zhang_profile  # noqa: E402
from afo_mj.experiments.walk_env import OBSERVATION_NAMES, AnkleAssistEnv  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "walk_healthy.toml"
OVERRIDES = ["gait.strides=4", "gait.analyse_strides=[2, 4]"]
BODY_MASS_KG = 75.0
GENERIC = np.array([0.2, 52.9, 26.2, 9.8])         # N·m/kg, % stride
W_EFFORT, W_ENERGY = 1.0, 0.02


def reward(env) -> float:
    """The example's stated objective per control step (module docstring), negated."""
    return -(W_EFFORT * env.last["effort"] + W_ENERGY * env.last["energy"])
PH = [OBSERVATION_NAMES.index("right_phase"), OBSERVATION_NAMES.index("left_phase")]


def profile(x) -> np.ndarray | None:
    """The torque table of parameters ``x`` (None when outside the profile's validity)."""
    peak, t_pk, rise, fall = (float(v) for v in x)
    if not (0.0 <= peak <= 1.2 and 0.1 <= rise and 0.1 <= fall and t_pk - rise >= 0.0
            and t_pk + fall <= 100.0):
        return None
    return zhang_profile(peak * BODY_MASS_KG, t_pk, rise, fall)


def objective(x) -> float:
    """Minus the environment's return of one episode under the profile (a fall or an invalid
    profile: 1e3)."""
    table = profile(x)
    if table is None:
        return 1e3
    env = AnkleAssistEnv(SCENARIO, control_rate_hz=100.0, max_torque_nm=100.0,
                         overrides=OVERRIDES, reward_fn=reward)
    obs, _ = env.reset(seed=0)
    total = 0.0
    while True:
        a = np.array([table_lookup(table, obs[PH[0]]), table_lookup(table, obs[PH[1]])])
        obs, r, term, trunc, _ = env.step(a)
        total += r
        if term:
            return 1e3
        if trunc:
            return -total


def main(generations: int = 8) -> dict:
    base = objective(GENERIC)
    # search in scaled units: peak in N·m/kg, times in tens of % stride
    scale = np.array([1.0, 10.0, 10.0, 10.0])
    es = cma.CMAEvolutionStrategy(GENERIC / scale, 0.1, {"seed": 1, "popsize": 8,
                                                          "verbose": -9})
    for _ in range(generations):
        X = es.ask()
        es.tell(X, [objective(np.asarray(x) * scale) for x in X])
    best_x = np.asarray(es.result.xbest) * scale
    best = float(es.result.fbest)
    if best > base:                       # CMA-ES keeps the best it saw; the start included
        best_x, best = GENERIC, base
    fmt = "peak {:.2f} N·m/kg, peak at {:.1f} %, rise {:.1f} %, fall {:.1f} %"
    print(f"generic Zhang profile ({fmt.format(*GENERIC)}): objective {base:.4f}")
    print(f"tuned through the environment ({fmt.format(*best_x)}): objective {best:.4f} "
          f"({100 * (best - base) / abs(base):+.1f} %), {es.countevals} episodes")
    out = {"generic": GENERIC.tolist(), "generic_objective": base, "tuned": best_x.tolist(),
           "tuned_objective": best, "episodes": es.countevals, "generations": generations}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8)
