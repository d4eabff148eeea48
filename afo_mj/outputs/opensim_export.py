"""A simulated walk written as OpenSim storage files, so OpenSim and its users' tools read it.

OpenSim storage format (``.sto``/``.mot``, version 1): a header of ``key=value`` lines ended by
``endheader``, a tab-separated label line, then one tab-separated row per sample
(:func:`afo_mj.gait.reference.read_opensim_storage` reads it back). :func:`write_opensim`
writes three files for a :class:`~afo_mj.gait.record.GaitRecord`:

* ``<name>_ik.mot`` — coordinates in degrees (``inDegrees=yes``), OpenSim names and signs of
  the Rajagopal 2015 model: ``pelvis_tilt`` (+ posterior tilt: the negative of the walker's
  forward lean), ``pelvis_tx``/``pelvis_ty`` (m, the walker's hip centre), ``hip_flexion_r/l``
  (+ flexion), ``knee_angle_r/l`` (+ flexion, Rajagopal's sign; gait2392 negates it),
  ``ankle_angle_r/l`` (+ dorsiflexion);
* ``<name>_id.sto`` — the joint moments along those coordinates (N·m, the human's; the
  orthosis's ankle torque in ``ankle_angle_r/l_device_moment``), as OpenSim's inverse
  dynamics names them (``<coordinate>_moment``);
* ``<name>_grf.mot`` — each foot's ground reaction force (N): ``ground_force_r_vx`` (forward),
  ``_vy`` (up), ``_vz`` (0, the walk is planar), likewise ``_l``. The record holds no centre of
  pressure, so no ``_p*`` columns are written (an OpenSim ExternalLoads file needs them).

Every file's header carries ``source=afo_mj`` and the conventions above in a ``comment`` line.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

__all__ = ["write_storage", "write_opensim"]


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
    """Write ``<name>_ik.mot``, ``<name>_id.sto`` and ``<name>_grf.mot`` of a gait record into
    ``out_dir`` (module docstring); returns their paths by kind."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = np.asarray(record.time_s, float)
    deg = 180.0 / math.pi
    ang = record.joint_angle_rad
    ik_cols = {"time": t, "pelvis_tilt": -deg * record.pelvis_tilt_rad,
               "pelvis_tx": record.pelvis_position_m[:, 0],
               "pelvis_ty": record.pelvis_position_m[:, 1]}
    id_cols = {"time": t}
    for s, sfx in ((0, "r"), (1, "l")):
        for j, coord in enumerate(("hip_flexion", "knee_angle", "ankle_angle")):
            ik_cols[f"{coord}_{sfx}"] = deg * ang[:, s, j]
            id_cols[f"{coord}_{sfx}_moment"] = record.joint_moment_nm[:, s, j]
        id_cols[f"ankle_angle_{sfx}_device_moment"] = record.device_moment_nm[:, s]
    grf_cols = {"time": t}
    for s, sfx in ((0, "r"), (1, "l")):
        grf_cols[f"ground_force_{sfx}_vx"] = record.grf_n[:, s, 0]
        grf_cols[f"ground_force_{sfx}_vy"] = record.grf_n[:, s, 1]
        grf_cols[f"ground_force_{sfx}_vz"] = np.zeros_like(t)
    conv = ("Rajagopal2015 signs: knee + flexion; pelvis_tilt + posterior (the walker's "
            "forward lean negated); pelvis_tx/ty the hip centre")
    paths = {}
    for kind, cols, ext, in_deg, note in (
            ("ik", ik_cols, "mot", True, conv),
            ("id", id_cols, "sto", False, "joint moments N*m along the coordinates; "
                                            "device_moment is the orthosis's ankle torque"),
            ("grf", grf_cols, "mot", False, "ground reaction force per foot, N; planar walk "
                                             "(vz = 0); no centre of pressure recorded")):
        paths[kind] = write_storage(out / f"{name}_{kind}.{ext}", list(cols),
                                    np.column_stack(list(cols.values())),
                                    name=f"{name}_{kind}", in_degrees=in_deg, comment=note)
    return paths
