"""The sagittal-plane walker: MJCF built with ``dm_control.mjcf`` and a Physics with named
accessors.

Seven segments (HAT = head, arms, trunk and pelvis; thigh, shank, foot per leg) scaled from de
Leva (1996) by body mass and stature (:mod:`afo_mj.human.anthropometry`). The pelvis is free in
the sagittal plane (``pelvis_tx`` forward, ``pelvis_tz`` up, ``pelvis_tilt`` pitch, positive =
forward lean). Hinges per leg ``hip_{r,l}``, ``knee_{r,l}``, ``ankle_{r,l}`` with the clinical
sign: positive = hip flexion, knee flexion, ankle dorsiflexion. Each foot touches the floor
through two spheres, ``heel_{side}`` and ``ball_{side}`` (the metatarsal heads: the foot is
rigid, toes are not modelled, so the ball sphere is the lowest forefoot point and "toe clearance"
is measured at it). Contact is never switched off.

Actuators per leg joint: ``pd_{joint}_{side}`` a proportional-derivative servo evaluated inside
MuJoCo (force = kp·(ctrl − q) − kv·q̇; set ctrl = q_ref + kv/kp·q̇_ref to track a velocity
too) and ``ff_{joint}_{side}`` a torque motor for feedforward and balance feedback. Their sum
is clamped per joint by ``actuatorfrcrange``: this is where the strength of each muscle group
lives (plantarflexor weakness lowers the negative ankle limit). Residual actuators
``residual_tx``, ``residual_tz``, ``residual_tilt`` act on the pelvis as OpenSim's residuals do.
Sensors: ``touch_{heel,ball}_{side}`` (normal contact force on each sphere) and
``foot_floor_force_{side}`` (MuJoCo's net-force contact sensor, world frame; the ground
reaction force is its negative).

Sites for devices: ``waist`` (power supply worn at the lower back), ``shank_cuff_{side}``,
``foot_plate_{side}`` and ``ankle_axis_{side}`` (the pulley axis of an orthosis). Devices add
their mass where they are worn with :func:`build_walker`'s ``worn_masses``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Sequence

import mujoco
import numpy as np
from dm_control import mjcf

from afo_mj.hydraulics.params import ParameterError, Parameters, param
from afo_mj.human.anthropometry import BodySegments, scale_body

__all__ = ["WalkerParams", "WornMass", "build_walker", "WalkerPhysics", "SIDES", "JOINTS",
           "hill_concentric_fraction", "write_default_xml", "DynamicScale"]

SIDES = ("r", "l")
JOINTS = ("hip", "knee", "ankle")
# Hinge axes giving the clinical sign convention (y points to the walker's left).
_AXIS = {"hip": (0, -1, 0), "knee": (0, 1, 0), "ankle": (0, -1, 0)}


@dataclasses.dataclass(frozen=True)
class WalkerParams(Parameters):
    """Body size, sole geometry, joint strength and passive joint properties of the walker.

    Strengths are the largest net actuator torques each muscle group can produce, per kg body
    mass, stated for a 1.75 m adult; other statures get them scaled by dynamic similarity
    (× stature / 1.75 m, as gait moments per kg scale), and the plantarflexors' unloaded speed
    by √(1.75 m / stature). Defaults: plantarflexors 2.5 N·m/kg isometric (healthy young adults
    produce about 150–200 N·m at 70–80 kg; above Winter's 1.69 N·m/kg gait peak), falling with
    shortening speed on Hill's curve (unloaded speed 20 rad/s, a/F0 0.25: about 55 % at
    180°/s, as isovelocity dynamometry shows); dorsiflexors 0.6 N·m/kg; hip and knee 3 N·m/kg.
    Impairments are fractions of these (1 = healthy) plus added passive ankle stiffness and
    damping for spasticity.
    """

    body_mass_kg: float = param(75.0, unit="kg", lo=10.0, hi=200.0, doc="body mass")
    height_m: float = param(1.75, unit="m", lo=0.8, hi=2.2, doc="stature")
    sole_pitch_rad: float = param(math.radians(6.0), unit="rad", lo=-0.3, hi=0.3,
                                  doc="heel-to-ball line pitched toe-up in the foot frame at 0 "
                                      "ankle angle (torque walker; the muscle walker's is "
                                      "level)")
    contact_radius_fraction: float = param(0.012, unit="1", lo=0.002, hi=0.03,
                                           doc="contact sphere radius / stature")
    ball_fraction: float = param(0.73, unit="1", lo=0.5, hi=1.0,
                                 doc="metatarsal heads from the heel / foot length")
    friction: float = param(1.0, unit="1", lo=0.1, hi=3.0, doc="foot-floor friction coefficient")
    contact_time_constant_s: float = param(
        0.015, unit="s", lo=0.002, hi=0.1,
        doc="MuJoCo solref time constant of foot-floor contact (critically damped) for a "
            "1.75 m body, × √(stature / 1.75 m) for others: the softness of heel pad and shoe")
    plantarflexor_strength_nm_per_kg: float = param(2.5, unit="N*m/kg", lo=0.1, hi=5.0)
    dorsiflexor_strength_nm_per_kg: float = param(0.6, unit="N*m/kg", lo=0.05, hi=3.0)
    hip_knee_strength_nm_per_kg: float = param(3.0, unit="N*m/kg", lo=0.5, hi=6.0)
    plantarflexor_strength_fraction: float = param(
        1.0, unit="1", lo=0.0, hi=1.0, doc="plantarflexor weakness: 1 healthy, 0.5 = half")
    dorsiflexor_strength_fraction: float = param(1.0, unit="1", lo=0.0, hi=1.0,
                                                 doc="dorsiflexor weakness (foot drop): 1 healthy")
    ankle_passive_stiffness_nm_per_rad: float = param(
        0.0, unit="N*m/rad", lo=0.0, hi=2000.0, doc="added passive ankle stiffness (spasticity)")
    ankle_passive_damping_nm_s_per_rad: float = param(
        0.0, unit="N*m*s/rad", lo=0.0, hi=100.0, doc="added passive ankle damping (spasticity)")
    plantarflexor_max_velocity_rad_s: float = param(
        20.0, unit="rad/s", lo=1.0, hi=200.0,
        doc="joint-level unloaded plantarflexion speed of the Hill torque-velocity curve")
    hill_curvature: float = param(0.25, unit="1", lo=0.05, hi=2.0,
                                  doc="Hill's a/F0 (curvature of the torque-velocity hyperbola)")
    timestep_s: float = param(1e-3, unit="s", lo=1e-4, hi=5e-3,
                              doc="MuJoCo time step; walkers below about 1.3 m stature need 0.5 ms "
                                  "(their dynamics are faster by √(1.75 m / stature))")


@dataclasses.dataclass(frozen=True)
class DynamicScale:
    """Factors that carry quantities of the 75 kg, 1.75 m reference walker to another body
    size under dynamic similarity (equal Froude number; Alexander & Jayes 1983, J. Zool.
    201:135): lengths × λ, times × √λ, speeds × √λ, forces × μ, torques × μ·λ, with
    λ = stature / 1.75 m and μ = mass / 75 kg.

    >>> DynamicScale.of(37.5, 1.4).torque
    0.4
    """

    length: float
    mass: float

    @classmethod
    def of(cls, body_mass_kg: float, height_m: float) -> "DynamicScale":
        return cls(height_m / 1.75, body_mass_kg / 75.0)

    @property
    def time(self) -> float:
        return math.sqrt(self.length)

    @property
    def speed(self) -> float:
        return math.sqrt(self.length)

    @property
    def force(self) -> float:
        return self.mass

    @property
    def torque(self) -> float:
        """N·m and N·m/rad."""
        return self.mass * self.length

    @property
    def rotational_damping(self) -> float:
        """N·m·s/rad: torque × time."""
        return self.mass * self.length * math.sqrt(self.length)

    @property
    def linear_stiffness(self) -> float:
        """N/m: force / length."""
        return self.mass / self.length

    @property
    def linear_damping(self) -> float:
        """N·s/m: force / speed."""
        return self.mass / math.sqrt(self.length)


def hill_concentric_fraction(shortening_velocity_rad_s, max_velocity_rad_s: float,
                             curvature: float):
    """Fraction of isometric torque a muscle group can produce while shortening.

    Hill's (1938) hyperbola written at joint level, as joint-torque models use it (e.g.
    Anderson, Madigan & Nussbaum 2007, J. Biomech. 40:3105):
    T/T0 = (1 − ω/ω_max) / (1 + ω/(a·ω_max)) for shortening speed 0 ≤ ω ≤ ω_max (0 beyond),
    1 when lengthening (eccentric enhancement left out). ``a`` is the curvature a/F0.

    >>> round(hill_concentric_fraction(3.0, 30.0, 0.25), 3)
    0.643
    """
    w = np.clip(np.asarray(shortening_velocity_rad_s, float) / max_velocity_rad_s, 0.0, 1.0)
    return (1.0 - w) / (1.0 + w / curvature)


@dataclasses.dataclass(frozen=True)
class WornMass:
    """A point-like mass worn at a walker site (a device part, a battery)."""

    site: str
    mass_kg: float
    name: str = "device"

    def __post_init__(self) -> None:
        if not (self.mass_kg >= 0 and math.isfinite(self.mass_kg)):
            raise ParameterError(f"WornMass.mass_kg = {self.mass_kg!r}; allowed: finite >= 0")


def add_foot_segment(foot, seg: BodySegments, p: WalkerParams, suffix: str = ""
                     ) -> tuple[float, float, float, float]:
    """Give a foot body (frame at the ankle axis, x forward) its mass, inertia, a visual
    capsule along the sole and the ``foot_plate`` site; return the sole's contact points
    (heel x, ball x, heel z, ball z) for contact spheres of radius
    ``contact_radius_fraction × stature``. The heel–ball line is pitched ``sole_pitch_rad``
    toe-up (Winter's neutral ankle then loads the heel); the foot CoM is de Leva's, from the
    heel. Shared by the walker and the ankle test stand."""
    r = p.contact_radius_fraction * p.height_m
    ft = seg.foot
    heel_x = -seg.heel_to_ankle_m + r
    ball_x = p.ball_fraction * ft.length_m - seg.heel_to_ankle_m
    sole_z = -seg.ankle_height_m + r
    ball_z = sole_z + math.tan(p.sole_pitch_rad) * (ball_x - heel_x)
    com_x = ft.com_from_proximal_m - seg.heel_to_ankle_m
    foot.add("inertial", pos=[com_x, 0, -0.5 * seg.ankle_height_m], mass=ft.mass_kg,
             diaginertia=[0.3 * ft.inertia_kg_m2, ft.inertia_kg_m2, ft.inertia_kg_m2])
    foot.add("geom", name=f"foot{suffix}", type="capsule", size=[0.5 * r],
             fromto=[heel_x, 0, sole_z, ft.length_m - seg.heel_to_ankle_m, 0, ball_z],
             mass=0, contype=0, conaffinity=0, rgba=[0.4, 0.4, 0.5, 1])
    foot.add("site", name=f"foot_plate{suffix}",
             pos=[0.5 * (heel_x + ball_x), 0, sole_z - r + 0.005], size=[0.01])
    return heel_x, ball_x, sole_z, ball_z


def _leg(parent, side: str, seg: BodySegments, p: WalkerParams, y: float,
         kp: dict[str, float], kv: dict[str, float]) -> None:
    s = p.height_m
    r = p.contact_radius_fraction * s
    th, sh = seg.thigh, seg.shank
    thigh = parent.add("body", name=f"thigh_{side}", pos=[0, y, 0])
    thigh.add("joint", name=f"hip_{side}", type="hinge", axis=_AXIS["hip"], range=[-0.7, 1.4])
    thigh.add("inertial", pos=[0, 0, -th.com_from_proximal_m], mass=th.mass_kg,
              diaginertia=[th.inertia_kg_m2, th.inertia_kg_m2, 0.2 * th.inertia_kg_m2])
    thigh.add("geom", name=f"thigh_{side}", type="capsule", size=[0.06 * s / 1.75],
              fromto=[0, 0, 0, 0, 0, -th.length_m], mass=0, contype=0, conaffinity=0,
              rgba=[0.8, 0.6, 0.5, 1])
    shank = thigh.add("body", name=f"shank_{side}", pos=[0, 0, -th.length_m])
    shank.add("joint", name=f"knee_{side}", type="hinge", axis=_AXIS["knee"], range=[-0.1, 2.3])
    shank.add("inertial", pos=[0, 0, -sh.com_from_proximal_m], mass=sh.mass_kg,
              diaginertia=[sh.inertia_kg_m2, sh.inertia_kg_m2, 0.15 * sh.inertia_kg_m2])
    shank.add("geom", name=f"shank_{side}", type="capsule", size=[0.045 * s / 1.75],
              fromto=[0, 0, 0, 0, 0, -sh.length_m], mass=0, contype=0, conaffinity=0,
              rgba=[0.8, 0.6, 0.5, 1])
    shank.add("site", name=f"shank_cuff_{side}", pos=[0.05 * s / 1.75, 0, -0.35 * sh.length_m],
              size=[0.01])
    foot = shank.add("body", name=f"foot_{side}", pos=[0, 0, -sh.length_m])
    ankle_range = [-0.7, 0.6]
    foot.add("joint", name=f"ankle_{side}", type="hinge", axis=_AXIS["ankle"], range=ankle_range,
             stiffness=p.ankle_passive_stiffness_nm_per_rad,
             damping=p.ankle_passive_damping_nm_s_per_rad)
    heel_x, ball_x, sole_z, ball_z = add_foot_segment(foot, seg, p, f"_{side}")
    for name, x, z in (("heel", heel_x, sole_z), ("ball", ball_x, ball_z)):
        foot.add("geom", name=f"{name}_{side}", type="sphere", size=[r], pos=[x, 0, z],
                 mass=0, contype=1, conaffinity=0, condim=3, friction=[p.friction, 0.005, 1e-4],
                 rgba=[0.2, 0.2, 0.3, 1])
    shank.add("site", name=f"ankle_axis_{side}", pos=[0, 0, -sh.length_m], size=[0.012])


def build_walker(params: WalkerParams | None = None, worn_masses: Sequence[WornMass] = (),
                 kp: dict[str, float] | None = None, kv: dict[str, float] | None = None
                 ) -> mjcf.RootElement:
    """Build the walker's MJCF (a ``dm_control.mjcf`` root) for a body size and impairment.

    ``kp`` and ``kv`` give the PD servo gains per joint kind (``hip``, ``knee``, ``ankle``) in
    N·m/rad and N·m·s/rad, as used (the controller scales them to body size; the defaults are
    the 75 kg, 1.75 m walker's).
    """
    p = params or WalkerParams()
    seg = scale_body(p.body_mass_kg, p.height_m)
    kp = {"hip": 600.0, "knee": 600.0, "ankle": 300.0, **(kp or {})}
    kv = {"hip": 30.0, "knee": 30.0, "ankle": 5.0, **(kv or {})}
    m = p.body_mass_kg
    root = mjcf.RootElement(model="walker")
    root.compiler.angle = "radian"
    root.option.timestep = p.timestep_s
    root.option.integrator = "implicitfast"
    root.size.njmax = 200
    root.visual.headlight.ambient = [0.4, 0.4, 0.4]
    root.asset.add("texture", name="grid", type="2d", builtin="checker", width=256, height=256,
                   rgb1=[0.85, 0.85, 0.85], rgb2=[0.7, 0.7, 0.7])
    root.asset.add("material", name="grid", texture="grid", texrepeat=[20, 20])
    root.default.geom.solref = [p.contact_time_constant_s
                                * math.sqrt(p.height_m / 1.75), 1.0]
    # MuJoCo's default impedance (0.9 → 0.95 over 1 mm of penetration), width scaled with size
    root.default.geom.solimp = [0.9, 0.95, 0.001 * p.height_m / 1.75, 0.5, 2]
    wb = root.worldbody
    wb.add("light", pos=[0, -3, 4], dir=[0, 1, -1])
    wb.add("geom", name="floor", type="plane", size=[100, 2, 0.1], material="grid",
           contype=0, conaffinity=1, friction=[p.friction, 0.005, 1e-4])
    hat = seg.hat
    hip_z = seg.hip_height_m
    pelvis = wb.add("body", name="pelvis", pos=[0, 0, hip_z])
    pelvis.add("joint", name="pelvis_tx", type="slide", axis=[1, 0, 0])
    pelvis.add("joint", name="pelvis_tz", type="slide", axis=[0, 0, 1])
    pelvis.add("joint", name="pelvis_tilt", type="hinge", axis=[0, 1, 0])
    pelvis.add("inertial", pos=[0, 0, hat.com_from_proximal_m], mass=hat.mass_kg,
               diaginertia=[hat.inertia_kg_m2, hat.inertia_kg_m2, 0.3 * hat.inertia_kg_m2])
    pelvis.add("geom", name="trunk", type="capsule", size=[0.12 * p.height_m / 1.75],
               fromto=[0, 0, 0.05, 0, 0, 0.55 * hat.length_m], mass=0, contype=0, conaffinity=0,
               rgba=[0.3, 0.5, 0.7, 1])
    pelvis.add("geom", name="head", type="sphere", size=[0.1 * p.height_m / 1.75],
               pos=[0, 0, 0.87 * hat.length_m], mass=0, contype=0, conaffinity=0,
               rgba=[0.8, 0.6, 0.5, 1])
    pelvis.add("site", name="waist", pos=[-0.12 * p.height_m / 1.75, 0, 0.08], size=[0.02])
    half_width = 0.09 * p.height_m / 1.75
    for side, y in (("r", -half_width), ("l", half_width)):
        _leg(pelvis, side, seg, p, y, kp, kv)

    ds = DynamicScale.of(m, p.height_m)
    mt = m * ds.length           # per-kg strengths are for 1.75 m: × λ (dynamic similarity)
    strength = {
        "hip": (-p.hip_knee_strength_nm_per_kg * mt, p.hip_knee_strength_nm_per_kg * mt),
        "knee": (-p.hip_knee_strength_nm_per_kg * mt, p.hip_knee_strength_nm_per_kg * mt),
        "ankle": (-p.plantarflexor_strength_nm_per_kg * mt * p.plantarflexor_strength_fraction,
                  p.dorsiflexor_strength_nm_per_kg * mt * p.dorsiflexor_strength_fraction),
    }
    for side in SIDES:
        for j in JOINTS:
            jn = f"{j}_{side}"
            joint = root.find("joint", jn)
            joint.actuatorfrclimited = "true"
            joint.actuatorfrcrange = list(strength[j])
            k, d = kp[j], kv[j]
            root.actuator.add("general", name=f"pd_{jn}", joint=jn, gaintype="fixed",
                              gainprm=[k], biastype="affine", biasprm=[0, -k, -d])
            root.actuator.add("motor", name=f"ff_{jn}", joint=jn, gear=[1])
    for dof in ("tx", "tz", "tilt"):
        root.actuator.add("motor", name=f"residual_{dof}", joint=f"pelvis_{dof}", gear=[1])
    for side in SIDES:
        for part in ("heel", "ball"):
            root.sensor.add("touch", name=f"touch_{part}_{side}",
                            site=_touch_site(root, part, side, seg, p))
    for side in SIDES:
        # Net contact force of the foot on the floor, world frame (MuJoCo's contact sensor,
        # reduce="netforce"); the ground reaction force is its negative.
        root.sensor.add("contact", name=f"foot_floor_force_{side}", subtree1=f"foot_{side}",
                        geom2="floor", data="force", reduce="netforce", num=1)
    for wm in worn_masses:
        site = root.find("site", wm.site)
        if site is None:
            raise ParameterError(f"WornMass.site = {wm.site!r} is not a walker site; allowed: "
                                 + ", ".join(s.name for s in root.find_all("site")))
        body = site.parent.add("body", name=f"worn_{wm.name}_{wm.site}", pos=site.pos)
        body.add("inertial", pos=[0, 0, 0], mass=max(wm.mass_kg, 1e-9),
                 diaginertia=[1e-5 + 1e-3 * wm.mass_kg] * 3)
    return root


def _touch_site(root, part: str, side: str, seg: BodySegments, p: WalkerParams) -> str:
    geom = root.find("geom", f"{part}_{side}")
    r = geom.size[0]
    geom.parent.add("site", name=f"touch_{part}_{side}", type="sphere", size=[1.6 * r],
                    pos=geom.pos, rgba=[0, 0, 0, 0])
    return f"touch_{part}_{side}"


#: where ``afo-mj build-models`` writes the default walker (75 kg, 1.75 m, healthy)
DEFAULT_XML_PATH = Path(__file__).resolve().parents[2] / "models" / "mjcf" / "walker.xml"


def write_default_xml(path: str | Path = DEFAULT_XML_PATH) -> Path:
    """Write the default walker (75 kg, 1.75 m, healthy, default gains) as MJCF; returns the
    path. The file is for inspection and for other tools (e.g. ``python -m mujoco.viewer``);
    afo_mj itself always builds the model from :class:`WalkerParams`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(build_walker().to_xml_string())
    return path


class WalkerPhysics:
    """A compiled walker with named index arrays for the hot loop (no name lookups per step).

    ``qpos_adr[j]``/``dof_adr[j]`` for joint names, ``act[name]`` actuator ids; ``leg_qpos``
    and ``leg_dof`` are (2, 3) index arrays [side r/l, hip/knee/ankle].
    """

    def __init__(self, root: mjcf.RootElement):
        self.xml = root.to_xml_string()
        self.model = mujoco.MjModel.from_xml_string(self.xml, root.get_assets())
        self.data = mujoco.MjData(self.model)
        m = self.model
        jid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)  # noqa: E731
        self.qpos_adr = {m.joint(i).name: int(m.jnt_qposadr[i]) for i in range(m.njnt)}
        self.dof_adr = {m.joint(i).name: int(m.jnt_dofadr[i]) for i in range(m.njnt)}
        self.act = {m.actuator(i).name: i for i in range(m.nu)}
        self.leg_qpos = np.array([[self.qpos_adr[f"{j}_{s}"] for j in JOINTS] for s in SIDES])
        self.leg_dof = np.array([[self.dof_adr[f"{j}_{s}"] for j in JOINTS] for s in SIDES])
        self.pd_act = np.array([[self.act[f"pd_{j}_{s}"] for j in JOINTS] for s in SIDES])
        self.ff_act = np.array([[self.act[f"ff_{j}_{s}"] for j in JOINTS] for s in SIDES])
        self.residual_act = np.array([self.act[f"residual_{d}"] for d in ("tx", "tz", "tilt")])
        self.pelvis_qpos = np.array([self.qpos_adr[f"pelvis_{d}"] for d in ("tx", "tz", "tilt")])
        self.pelvis_dof = np.array([self.dof_adr[f"pelvis_{d}"] for d in ("tx", "tz", "tilt")])
        gid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)  # noqa: E731
        self.contact_geoms = np.array([[gid(f"{p}_{s}") for p in ("heel", "ball")] for s in SIDES])
        self.floor_geom = gid("floor")
        self.touch_adr = np.array([[m.sensor_adr[mujoco.mj_name2id(
            m, mujoco.mjtObj.mjOBJ_SENSOR, f"touch_{p}_{s}")] for p in ("heel", "ball")]
            for s in SIDES])
        #: sensordata addresses of the (x, y, z) foot-on-floor force per side
        self.foot_force_adr = np.array([m.sensor_adr[mujoco.mj_name2id(
            m, mujoco.mjtObj.mjOBJ_SENSOR, f"foot_floor_force_{s}")] for s in SIDES])
        self.body_mass_kg = float(m.body_subtreemass[0])
        #: height of the pelvis (hip centre) frame when ``pelvis_tz`` is 0
        self.pelvis_height_offset_m = float(
            m.body_pos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis"), 2])
        self.foot_body = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"foot_{s}")
                                   for s in SIDES])
        self.contact_radius_m = float(m.geom_size[self.contact_geoms[0, 0], 0])
        ankle_lim = np.array([m.jnt_actfrcrange[jid(f"ankle_{s}")] for s in SIDES])
        self.ankle_torque_limits_nm = ankle_lim
        self.ankle_joint = np.array([jid(f"ankle_{s}") for s in SIDES])

    # -- named accessors (allocation-free views) ------------------------------------------
    def leg_angles_rad(self) -> np.ndarray:
        """(2, 3) joint angles [r/l][hip, knee, ankle], clinical sign."""
        return self.data.qpos[self.leg_qpos]

    def leg_velocities_rad_s(self) -> np.ndarray:
        return self.data.qvel[self.leg_dof]

    def leg_actuator_torques_nm(self) -> np.ndarray:
        """(2, 3) net human actuator torque per joint, after the strength clamp."""
        return self.data.qfrc_actuator[self.leg_dof]

    def contact_point_heights_m(self) -> np.ndarray:
        """(2, 2) lowest point of the heel and ball spheres above the floor [r/l][heel, ball]."""
        return self.data.geom_xpos[self.contact_geoms, 2] - self.contact_radius_m

    def ground_reaction_forces_n(self) -> np.ndarray:
        """(2, 2) ground reaction force on each foot, world [x, z] (after mj_forward/mj_step)."""
        adr = self.foot_force_adr
        return -self.data.sensordata[np.stack([adr, adr + 2], axis=1)]

    def contact_normal_forces_n(self) -> np.ndarray:
        """(2, 2) normal contact force on heel and ball spheres (touch sensors)."""
        return self.data.sensordata[self.touch_adr]
