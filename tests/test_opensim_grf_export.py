"""The GRF export in OpenSim's external-loads layout (issue 43 item 2): per foot force, centre of
pressure and free torque columns, a header whose only '=' are its key=value separators, and an
ExternalLoads XML naming the columns. Checked with a small parser written here (not the
exporter's or afo_mj's reader) and the contact points from forward kinematics done here."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from afo_mj.outputs.opensim_export import write_opensim, write_storage

ROOT = Path(__file__).resolve().parents[1]
FEET = ("r", "l")


def _parse_mot(path: Path):
    """(first line, header lines between it and endheader, labels, data) of a storage file."""
    lines = path.read_text(encoding="utf-8").splitlines()
    end = lines.index("endheader")
    labels = lines[end + 1].split("\t")
    data = np.array([[float(v) for v in ln.split("\t")] for ln in lines[end + 2:] if ln.strip()])
    return lines[0], lines[1:end], labels, data


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    from afo_mj.gait.walk import simulate_walk
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(ROOT / "scenarios" / "walk_healthy.toml",
                       overrides=["gait.strides=3", "gait.analyse_strides=[2, 3]"])
    rec = simulate_walk(sc)
    out = tmp_path_factory.mktemp("osim")
    return rec, write_opensim(rec, out, "walk")


@pytest.fixture(scope="module")
def contact_points(walk):
    """(n, 2, 2, 3) world positions of [r/l][heel, ball] sphere centres, by mujoco FK here."""
    import mujoco
    rec, _ = walk
    model = mujoco.MjModel.from_xml_string(rec.model_xml)
    data = mujoco.MjData(model)
    ids = [[model.geom(f"{part}_{side}").id for part in ("heel", "ball")] for side in FEET]
    pts = np.empty((len(rec.time_s), 2, 2, 3))
    for k, q in enumerate(rec.qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        for s in range(2):
            for c in range(2):
                pts[k, s, c] = data.geom_xpos[ids[s][c]]
    return pts


def test_header_holds_only_key_value_lines(walk):
    rec, paths = walk
    for kind in ("ik", "id", "grf"):
        first, header, labels, data = _parse_mot(paths[kind])
        assert "=" not in first and first == f"walk_{kind}"
        keys = [ln.split("=")[0] for ln in header]
        assert keys == ["version", "nRows", "nColumns", "inDegrees", "source", "comment"], kind
        assert all(ln.count("=") == 1 for ln in header), [ln for ln in header
                                                          if ln.count("=") != 1]
        kv = dict(ln.split("=") for ln in header)
        # the force files one row fewer (forces at the state before their row's: Timing)
        assert int(kv["nRows"]) == data.shape[0] == len(rec.time_s) - (kind != "ik")
        assert int(kv["nColumns"]) == data.shape[1] == len(labels)


def test_grf_columns_forces_and_centre_of_pressure(walk, contact_points):
    rec, paths = walk
    _, _, labels, data = _parse_mot(paths["grf"])
    expected = {"time"} | {f"ground_force_{s}_{c}{a}" for s in FEET for c in "vp" for a in "xyz"}
    expected |= {f"ground_torque_{s}_{a}" for s in FEET for a in "xyz"}
    assert set(labels) == expected and len(labels) == len(expected)
    col = {lab: data[:, i] for i, lab in enumerate(labels)}
    np.testing.assert_allclose(col["time"], rec.time_s[:-1], rtol=1e-9)
    # row k of the record: forces computed at the state of row k − 1, written at its time
    # and applied at its contact points
    normal = rec.contact_force_n[1:]
    grf = rec.grf_n[1:]
    points = contact_points[:-1]
    seen = {"both": 0, "heel_only": 0, "unloaded": 0}
    for s, side in enumerate(FEET):
        np.testing.assert_allclose(col[f"ground_force_{side}_vy"], grf[:, s, 1],
                                   rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(col[f"ground_force_{side}_vx"], grf[:, s, 0],
                                   rtol=1e-8, atol=1e-8)
        for a in "xyz":
            assert np.all(col[f"ground_torque_{side}_{a}"] == 0.0)
        assert np.all(col[f"ground_force_{side}_vz"] == 0.0)
        assert np.all(col[f"ground_force_{side}_py"] == 0.0)      # on the floor
        px, pz = col[f"ground_force_{side}_px"], col[f"ground_force_{side}_pz"]
        heel_x, ball_x = points[:, s, 0, 0], points[:, s, 1, 0]
        n_heel, n_ball = normal[:, s, 0], normal[:, s, 1]
        loaded = n_heel + n_ball > 0
        unloaded = ~loaded
        assert np.all(px[unloaded] == 0.0) and np.all(pz[unloaded] == 0.0)
        tol = 1e-8
        lo, hi = np.minimum(heel_x, ball_x) - tol, np.maximum(heel_x, ball_x) + tol
        assert np.all((px[loaded] >= lo[loaded]) & (px[loaded] <= hi[loaded]))
        heel_only = (n_heel > 0) & (n_ball == 0)
        np.testing.assert_allclose(px[heel_only], heel_x[heel_only], atol=1e-8)
        # the CoP zeroes the normal forces' moment about the floor's lateral axis
        both = (n_heel > 0) & (n_ball > 0)
        moment = n_heel * (heel_x - px) + n_ball * (ball_x - px)
        assert np.max(np.abs(moment[both])) < 1e-6 * max(1.0, np.max(n_heel + n_ball))
        # lateral: OpenSim Z (right) is minus the walker's y; the right foot is on the right
        np.testing.assert_allclose(pz[loaded], -points[loaded, s, 0, 1], atol=1e-8)
        assert (np.all(pz[loaded] > 0) if side == "r" else np.all(pz[loaded] < 0))
        seen["both"] += int(both.sum())
        seen["heel_only"] += int(heel_only.sum())
        seen["unloaded"] += int(unloaded.sum())
    assert all(v > 0 for v in seen.values()), seen          # every case was exercised


def test_external_loads_xml_names_the_columns(walk):
    _, paths = walk
    root = ET.parse(paths["grf_xml"]).getroot()
    assert root.tag == "OpenSimDocument"
    loads = root.find("ExternalLoads")
    assert loads.findtext("datafile") == paths["grf"].name
    forces = loads.findall("objects/ExternalForce")
    got = {f.findtext("applied_to_body"): f for f in forces}
    assert set(got) == {"calcn_r", "calcn_l"}
    _, _, labels, _ = _parse_mot(paths["grf"])
    for side in FEET:
        f = got[f"calcn_{side}"]
        assert f.findtext("force_expressed_in_body") == "ground"
        assert f.findtext("point_expressed_in_body") == "ground"
        for tag, ident in (("force_identifier", f"ground_force_{side}_v"),
                           ("point_identifier", f"ground_force_{side}_p"),
                           ("torque_identifier", f"ground_torque_{side}_")):
            assert f.findtext(tag) == ident
            assert all(ident + a in labels for a in "xyz")      # OpenSim appends x, y, z


def test_write_storage_refuses_an_equals_sign_in_the_header(tmp_path):
    with pytest.raises(ValueError, match="comment = 'a = b' holds '='"):
        write_storage(tmp_path / "x.sto", ["time"], [[0.0]], name="x", in_degrees=False,
                      comment="a = b")
    with pytest.raises(ValueError, match="name = 'x=1'"):
        write_storage(tmp_path / "x.sto", ["time"], [[0.0]], name="x=1", in_degrees=False)
    assert not list(tmp_path.iterdir())


def test_opensim_reads_the_grf_back(walk):
    opensim = pytest.importorskip(
        "opensim", reason="opensim is not installed (pip install opensim): OpenSim read-back "
                          "skipped")
    opensim.Logger.removeFileSink()     # no opensim.log in the working directory
    _, paths = walk
    table = opensim.TimeSeriesTable(str(paths["grf"]))
    labels = list(table.getColumnLabels())
    _, _, ours, data = _parse_mot(paths["grf"])
    assert labels == ours[1:]
    assert table.getNumRows() == data.shape[0]
    assert math.isclose(table.getIndependentColumn()[0], data[0, 0], abs_tol=1e-9)
    loads = opensim.ExternalLoads(str(paths["grf_xml"]), True)
    assert loads.getSize() == 2
