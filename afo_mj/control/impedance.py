"""Impedance emulation: the commanded ankle torque of a spring, damper or clutched spring that
changes with the gait phase (the stiffness-emulating orthoses of seed ch. 7; facts.md).

A device that emulates a passive AFO asks its torque loop for the torque of the emulated
element at the present joint state instead of a tabulated torque vs phase
(:mod:`afo_mj.control.assistance`). The rows are packed by :func:`impedance_table` into the
same buffer a profile would use and read per step by the compiled :func:`impedance_torque`.

Each row is ``(phase_end, K, B, θ0, clutched)``: it applies while the stride phase is below
``phase_end`` (the rows in increasing order; the last also after it); ``K`` in N·m/rad,
``B`` in N·m·s/rad, ``θ0`` the rest angle (rad, +dorsiflexion) and ``clutched`` 1 for a
spring engaged only past ``θ0`` in dorsiflexion (the clutched spring of Nuckols & Sawicki,
"Impact of elastic ankle exoskeleton stiffness on neuromechanics and energetics of human
walking across multiple speeds", *J NeuroEng Rehabil* 17:75, 2020).

Example — a 3 N·m/deg spring about neutral, all stride long::

    table = impedance_table([(1.0, 3.0 * 180 / math.pi, 0.0, 0.0, 0)])
    impedance_torque(table, 0.3, 0.1, 0.0)   # -17.2 N·m: the spring resists dorsiflexion
"""

from __future__ import annotations

import numba
import numpy as np

from afo_mj.hydraulics.params import ParameterError

#: numbers per impedance row
IMP_COLS = 5

__all__ = ["IMP_COLS", "impedance_table", "impedance_torque"]


def impedance_table(rows) -> np.ndarray:
    """Pack impedance rows ``(phase_end, stiffness_nm_per_rad, damping_nm_s_per_rad,
    rest_angle_rad, clutched)`` into the buffer :func:`impedance_torque` reads:
    ``[n_rows, row_0 …, row_{n−1} …]``. ``phase_end`` increases from row to row; stiffness
    and damping are ≥ 0."""
    try:
        rows = [tuple(float(v) for v in r) for r in rows]
    except (TypeError, ValueError):
        raise ParameterError(f"impedance = {rows!r}; allowed: rows of 5 numbers (phase_end, "
                             "stiffness_nm_per_rad, damping_nm_s_per_rad, rest_angle_rad, "
                             "clutched 0/1)") from None
    if not rows:
        raise ParameterError("impedance = []; allowed: at least one row (phase_end, K, B, "
                             "theta0, clutched)")
    last = -1.0
    for r in rows:
        if len(r) != IMP_COLS:
            raise ParameterError(f"impedance row = {r!r}; allowed: 5 numbers (phase_end, "
                                 "stiffness_nm_per_rad, damping_nm_s_per_rad, rest_angle_rad, "
                                 "clutched 0/1)")
        if not np.all(np.isfinite(r)):
            raise ParameterError(f"impedance row = {r!r}; allowed: finite numbers")
        if r[0] <= last or r[1] < 0 or r[2] < 0:
            raise ParameterError(f"impedance row = {r!r}; allowed: phase_end increasing, "
                                 "stiffness and damping ≥ 0")
        if r[4] not in (0.0, 1.0):
            raise ParameterError(f"impedance row = {r!r}: clutched = {r[4]!r}; allowed: 0, 1")
        last = r[0]
    return np.array([float(len(rows))] + [v for r in rows for v in r])


@numba.njit(cache=True)
def impedance_torque(table, phase, theta, theta_dot):
    """Commanded torque of the emulated element (+dorsiflexion, N·m).

    The row is the first whose ``phase_end`` exceeds the gait phase (phase < 0, not yet
    known: the first row). ``τ = −K (θ − θ0) − B θ̇``; a clutched row is engaged only past
    ``θ0`` in dorsiflexion: ``τ = −K (θ − θ0) − B θ̇`` for ``θ > θ0``, else 0 (module
    docstring: Nuckols & Sawicki 2020)."""
    n = int(table[0])
    row = 0
    if phase >= 0.0:
        row = n - 1
        for k in range(n):
            if phase < table[1 + k * IMP_COLS]:
                row = k
                break
    b = 1 + row * IMP_COLS
    stiffness = table[b + 1]
    damping = table[b + 2]
    theta0 = table[b + 3]
    if table[b + 4] != 0.0 and theta <= theta0:
        return 0.0
    return -stiffness * (theta - theta0) - damping * theta_dot
