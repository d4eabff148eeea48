"""A simulated walk written as OpenSim storage files, so OpenSim and its users' tools read it.

OpenSim storage format (``.sto``/``.mot``, version 1): a header of ``key=value`` lines ended by
``endheader``, a tab-separated label line, then one tab-separated row per sample
(:func:`afo_mj.gait.reference.read_opensim_storage` reads it back). :func:`write_opensim`
writes five files for a :class:`~afo_mj.gait.record.GaitRecord`:

* ``<name>_ik.mot`` — coordinates in degrees (``inDegrees=yes``), OpenSim names and signs of
  the Rajagopal 2015 model: ``pelvis_tilt`` (+ posterior tilt: the negative of the walker's
  forward lean), ``pelvis_tx``/``pelvis_ty`` (m, the walker's hip centre), ``hip_flexion_r/l``
  (+ flexion), ``knee_angle_r/l`` (+ flexion, Rajagopal's sign; gait2392 negates it),
  ``ankle_angle_r/l`` (+ dorsiflexion);
* ``<name>_id.sto`` — the joint moments along those coordinates (N·m, the human's; the
  orthosis's ankle torque in ``ankle_angle_r/l_device_moment``), as OpenSim's inverse
  dynamics names them (``<coordinate>_moment``);
* ``<name>_grf.mot`` — each foot's ground reaction force in OpenSim's external-loads layout
  (the Rajagopal 2015 / gait10dof18musc column names), SI units, in OpenSim's ground frame
  (X forward = the walker's x, Y up = its z, Z to the right = minus its y):
  ``ground_force_r_vx, _vy, _vz`` the force (N; ``_vz`` is 0, the walk is planar),
  ``ground_force_r_px, _py, _pz`` the centre of pressure (m) and ``ground_torque_r_x, _y, _z``
  the free torque (N·m), likewise ``_l`` (:func:`foot_centre_of_pressure_m`);
* ``<name>_grf.xml`` — the OpenSim ``ExternalLoads`` that names those columns per foot
  (applied to ``calcn_r``/``calcn_l``, force and point expressed in ``ground``), for OpenSim's
  inverse dynamics tool;
* ``<name>.osim`` — the walker as an OpenSim model (below).

Centre of pressure (CoP). A foot touches the floor only through its heel and ball spheres; on a
flat floor each contact is a point force at the sphere's lowest point, directly below its centre
on the floor plane (z = 0, within the penetration of a few mm). The CoP is the point of the floor
about which the moment of the foot's contact forces has no horizontal component:
``Σ_i (x_i − x_cop) N_i = 0`` with ``N_i`` the normal (vertical) force of contact ``i``, so
``x_cop = Σ_i N_i x_i / Σ_i N_i`` (likewise for the lateral position); the tangential (friction)
forces act in the floor plane and have no moment about a point on it, so the CoP carries them.
The free torque is the remaining moment about the vertical through the CoP: zero in the planar
walk (no transverse rotation, contacts on the sagittal line), so ``ground_torque_*`` is 0. A
foot carrying no load (``Σ N_i = 0``) has force 0 and its CoP written as 0 (OpenSim's convention:
with no force, the point is arbitrary). The normal forces are the record's touch sensors
(``contact_force_n``), the contact positions the heel and ball geoms' world positions by forward
kinematics of the record's ``qpos`` on its ``model_xml`` (of the state the forces were computed
at, see Timing).

Timing. A record's row ``k`` holds the state *after* MuJoCo step ``k`` (``time_s[k]``, ``qpos``)
but the forces of that step (joint moments, device torque, contact forces, residuals), which
``mj_step`` computes from the state *before* it, i.e. that of row ``k − 1``, and then holds
over the step (a semi-implicit Euler step: ``q̇ₖ = q̇ₖ₋₁ + h·q̈(state ₖ₋₁)``). Inverse dynamics
on the coordinates finds the acceleration at ``time_s[k − 1]`` from them, so the force files
(``_id.sto``, ``_grf.mot``) write row ``k``'s forces at ``time_s[k − 1]`` (and its centre of
pressure from row ``k − 1``'s positions): they have one row fewer than ``_ik.mot`` (the forces
of the first row belong to a state before the record) and share its time grid. Written at
``time_s[k]`` instead, they would lag the motion by one step, which at a heel strike (the force
rising by hundreds of newtons within a step) is a large error: OpenSim's inverse dynamics on
the walk then misses our hip moment by 8 % of its peak (RMS) instead of 2 %
(``tests/test_opensim_roundtrip.py``). This needs one row per MuJoCo step
(``sample_period_s`` equal to the model's time step), which every walk records; a record that
is not is refused.

Model. ``<name>.osim`` is the walker of the record as an OpenSim model
(:mod:`afo_mj.outputs.opensim_model`): with the three files, OpenSim's inverse dynamics tool
reproduces the ``_id.sto`` moments (README: OpenSim).

Every file's header holds ``key=value`` lines only (OpenSim's reader splits each on ``=``):
``source=afo_mj`` and the conventions above in a ``comment`` line whose text has no ``=``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

__all__ = ["write_storage", "write_opensim", "foot_centre_of_pressure_m",
           "write_external_loads_xml"]

#: the feet in OpenSim's suffixes, in the record's side order, and the body each loads
_FEET = (("r", "calcn_r"), ("l", "calcn_l"))


def write_storage(path, labels, data, *, name: str, in_degrees: bool, comment: str = "") -> Path:
    """Write one OpenSim storage file (atomically: a temporary file renamed into place).
    ``data`` (rows × len(labels)) must be finite; the first label must be ``time``."""
    data = np.asarray(data, float)
    labels = list(labels)
    if labels[0] != "time" or data.ndim != 2 or data.shape[1] != len(labels):
        raise ValueError(f"write_storage: labels {labels[:3]}… and data {data.shape}; allowed: "
                         "'time' first and one column per label")
    if not np.all(np.isfinite(data)):
        bad = labels[int(np.flatnonzero(~np.all(np.isfinite(data), axis=0))[0])]
        raise ValueError(f"write_storage: column {bad!r} has non-finite values")
    for key, text in (("name", name), ("comment", comment)):
        if "=" in text or "\n" in text or "\r" in text:
            raise ValueError(f"write_storage: {key} = {text!r} holds '=' or a line break; "
                             "allowed: one line without '=' (OpenSim splits header lines on "
                             "'=')")
    lines = [name, "version=1", f"nRows={data.shape[0]}", f"nColumns={data.shape[1]}",
             f"inDegrees={'yes' if in_degrees else 'no'}", "source=afo_mj"]
    if comment:
        lines.append(f"comment={comment}")
    lines += ["endheader", "\t".join(labels)]
    lines += ["\t".join(f"{v:.10g}" for v in row) for row in data]
    p = Path(path)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    os.replace(tmp, p)
    return p


def write_opensim(record, out_dir, name: str = "run") -> dict[str, Path]:
    """Write ``<name>_ik.mot``, ``<name>_id.sto``, ``<name>_grf.mot``, ``<name>_grf.xml`` and
    ``<name>.osim`` of a gait record into ``out_dir`` (module docstring: the force files one
    step earlier than the row they are kept in); returns their paths by kind (``ik``, ``id``,
    ``grf``, ``grf_xml``, ``model``)."""
    from afo_mj.outputs.opensim_model import write_osim_model
    model = _record_model(record, "write_opensim")
    t = np.asarray(record.time_s, float)
    h = float(record.sample_period_s)
    if t.size < 2 or abs(model.opt.timestep - h) > 1e-12 * max(1.0, h) or not np.allclose(
            np.diff(t), h, rtol=0.0, atol=1e-9):
        raise ValueError(f"write_opensim: record.sample_period_s = {h} with {t.size} rows and "
                         f"the model's time step {model.opt.timestep}; allowed: two or more "
                         "rows, one per MuJoCo step (the force files are written one step "
                         "earlier than their row)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    deg = 180.0 / math.pi
    ang = record.joint_angle_rad
    ik_cols = {"time": t, "pelvis_tilt": -deg * record.pelvis_tilt_rad,
               "pelvis_tx": record.pelvis_position_m[:, 0],
               "pelvis_ty": record.pelvis_position_m[:, 1]}
    f = slice(1, None)                  # force rows 1…n−1, at the times of rows 0…n−2
    tf = t[:-1]
    id_cols = {"time": tf}
    for s, sfx in ((0, "r"), (1, "l")):
        for j, coord in enumerate(("hip_flexion", "knee_angle", "ankle_angle")):
            ik_cols[f"{coord}_{sfx}"] = deg * ang[:, s, j]
            id_cols[f"{coord}_{sfx}_moment"] = record.joint_moment_nm[f, s, j]
        id_cols[f"ankle_angle_{sfx}_device_moment"] = record.device_moment_nm[f, s]
    cop = foot_centre_of_pressure_m(record, model)[f]
    zero = np.zeros_like(tf)
    grf_cols = {"time": tf}
    for s, (sfx, _) in enumerate(_FEET):
        grf_cols[f"ground_force_{sfx}_vx"] = record.grf_n[f, s, 0]
        grf_cols[f"ground_force_{sfx}_vy"] = record.grf_n[f, s, 1]
        grf_cols[f"ground_force_{sfx}_vz"] = zero
        for a, axis in enumerate("xyz"):
            grf_cols[f"ground_force_{sfx}_p{axis}"] = cop[:, s, a]
        for axis in "xyz":
            grf_cols[f"ground_torque_{sfx}_{axis}"] = zero
    conv = ("Rajagopal2015 signs: knee + flexion; pelvis_tilt + posterior (the walker's "
            "forward lean negated); pelvis_tx/ty the hip centre")
    step = ("; each row holds the forces MuJoCo computed at this time and held over the "
            "step that follows")
    paths = {}
    for kind, cols, ext, in_deg, note in (
            ("ik", ik_cols, "mot", True, conv),
            ("id", id_cols, "sto", False, "joint moments N*m along the coordinates; "
                                            "device_moment is the orthosis's ankle torque"
                                            + step),
            ("grf", grf_cols, "mot", False, "ground reaction force per foot N, centre of "
                                             "pressure m and free torque N*m in OpenSim ground "
                                             "axes (X forward, Y up, Z right); planar walk: vz "
                                             "and torques are 0; unloaded foot: point 0"
                                             + step)):
        paths[kind] = write_storage(out / f"{name}_{kind}.{ext}", list(cols),
                                    np.column_stack(list(cols.values())),
                                    name=f"{name}_{kind}", in_degrees=in_deg, comment=note)
    paths["grf_xml"] = write_external_loads_xml(out / f"{name}_grf.xml", paths["grf"].name,
                                                name=f"{name}_grf")
    paths["model"] = write_osim_model(model, out / f"{name}.osim", name=name)
    return paths


def _record_model(record, who: str):
    """The compiled MuJoCo model of ``record.model_xml`` (ValueError naming ``who`` when the
    record kept no model or positions)."""
    import mujoco
    if record.qpos is None or record.model_xml is None:
        raise ValueError(f"{who}: record.qpos / record.model_xml = None; allowed: a record "
                         "that kept its qpos and model (the centre of pressure and the OpenSim "
                         "model need them)")
    return mujoco.MjModel.from_xml_string(record.model_xml)


def foot_centre_of_pressure_m(record, model=None) -> np.ndarray:
    """(n, 2, 3) centre of pressure of each foot [r/l] in OpenSim's ground axes (X forward,
    Y up, Z right; m): the normal-force-weighted mean of the heel and ball contact points on the
    floor (module docstring), ``Y = 0``; 0 where the foot carries no load. Row ``k``'s normal
    forces act at the contact points of the state they were computed at, row ``k − 1``'s
    (module docstring, Timing; row 0, whose state is not recorded, uses its own): the points
    come from forward kinematics (``mujoco.mj_kinematics``) of ``record.qpos`` on
    ``record.model_xml`` (or ``model``, its compiled form)."""
    import mujoco
    if model is None:
        model = _record_model(record, "foot_centre_of_pressure_m")
    elif record.qpos is None:
        raise ValueError("foot_centre_of_pressure_m: record.qpos = None; allowed: a record "
                         "that kept its qpos")
    data = mujoco.MjData(model)
    gid = np.array([[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{part}_{sfx}")
                     for part in ("heel", "ball")] for sfx, _ in _FEET])
    if np.any(gid < 0):
        raise ValueError("foot_centre_of_pressure_m: record.model_xml lacks a heel_/ball_ "
                         "geom; allowed: the walker's model (heel_r, ball_r, heel_l, ball_l)")
    qpos = np.asarray(record.qpos, float)
    n = qpos.shape[0]
    xy = np.empty((n, 2, 2, 2))                  # [sample][side][heel, ball][x, y]
    for k in range(n):
        data.qpos[:] = qpos[max(k - 1, 0)]
        mujoco.mj_kinematics(model, data)
        xy[k] = data.geom_xpos[gid, :2]
    normal = np.clip(np.asarray(record.contact_force_n, float), 0.0, None)    # (n, 2, 2)
    load = normal.sum(axis=2)
    loaded = load > 0.0
    w = np.divide(normal, load[..., None], out=np.zeros_like(normal), where=loaded[..., None])
    cop = np.zeros((n, 2, 3))
    cop[..., 0] = np.sum(w * xy[..., 0], axis=2)
    cop[..., 2] = -np.sum(w * xy[..., 1], axis=2)        # OpenSim Z (right) = −MuJoCo y
    return cop


def write_external_loads_xml(path, datafile: str, *, name: str = "externalloads") -> Path:
    """Write OpenSim's ``ExternalLoads`` (XML, OpenSim 4 document) for a ``_grf.mot`` written
    by :func:`write_opensim`: one ``ExternalForce`` per foot applied to ``calcn_r``/``calcn_l``,
    force and point expressed in ``ground``, identifiers ``ground_force_<s>_v``,
    ``ground_force_<s>_p`` and ``ground_torque_<s>_`` (OpenSim appends x, y, z), the data file
    ``datafile`` (relative to the XML's folder)."""
    forces = "".join(f"""
\t\t\t<ExternalForce name="{sfx}_foot_ground_reaction">
\t\t\t\t<applied_to_body>{body}</applied_to_body>
\t\t\t\t<force_expressed_in_body>ground</force_expressed_in_body>
\t\t\t\t<point_expressed_in_body>ground</point_expressed_in_body>
\t\t\t\t<force_identifier>ground_force_{sfx}_v</force_identifier>
\t\t\t\t<point_identifier>ground_force_{sfx}_p</point_identifier>
\t\t\t\t<torque_identifier>ground_torque_{sfx}_</torque_identifier>
\t\t\t\t<data_source_name>Unassigned</data_source_name>
\t\t\t</ExternalForce>""" for sfx, body in _FEET)
    text = (f'<?xml version="1.0" encoding="UTF-8" ?>\n<OpenSimDocument Version="40000">\n'
            f'\t<ExternalLoads name="{name}">\n\t\t<objects>{forces}\n\t\t</objects>\n'
            f'\t\t<groups />\n\t\t<datafile>{datafile}</datafile>\n\t</ExternalLoads>\n'
            f'</OpenSimDocument>\n')
    p = Path(path)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, p)
    return p
