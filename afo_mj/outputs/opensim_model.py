"""The walker as an OpenSim model (``.osim``, OpenSim 4.x document), read from its compiled MuJoCo
model, so OpenSim's tools (inverse dynamics, analyses, the GUI) run on the body that walked.

Everything physical is read from the compiled ``mujoco.MjModel`` (``body_mass``,
``body_inertia``/``body_iquat``, ``body_ipos``, the bodies' and joints' poses by forward
kinematics at ``qpos0``, ``jnt_axis``, ``jnt_range``, ``opt.gravity``); only the names are
mapped. Conventions are those of the storage files of :mod:`afo_mj.outputs.opensim_export`:

* axes: OpenSim's ground X forward = MuJoCo x, Y up = MuJoCo z, Z to the right = −MuJoCo y
  (the linear map :data:`_P`, a proper rotation, so inertia tensors map as ``P·I·Pᵀ``);
* bodies: ``pelvis`` (the walker's HAT: head, arms, trunk and pelvis), ``femur_r/l``
  (``thigh_*``), ``tibia_r/l`` (``shank_*``), ``calcn_r/l`` (``foot_*``; the ``ExternalLoads``
  of the ground reaction apply to these). A body without a joint (a worn mass: a device part,
  a battery) is welded to its moving ancestor, as it is in MuJoCo: its mass is added to that
  body and its inertia moved to their common centre of mass by the parallel-axis theorem
  ``I = Σ (I_i + m_i (|d_i|² 1 − d_i d_iᵀ))``, ``d_i`` from the common centre to body i's;
* joints: ``ground_pelvis``, a ``PlanarJoint`` (coordinates ``pelvis_tilt`` about +Z,
  ``pelvis_tx``, ``pelvis_ty`` along ground X, Y) in place of MuJoCo's slide-x, slide-z,
  hinge-y; as in the ``_ik.mot`` file, ``pelvis_tilt`` is the walker's forward lean negated
  (MuJoCo's hinge axis +y is OpenSim's −Z) and ``pelvis_ty`` the hip centre's height (the
  pelvis body's rest height is folded into the coordinate, not the joint's parent frame).
  ``hip_r``/``knee_r``/``ankle_r`` (and ``_l``) are PinJoints whose frames' Z is the
  MuJoCo hinge axis, so the coordinates ``hip_flexion_*``, ``knee_angle_*``, ``ankle_angle_*``
  equal the walker's angles (+ flexion, + knee flexion, + dorsiflexion), ranges from
  ``jnt_range`` (not clamped: a recorded motion is never altered);
* contact geometry (for display; no force uses it): a ``ContactHalfSpace`` floor on ground and
  a ``ContactSphere`` per MuJoCo contact sphere (``heel_*``, ``ball_*``) on its foot.

No muscles, actuators or passive forces: the model is for inverse dynamics (net joint moments)
and kinematics. A MuJoCo model that is not the planar walker's layout (other root joints, a
hinge that is not about the lateral axis, a missing segment) is refused naming what differs.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

__all__ = ["osim_model_xml", "write_osim_model", "OSIM_BODIES", "OSIM_COORDINATES",
           "OpenSimModelError"]

#: MuJoCo axes → OpenSim axes (X forward = x, Y up = z, Z right = −y); det = +1
_P = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

#: MuJoCo body → OpenSim body (Rajagopal 2015 names)
OSIM_BODIES = {"pelvis": "pelvis",
               **{f"{mj}_{s}": f"{os_}_{s}" for s in ("r", "l")
                  for mj, os_ in (("thigh", "femur"), ("shank", "tibia"), ("foot", "calcn"))}}

#: MuJoCo leg hinge → (OpenSim joint, coordinate)
_LEG_JOINTS = {f"{j}_{s}": (f"{j}_{s}", f"{c}_{s}") for s in ("r", "l")
               for j, c in (("hip", "hip_flexion"), ("knee", "knee_angle"),
                            ("ankle", "ankle_angle"))}

#: the model's coordinates, in the ``_ik.mot`` file's column order
OSIM_COORDINATES = ("pelvis_tilt", "pelvis_tx", "pelvis_ty",
                    *(c for s in ("r", "l") for c in (f"hip_flexion_{s}", f"knee_angle_{s}",
                                                      f"ankle_angle_{s}")))


class OpenSimModelError(ValueError):
    """The MuJoCo model cannot be written as the planar OpenSim walker."""


def _euler_xyz(R: np.ndarray) -> np.ndarray:
    """Body-fixed X-Y-Z Euler angles (OpenSim's ``orientation``) of a rotation matrix
    ``R = Rx(a)·Ry(b)·Rz(c)``: ``sin b = R[0,2]``, ``tan a = −R[1,2]/R[2,2]``,
    ``tan c = −R[0,1]/R[0,0]`` (away from the gimbal lock |b| = π/2, which a frame built by
    :func:`_frame_with_z` for a lateral hinge never reaches)."""
    b = math.asin(max(-1.0, min(1.0, R[0, 2])))
    a = math.atan2(-R[1, 2], R[2, 2])
    c = math.atan2(-R[0, 1], R[0, 0])
    return np.array([a, b, c])


def _frame_with_z(u: np.ndarray) -> np.ndarray:
    """A right-handed orthonormal frame (columns X, Y, Z) whose Z is the unit vector ``u``."""
    u = u / np.linalg.norm(u)
    e = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = e - (e @ u) * u
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(u, x), u])


def _vec(v) -> str:
    return " ".join(f"{float(x):.12g}" for x in v)


def _compile(model_or_xml):
    import mujoco
    if isinstance(model_or_xml, mujoco.MjModel):
        return model_or_xml
    if isinstance(model_or_xml, str):
        return mujoco.MjModel.from_xml_string(model_or_xml)
    raise OpenSimModelError(f"model = {type(model_or_xml).__name__}; allowed: a mujoco.MjModel "
                            "or its MJCF text (a GaitRecord's model_xml)")


def _segments(m, d):
    """``{MuJoCo moving body id: (mass, com in its frame, inertia about the com in its frame)}``
    with every welded (jointless) body merged in (module docstring; MuJoCo axes)."""
    out = {}
    for b in range(1, m.nbody):
        if m.body_jntnum[b] > 0:
            out[b] = []
    for b in range(1, m.nbody):
        w = int(m.body_weldid[b])
        if w == 0:
            continue                          # welded to the world: not part of the walker
        if w not in out:
            raise OpenSimModelError(f"body {m.body(b).name!r} is welded to "
                                    f"{m.body(w).name!r}, which has no joint")
        out[w].append(b)
    seg = {}
    for w, members in out.items():
        mass = np.array([m.body_mass[b] for b in members])
        com_w = np.array([d.xipos[b] for b in members])
        total = float(mass.sum())
        if total <= 0:
            raise OpenSimModelError(f"body {m.body(w).name!r}: mass = {total}; allowed: > 0")
        c = (mass[:, None] * com_w).sum(axis=0) / total
        inertia = np.zeros((3, 3))
        for b, mb, x in zip(members, mass, com_w):
            R = d.ximat[b].reshape(3, 3)       # principal axes of body b, world
            dv = x - c
            inertia += R @ np.diag(m.body_inertia[b]) @ R.T
            inertia += mb * ((dv @ dv) * np.eye(3) - np.outer(dv, dv))
        Rw = d.xmat[w].reshape(3, 3)
        seg[w] = (total, Rw.T @ (c - d.xpos[w]), Rw.T @ inertia @ Rw)
    return seg


def osim_model_xml(model_or_xml, name: str = "afo_mj_walker") -> str:
    """The OpenSim 4 model document (text) of the walker's compiled MuJoCo model (or its MJCF
    text): bodies, joints, coordinates and contact geometry as the module docstring says."""
    import mujoco
    m = _compile(model_or_xml)
    if "<" in name or "&" in name or '"' in name:
        raise OpenSimModelError(f"name = {name!r}; allowed: text without <, & or \"")
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    mujoco.mj_kinematics(m, d)
    bid = {m.body(b).name: b for b in range(m.nbody)}
    missing = [b for b in OSIM_BODIES if b not in bid]
    if missing:
        raise OpenSimModelError(f"the MuJoCo model lacks the bodies {missing}; allowed: the "
                                "walker's (afo_mj.human.walker.build_walker)")
    seg = _segments(m, d)
    moving = {m.body(b).name for b in seg}
    extra = sorted(moving - set(OSIM_BODIES))
    if extra:
        raise OpenSimModelError(f"the MuJoCo model has moving bodies {extra} that the planar "
                                f"walker has not; allowed: {sorted(OSIM_BODIES)}")

    def rot(b):                                # body b's orientation in OpenSim axes
        return _P @ d.xmat[b].reshape(3, 3) @ _P.T

    bodies = []
    for mj_name, os_name in OSIM_BODIES.items():
        mass, com, inertia = seg[bid[mj_name]]
        I = _P @ inertia @ _P.T
        bodies.append(f"""
\t\t\t\t<Body name="{os_name}">
\t\t\t\t\t<mass>{mass:.12g}</mass>
\t\t\t\t\t<mass_center>{_vec(_P @ com)}</mass_center>
\t\t\t\t\t<inertia>{_vec([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}</inertia>
\t\t\t\t</Body>""")

    def frame(fname, parent_path, translation, R):
        return f"""
\t\t\t\t\t\t<PhysicalOffsetFrame name="{fname}">
\t\t\t\t\t\t\t<socket_parent>{parent_path}</socket_parent>
\t\t\t\t\t\t\t<translation>{_vec(translation)}</translation>
\t\t\t\t\t\t\t<orientation>{_vec(_euler_xyz(R))}</orientation>
\t\t\t\t\t\t</PhysicalOffsetFrame>"""

    def coordinate(cname, default, rng):
        r = "" if rng is None else f"\n\t\t\t\t\t\t\t<range>{_vec(rng)}</range>"
        return f"""
\t\t\t\t\t\t<Coordinate name="{cname}">
\t\t\t\t\t\t\t<default_value>{default:.12g}</default_value>{r}
\t\t\t\t\t\t\t<clamped>false</clamped>
\t\t\t\t\t\t\t<locked>false</locked>
\t\t\t\t\t\t</Coordinate>"""

    # --- the pelvis: MuJoCo slide x, slide z, hinge y at the body origin → PlanarJoint
    pel = bid["pelvis"]
    jn = {m.joint(j).name: j for j in range(m.njnt)}
    want = {"pelvis_tx": (mujoco.mjtJoint.mjJNT_SLIDE, (1, 0, 0)),
            "pelvis_tz": (mujoco.mjtJoint.mjJNT_SLIDE, (0, 0, 1)),
            "pelvis_tilt": (mujoco.mjtJoint.mjJNT_HINGE, (0, 1, 0))}
    for jname, (jtype, axis) in want.items():
        kind = "slide" if jtype == mujoco.mjtJoint.mjJNT_SLIDE else "hinge"
        j = jn.get(jname)
        if (j is None or m.jnt_bodyid[j] != pel or m.jnt_type[j] != jtype
                or not np.allclose(d.xaxis[j], axis, atol=1e-9)
                or not np.allclose(m.jnt_pos[j], 0.0, atol=1e-12)):
            raise OpenSimModelError(f"joint {jname!r}: the pelvis needs a {kind} joint "
                                    f"along world {axis} at its origin (the planar walker's); "
                                    "allowed: the walker's model")
    if m.body_jntnum[pel] != 3 or m.body_parentid[pel] != 0:
        raise OpenSimModelError("body 'pelvis': needs exactly the three planar joints and the "
                                "world as parent; allowed: the walker's model")
    if not np.allclose(d.xmat[pel], np.eye(3).ravel(), atol=1e-12):
        raise OpenSimModelError("body 'pelvis': rotated at rest; allowed: upright (identity)")
    rest = _P @ d.xpos[pel]                      # OpenSim axes; Y (the height) goes into ty
    tilt = jn["pelvis_tilt"]
    joints = [f"""
\t\t\t\t<PlanarJoint name="ground_pelvis">
\t\t\t\t\t<socket_parent_frame>ground_offset</socket_parent_frame>
\t\t\t\t\t<socket_child_frame>pelvis_offset</socket_child_frame>
\t\t\t\t\t<coordinates>{coordinate("pelvis_tilt", -m.qpos0[m.jnt_qposadr[tilt]], None)}
{coordinate("pelvis_tx", m.qpos0[m.jnt_qposadr[jn["pelvis_tx"]]], None)}
{coordinate("pelvis_ty", rest[1] + m.qpos0[m.jnt_qposadr[jn["pelvis_tz"]]], None)}
\t\t\t\t\t</coordinates>
\t\t\t\t\t<frames>{frame("ground_offset", "/ground", [rest[0], 0.0, rest[2]], np.eye(3))}
{frame("pelvis_offset", "/bodyset/pelvis", np.zeros(3), np.eye(3))}
\t\t\t\t\t</frames>
\t\t\t\t</PlanarJoint>"""]
    # --- leg hinges → PinJoints whose frames' Z is the hinge axis
    for mj_joint, (os_joint, cname) in _LEG_JOINTS.items():
        j = jn.get(mj_joint)
        if j is None or m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            raise OpenSimModelError(f"joint {mj_joint!r}: missing or not a hinge; allowed: the "
                                    "walker's model")
        child = int(m.jnt_bodyid[j])
        parent = int(m.body_weldid[m.body_parentid[child]])
        if m.body_jntnum[child] != 1 or parent not in seg:
            raise OpenSimModelError(f"joint {mj_joint!r}: its body {m.body(child).name!r} "
                                    "needs exactly one joint and a moving parent")
        axis_w = _P @ d.xaxis[j]
        if abs(axis_w[2]) < 1.0 - 1e-9:
            raise OpenSimModelError(f"joint {mj_joint!r}: axis {d.xaxis[j].tolist()} at rest is "
                                    "not the lateral axis (±y); allowed: a sagittal-plane hinge")
        RJ = _frame_with_z(axis_w)
        anchor = _P @ d.xanchor[j]
        pname, cname_b = OSIM_BODIES[m.body(parent).name], OSIM_BODIES[m.body(child).name]
        rng = m.jnt_range[j] if m.jnt_limited[j] else None
        frames = []
        for tag, b, bname in (("parent", parent, pname), ("child", child, cname_b)):
            Rb = rot(b)
            frames.append(frame(f"{bname}_{os_joint}_{tag}", f"/bodyset/{bname}",
                                Rb.T @ (anchor - _P @ d.xpos[b]), Rb.T @ RJ))
        joints.append(f"""
\t\t\t\t<PinJoint name="{os_joint}">
\t\t\t\t\t<socket_parent_frame>{pname}_{os_joint}_parent</socket_parent_frame>
\t\t\t\t\t<socket_child_frame>{cname_b}_{os_joint}_child</socket_child_frame>
\t\t\t\t\t<coordinates>{coordinate(cname, m.qpos0[m.jnt_qposadr[j]], rng)}
\t\t\t\t\t</coordinates>
\t\t\t\t\t<frames>{''.join(frames)}
\t\t\t\t\t</frames>
\t\t\t\t</PinJoint>""")
    # --- contact geometry (display only): each foot's contact spheres and the floor
    contacts = []
    for g in range(m.ngeom):
        b = int(m.body_weldid[m.geom_bodyid[g]])
        if (m.geom_type[g] != mujoco.mjtGeom.mjGEOM_SPHERE or b not in seg
                or m.geom_contype[g] == 0):
            continue
        bname = OSIM_BODIES[m.body(b).name]
        Rb = rot(b)
        loc = Rb.T @ (_P @ d.geom_xpos[g] - _P @ d.xpos[b])
        contacts.append(f"""
\t\t\t\t<ContactSphere name="{m.geom(g).name}">
\t\t\t\t\t<socket_frame>/bodyset/{bname}</socket_frame>
\t\t\t\t\t<location>{_vec(loc)}</location>
\t\t\t\t\t<orientation>0 0 0</orientation>
\t\t\t\t\t<radius>{m.geom_size[g, 0]:.12g}</radius>
\t\t\t\t</ContactSphere>""")
    g = _P @ m.opt.gravity
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40600">
\t<Model name="{name}">
\t\t<credits>afo_mj.human.walker, read from its compiled MuJoCo model</credits>
\t\t<length_units>meters</length_units>
\t\t<force_units>N</force_units>
\t\t<gravity>{_vec(g)}</gravity>
\t\t<Ground name="ground" />
\t\t<BodySet name="bodyset">
\t\t\t<objects>{''.join(bodies)}
\t\t\t</objects>
\t\t\t<groups />
\t\t</BodySet>
\t\t<JointSet name="jointset">
\t\t\t<objects>{''.join(joints)}
\t\t\t</objects>
\t\t\t<groups />
\t\t</JointSet>
\t\t<ContactGeometrySet name="contactgeometryset">
\t\t\t<objects>
\t\t\t\t<ContactHalfSpace name="floor">
\t\t\t\t\t<socket_frame>/ground</socket_frame>
\t\t\t\t\t<location>0 0 0</location>
\t\t\t\t\t<orientation>0 0 {-math.pi / 2:.12g}</orientation>
\t\t\t\t</ContactHalfSpace>{''.join(contacts)}
\t\t\t</objects>
\t\t\t<groups />
\t\t</ContactGeometrySet>
\t</Model>
</OpenSimDocument>
"""


def write_osim_model(model_or_xml, path, name: str = "afo_mj_walker") -> Path:
    """Write :func:`osim_model_xml` to ``path`` (atomically: a temporary file renamed into
    place); returns the path."""
    text = osim_model_xml(model_or_xml, name)
    p = Path(path)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, p)
    return p
