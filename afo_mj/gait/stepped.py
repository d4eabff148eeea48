"""What every steppable walk (:class:`afo_mj.gait.controller_walk.ControllerWalk` and its
built-in subclasses :class:`afo_mj.gait.walk.Walk`,
:class:`afo_mj.gait.muscle_walk.MuscleWalkStepper`) reads the same way: the named accessors
of the MuJoCo state they share, written once. A walk provides ``data`` (its ``MjData``),
``phys`` (its :class:`~afo_mj.human.walker.WalkerPhysics`), ``events`` (its
:class:`~afo_mj.gait.record.GaitEvents`), ``_done`` (a one-element list) and ``_steps()`` (the
rows recorded); what differs between walkers (phase, stance, the moments) stays in each.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SteppedWalk"]


class SteppedWalk:
    """The accessors shared by the steppable walks (module docstring); copies, not views."""

    @property
    def done(self) -> bool:
        """The walk has ended (a fall, its strides or its duration walked)."""
        return self._done[0]

    @property
    def steps(self) -> int:
        """Steps recorded so far."""
        return self._steps()

    @property
    def fallen(self) -> bool:
        return self.events.fall_time_s is not None

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def joint_angles_rad(self) -> np.ndarray:
        """(2, 3) [right, left][hip, knee, ankle] (+ flexion, + dorsiflexion)."""
        return self.data.qpos[self.phys.leg_qpos].copy()

    @property
    def joint_velocities_rad_s(self) -> np.ndarray:
        return self.data.qvel[self.phys.leg_dof].copy()

    @property
    def grf_n(self) -> np.ndarray:
        """(2, 2) ground reaction force per foot [forward, up] (N)."""
        s = self.data.sensordata
        adr = self.phys.foot_force_adr
        return -np.stack([s[adr], s[adr + 2]], axis=1)

    @property
    def pelvis_speed_m_s(self) -> float:
        return float(self.data.qvel[self.phys.pelvis_dof[0]])
