"""The compiled reflex law's muscle geometry (afo_mj.gait.reflex_law.mtu_length_and_arms_sc:
a leg's knee and ankle sines and cosines shared by its paths through the angle-addition
formulas and the table's cos φ_max, sin φ_max, sin(φ_ref − φ_max)) against the path relation
written directly, afo_mj.human.muscle.path_length_and_arm (Geyer & Herr 2010, section II-B),
summed over each muscle's paths; and the table's trigonometric columns against math."""

from __future__ import annotations

import itertools
import math

import numpy as np

from afo_mj.gait import reflex_law as rl
from afo_mj.human import muscle as mu


def _direct(m, phi_h, phi_k, phi_a):
    """(l_MTU, r per path) from path_length_and_arm, each path at its own joint's angle."""
    p, paths = mu.GEYER_HERR_2010[rl.MUSCLES[m]]
    lm = p.optimal_length_m + p.slack_length_m
    arms = [0.0, 0.0]
    for q, jp in enumerate(paths):
        phi = {"hip": phi_h, "knee": phi_k, "ankle": phi_a}[jp.joint]
        dl, r = mu.path_length_and_arm(phi, float(jp.sign), jp.r0_m, jp.phi_max_rad or 0.0,
                                       jp.phi_ref_rad, jp.rho, jp.phi_max_rad is None)
        lm += dl
        arms[q] = r
    return lm, arms


def test_table_holds_each_paths_trigonometry():
    T = rl.muscle_table(1e-3)
    for m, name in enumerate(rl.MUSCLES):
        for q, jp in enumerate(mu.GEYER_HERR_2010[name][1]):
            c = rl.T_PATH + rl.PATH_W * q
            pm = jp.phi_max_rad or 0.0
            assert T[m, c + 7] == math.cos(pm) and T[m, c + 8] == math.sin(pm)
            assert T[m, c + 9] == math.sin(jp.phi_ref_rad - pm)


def test_shared_trigonometry_is_the_path_relation():
    """MTU length to 1e-15 m and moment arms to 1e-15 m of the direct relation, for every
    muscle over a grid of hip, knee and ankle angles spanning walking and beyond."""
    T = rl.muscle_table(1e-3)
    angles = np.radians([-40.0, -10.0, 0.0, 15.0, 45.0, 90.0])
    for th_h, th_k, th_a in itertools.product(angles, angles, angles):
        ph, pk, pa = rl.geyer_angles(th_h, th_k, th_a)
        for m in range(rl.N_MUSCLES):
            lm, r0, r1 = rl.mtu_length_and_arms(T, m, ph, pk, pa)
            lm_ref, (r0_ref, r1_ref) = _direct(m, ph, pk, pa)
            assert abs(lm - lm_ref) < 1e-15 and abs(r0 - r0_ref) < 1e-15
            assert abs(r1 - r1_ref) < 1e-15
