"""A third human controller, written only against the controller interface
(:mod:`afo_mj.gait.controller`) for the tests: a clock-driven torque-profile gait controller.

Each leg's phase runs on a clock (``t / cycle_time_s``, the left leg half a cycle on), with no
feedback from the feet; each joint gets a PD torque toward the reference's angle and velocity
at that phase plus a fraction of the reference's joint moment, through the joint torque
motors. The pelvis residuals (as OpenSim's residual actuators) carry half the body weight (as a
body-weight-support harness in gait training does), hold the trunk upright and push toward the
start speed, so that the clock's gait is walked whatever the legs do.
Because the legs follow a clock, its cadence is the clock's: 120 / cycle time — what the tests
check the walk's measured cadence against.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from afo_mj.gait.controller import HumanController
from afo_mj.hydraulics.params import Parameters, param

NAME = "clock_profile_test"


@dataclasses.dataclass(frozen=True)
class ClockParams(Parameters):
    """Gains of the clock controller (75 kg walker)."""

    kp_nm_per_rad: float = param(1000.0, unit="N*m/rad", lo=0.0, hi=5000.0)
    kv_nm_s_per_rad: float = param(40.0, unit="N*m*s/rad", lo=0.0, hi=500.0)
    ankle_gain_fraction: float = param(0.3, unit="1", lo=0.0, hi=1.0,
                                       doc="the ankle's PD gains as a fraction of hip and knee's")
    moment_feedforward: float = param(0.0, unit="1", lo=0.0, hi=1.5)
    body_weight_support: float = param(0.5, unit="1", lo=0.0, hi=1.0)
    support_n_s_per_m: float = param(300.0, unit="N*s/m", lo=0.0, hi=1e5)
    trunk_nm_per_rad: float = param(3000.0, unit="N*m/rad", lo=0.0, hi=1e5)
    trunk_nm_s_per_rad: float = param(300.0, unit="N*m*s/rad", lo=0.0, hi=1e4)
    speed_n_s_per_m: float = param(400.0, unit="N*s/m", lo=0.0, hi=1e5)


class ClockController(HumanController):
    """The clock-driven torque-profile controller (module docstring)."""

    name = NAME
    Params = ClockParams
    actuators = ("ff", "residual")
    reads = ("time", "qpos", "qvel", "touch")
    #: the clock's windows in which a foot's load change counts as its heel strike (late
    #: swing to loading) and its toe off (pre-swing): a clock-driven foot that brushes the
    #: floor in mid-swing is not a new stride
    heel_strike_window = (0.85, 0.25)
    toe_off_window = (0.45, 0.80)

    def start(self, phys) -> None:
        super().start(phys)
        self._z0 = float(phys.data.qpos[phys.pelvis_qpos[1]])
        ref = self.setup.reference
        self._speed = float(phys.data.qvel[phys.pelvis_dof[0]])
        self._mass = float(self.walker_params().body_mass_kg)
        self._ref = ref

    def step(self, t, phys):
        p, T, ref = self.params, self.setup.cycle_time_s, self._ref
        d = phys.data
        ph = np.mod(np.array([t / T, t / T + 0.5]), 1.0)
        q, v = d.qpos[phys.leg_qpos], d.qvel[phys.leg_dof]
        gain = np.array([1.0, 1.0, p.ankle_gain_fraction])
        tau = (gain * (p.kp_nm_per_rad * (ref.angles_rad(ph) - q)
                       + p.kv_nm_s_per_rad * (ref.velocities_rad_s(ph, T) - v))
               + p.moment_feedforward * self._mass * ref.moments_nm_per_kg(ph))
        d.ctrl[phys.ff_act] = tau
        px, pz, pt = phys.pelvis_qpos
        vx, vz, vt = phys.pelvis_dof
        d.ctrl[phys.residual_act[0]] = p.speed_n_s_per_m * (self._speed - d.qvel[vx])
        d.ctrl[phys.residual_act[1]] = (p.body_weight_support * self._mass * 9.81
                                        - p.support_n_s_per_m * d.qvel[vz])
        d.ctrl[phys.residual_act[2]] = (-p.trunk_nm_per_rad * d.qpos[pt]
                                        - p.trunk_nm_s_per_rad * d.qvel[vt])
        return self._windowed_events(ph, phys)

    def _windowed_events(self, ph, phys):
        load = phys.contact_normal_forces_n().sum(axis=1) / (self._mass * 9.81)
        out = [0, 0]
        lo, hi = self.heel_strike_window
        for s in range(2):
            in_hs = ph[s] >= lo or ph[s] < hi
            in_to = self.toe_off_window[0] <= ph[s] < self.toe_off_window[1]
            if not self._stance[s] and in_hs and load[s] > self.stance_on_fraction:
                self._stance[s] = True
                out[s] = 1
            elif self._stance[s] and in_to and load[s] < self.stance_off_fraction:
                self._stance[s] = False
                out[s] = 2
        return out[0], out[1]
