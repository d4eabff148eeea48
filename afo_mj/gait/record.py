"""What a gait run hands to the analysis: sampled signals and gait events, SI units.

The driver fills a :class:`GaitRecord` once per control step into preallocated arrays (no
allocation in the loop) and trims it at the end. Sign conventions: joint angles positive =
hip flexion, knee flexion, ankle dorsiflexion; joint moments in the same direction as the angle
(positive moment acts to increase the angle), so joint power = moment × angular velocity.
Side index 0 = right, 1 = left; joint index 0 = hip, 1 = knee, 2 = ankle.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["GaitRecord", "GaitEvents", "phase_from_events"]


@dataclasses.dataclass
class GaitEvents:
    """Gait events detected from foot contact during the run (times in s).

    ``heel_strikes_s[side]`` and ``toe_offs_s[side]`` are sorted times; ``fall_time_s`` is the
    time the walker fell (pelvis below a height threshold) or ``None``; ``swing_toe_contacts``
    lists (time_s, side) of forefoot-floor contacts during swing (scuffs, stumbles).
    """

    heel_strikes_s: tuple[list[float], list[float]] = dataclasses.field(
        default_factory=lambda: ([], []))
    toe_offs_s: tuple[list[float], list[float]] = dataclasses.field(
        default_factory=lambda: ([], []))
    fall_time_s: float | None = None
    swing_toe_contacts: list[tuple[float, int]] = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class GaitRecord:
    """Signals of a walking run, one row per sample at ``sample_period_s``.

    Shapes: n samples; (n, 2, 3) = [sample, side, joint]; (n, 2, 2) = [sample, side, part] with
    part 0 = heel, 1 = ball (forefoot) for contact, or component 0 = x (forward), 1 = z (up)
    for forces.
    """

    body_mass_kg: float
    height_m: float
    sample_period_s: float
    time_s: np.ndarray                      # (n,)
    joint_angle_rad: np.ndarray             # (n, 2, 3)
    joint_velocity_rad_s: np.ndarray        # (n, 2, 3)
    joint_moment_nm: np.ndarray             # (n, 2, 3) human (muscle) net joint moment
    device_moment_nm: np.ndarray            # (n, 2) orthosis torque on the ankle, same sign
    grf_n: np.ndarray                       # (n, 2, 2) ground reaction force per foot [x, z]
    contact_force_n: np.ndarray             # (n, 2, 2) normal force on heel and ball spheres
    contact_height_m: np.ndarray            # (n, 2, 2) lowest point of heel / ball above floor
    pelvis_position_m: np.ndarray           # (n, 2) hip-centre x, z
    pelvis_velocity_m_s: np.ndarray         # (n, 2)
    pelvis_tilt_rad: np.ndarray             # (n,)  positive = forward lean
    residual_force_n: np.ndarray            # (n, 2) pelvis residual force [x, z]
    residual_moment_nm: np.ndarray          # (n,)  pelvis residual pitch moment
    gait_phase: np.ndarray                  # (n, 2) controller's phase estimate per leg, 0..1
    events: GaitEvents = dataclasses.field(default_factory=GaitEvents)
    #: (n, nq) generalised positions of the MuJoCo model, for replaying the run in 3D
    #: (recordings, videos); ``None`` when the run did not keep them
    qpos: np.ndarray | None = None
    #: the compiled walker's MJCF text (builtin textures only, no asset files), so the
    #: model of ``qpos`` can be rebuilt with ``mujoco.MjModel.from_xml_string``
    model_xml: str | None = None
    #: per-step signals of the human controller beside the joint signals, by name, each
    #: ``(n,) + shape`` (e.g. a muscle controller's activations); empty when it declares none
    signals: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def allocate(cls, n: int, body_mass_kg: float, height_m: float,
                 sample_period_s: float) -> "GaitRecord":
        """Preallocated zero arrays for ``n`` samples."""
        z = np.zeros
        return cls(body_mass_kg, height_m, sample_period_s, z(n), z((n, 2, 3)), z((n, 2, 3)),
                   z((n, 2, 3)), z((n, 2)), z((n, 2, 2)), z((n, 2, 2)), z((n, 2, 2)), z((n, 2)),
                   z((n, 2)), z(n), z((n, 2)), z(n), z((n, 2)))

    def array_fields(self) -> list[str]:
        return [f.name for f in dataclasses.fields(self)
                if isinstance(getattr(self, f.name), np.ndarray)]

    def trimmed(self, n: int) -> "GaitRecord":
        """The first ``n`` samples (views)."""
        return dataclasses.replace(self, **{k: getattr(self, k)[:n] for k in self.array_fields()},
                                   signals={k: v[:n] for k, v in self.signals.items()})

    @property
    def joint_power_w(self) -> np.ndarray:
        """(n, 2, 3) human joint power, moment × angular velocity [W]."""
        return self.joint_moment_nm * self.joint_velocity_rad_s


def phase_from_events(time_s: np.ndarray, events: GaitEvents) -> np.ndarray:
    """(n, 2) gait phase per leg at ``time_s``: time since its last heel strike over the last
    stride's duration (0 before its second heel strike), clipped to [0, 1].

    Times in increasing order (a walk's) are filled stride by stride, each stride's samples a
    slice (no per-sample index arrays); others per sample. The same arithmetic either way."""
    t = np.asarray(time_s, float)
    out = np.zeros((len(t), 2))
    ordered = len(t) < 2 or bool((t[1:] >= t[:-1]).all())
    for s in range(2):
        hs = np.asarray(events.heel_strikes_s[s], float)
        if len(hs) < 2:
            continue
        if ordered:
            # the samples whose last heel strike is hs[j]: from the first t >= hs[j] on
            first = np.searchsorted(t, hs, side="left")
            for j in range(1, len(hs)):
                lo = first[j]
                hi = first[j + 1] if j + 1 < len(hs) else len(t)
                if hi > lo:
                    b, a = hs[j], hs[j - 1]
                    np.clip((t[lo:hi] - b) / (b - a), 0.0, 1.0, out=out[lo:hi, s])
            continue
        i = np.searchsorted(hs, t, side="right") - 1          # the last heel strike <= t
        sel = i >= 1
        b, a = hs[i[sel]], hs[i[sel] - 1]
        out[sel, s] = np.clip((t[sel] - b) / (b - a), 0.0, 1.0)
    return out
