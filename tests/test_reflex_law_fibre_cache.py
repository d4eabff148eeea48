"""The reflex law keeps each muscle's Bhargava fibre excitations (u_ST, u_FT) while its
excitation holds (X_FIBRE_U …): a walk's law steps with that cache equal, bit for bit, the
same steps with the cache emptied before every step (each rate computed from u afresh), and
the cache is used (the excitation held in a good part of the muscle-steps)."""

from __future__ import annotations

import numpy as np

from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import (GRAVITY_M_S2, MuscleWalkStepper, load_reflex_set,
                                     muscle_table_scaled)


def test_the_fibre_cache_is_a_fresh_computation_bit_for_bit():
    w = MuscleWalkStepper(params=load_reflex_set("afo_mj/data/reflex_params_1.25.json"),
                          duration_s=1.0, loop="python")
    d, phys = w.data, w.phys
    X0 = w._X.copy()
    inputs = []
    while not w.done:
        inputs.append((d.time, d.qpos.copy(), d.qvel.copy(), d.sensordata.copy()))
        w.step()
    h = float(w.model.opt.timestep)
    T = muscle_table_scaled(h, None, w.walker.height_m)
    mg = phys.body_mass_kg * GRAVITY_M_S2
    cached, fresh = X0.copy(), X0.copy()
    ring_c = np.zeros((rl.RING_LEN, rl.RING_COLS))
    ring_f = ring_c.copy()
    held = 0
    u = rl.X_U
    for t, q, v, s in inputs:
        u_before = cached[rl.X_FIBRE_U:rl.X_FIBRE_U + 14].copy()
        fresh[rl.X_FIBRE_U:rl.X_FIBRE_U + 14] = -1.0
        for X, ring in ((cached, ring_c), (fresh, ring_f)):
            rl.reflex_step(t, h, q, v, s, phys.leg_qpos, phys.leg_dof, phys.touch_adr,
                           int(phys.pelvis_qpos[2]), int(phys.pelvis_dof[2]), w.params, T, X,
                           ring, mg)
        held += int(np.sum(cached[u:u + 14] == u_before))
        assert np.array_equal(cached, fresh)
    # the law replayed is the walk's
    assert np.array_equal(cached[rl.X_ACT:rl.X_ACT + 14].reshape(2, 7),
                          w.record().activation[-1])
    assert held > 0.2 * 14 * len(inputs)
