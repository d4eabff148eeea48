"""Reference gait: shipped normative table and the user-data loaders.

Independent references:
* the source files in ``shared/data`` (read here with their own small parser and the unit/sign
  conversions written out by hand), when present next to the repository;
* the figures printed in ``shared/data/README.md`` for Winter's normal cadence (computed there by
  central differences on a 75 kg subject): peak ankle plantarflexor moment 1.688 Nm/kg at 46 %,
  peak ankle power 3.24 W/kg at 54 %, positive ankle work 0.345 J/kg and negative 0.125 J/kg per
  stride, ankle range -19.8 deg (66 %) to +9.6 deg (44 %);
* the general shape of children's push-off (Schwartz 2008 Free: ankle power generation peak in
  late stance, 45-65 % of the cycle);
* synthetic OpenSim/CSV files written here with known contents (round trips).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from afo_mj.gait.reference import (ReferenceGaitError, load_normative, load_opensim_storage,
                                   load_reference_csv)

REPO = Path(__file__).resolve().parents[1]
WINTER_T_S = 1.1396  # cycle time in the Winter source header
SOURCE_PC = np.arange(0, 100, 2) / 100.0  # the source's 2 % samples, 0..98 %


def _shared_data() -> Path:
    for d in (REPO / ".." / "shared" / "data", Path("/work/shared/data")):
        if (d / "winter_normal_cadence.csv").is_file():
            return d.resolve()
    pytest.skip("shared/data with the source gait files not found")


# ------------------------------------------------------------------------------------------
# derived table vs the source files
# ------------------------------------------------------------------------------------------

def test_winter_table_equals_source_at_source_samples():
    d = _shared_data()
    with (d / "winter_normal_cadence.csv").open(encoding="utf-8-sig", newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and r[0].strip().isdigit()]
    a = np.array([[float(x) for x in r[4:12]] for r in rows])
    assert a.shape == (51, 8)
    g = load_normative("winter", "normal")
    expect = {
        "hip_angle_rad": np.radians(a[:, 0]), "knee_angle_rad": np.radians(a[:, 1]),
        "ankle_angle_rad": np.radians(a[:, 2]), "grf_x_n_per_kg": a[:, 3],
        "grf_z_n_per_kg": a[:, 4],
        # Winter moments are extensor / plantarflexor positive; ours flexor / dorsiflexor
        "hip_moment_nm_per_kg": -a[:, 5], "knee_moment_nm_per_kg": -a[:, 6],
        "ankle_moment_nm_per_kg": -a[:, 7],
    }
    for name, src in expect.items():
        np.testing.assert_allclose(g.channel(name, SOURCE_PC), src[:50], atol=1e-6,
                                   err_msg=name)
        mean, sd = g.band(name, SOURCE_PC)
        assert sd is None
    assert g.cycle_time_s == pytest.approx(WINTER_T_S)
    assert g.speed_m_s == pytest.approx(1.325)


@pytest.mark.parametrize("cond", ["VerySlow", "Slow", "Free", "Fast", "VeryFast"])
def test_schwartz_table_equals_source_at_source_samples(cond):
    d = _shared_data()
    src = json.loads((d / "schwartz2008_normative.json").read_text())["Schwartz2008"][cond]
    g = load_normative("schwartz2008", cond)
    for joint in ("Hip", "Knee", "Ankle"):
        j = joint.lower()
        for key, axis, name, scale in (
                (f"{joint}Angles", "X", f"{j}_angle_rad", math.pi / 180.0),
                (f"{joint}Moment", "X", f"{j}_moment_nm_per_kg", -1e-3),  # N*mm/kg ext+ -> ours
                (f"{joint}Power", "Z", f"{j}_power_w_per_kg", 1.0)):
            b = np.array(src[key][axis], dtype=float)
            np.testing.assert_array_equal(b[:50, 0], np.arange(0, 100, 2))
            mean, sd = g.band(name, SOURCE_PC)
            np.testing.assert_allclose(mean, 0.5 * (b[:50, 1] + b[:50, 2]) * scale, atol=1e-6,
                                       err_msg=f"{cond} {name} mean")
            np.testing.assert_allclose(sd, 0.5 * (b[:50, 2] - b[:50, 1]) * abs(scale),
                                       atol=1e-6, err_msg=f"{cond} {name} sd")
    pelvis = np.array(src["PelvisAngles"]["X"], dtype=float)[:50]
    hip = np.array(src["HipAngles"]["X"], dtype=float)[:50]
    tilt_mean, _ = g.band("pelvis_tilt_rad", SOURCE_PC)
    np.testing.assert_allclose(tilt_mean, np.radians(0.5 * (pelvis[:, 1] + pelvis[:, 2])),
                               atol=1e-6)
    thigh_mean, _ = g.band("thigh_angle_rad", SOURCE_PC)
    np.testing.assert_allclose(
        thigh_mean, np.radians(0.5 * (hip[:, 1] + hip[:, 2]) - 0.5 * (pelvis[:, 1] + pelvis[:, 2])),
        atol=1e-6)


# ------------------------------------------------------------------------------------------
# independent figures (shared/data/README.md), from the shipped table alone
# ------------------------------------------------------------------------------------------

def test_winter_peak_ankle_plantarflexor_moment():
    g = load_normative()
    pc = np.arange(101) / 100.0
    m = g.moments_nm_per_kg(pc)[:, 2]
    k = int(np.argmin(m))
    assert -m[k] == pytest.approx(1.688, rel=0.01)  # plantarflexor = negative in our convention
    assert 44 <= k <= 48
    # 127 N*m for the 75 kg subject
    assert -m[k] * 75.0 == pytest.approx(127.0, rel=0.01)


def test_winter_ankle_power_and_work_from_moment_times_spline_velocity():
    g = load_normative()
    # peak at the source's own 2 % samples (how the README figure was sampled)
    p = g.moments_nm_per_kg(SOURCE_PC)[:, 2] * g.velocities_rad_s(SOURCE_PC)[:, 2]
    k = int(np.argmax(p))
    assert p[k] == pytest.approx(3.24, rel=0.03)
    assert 52 <= 100 * SOURCE_PC[k] <= 56
    # stride work, fine grid
    ph = np.linspace(0.0, 1.0, 20001)
    pf = g.moments_nm_per_kg(ph)[:, 2] * g.velocities_rad_s(ph)[:, 2]
    dt = WINTER_T_S * (ph[1] - ph[0])
    pos = np.sum(np.clip(pf, 0, None)[:-1]) * dt
    neg = -np.sum(np.clip(pf, None, 0)[:-1]) * dt
    assert pos == pytest.approx(0.345, rel=0.10)
    assert neg == pytest.approx(0.125, rel=0.10)
    # powers_w_per_kg (no stored power for Winter) is the same product
    np.testing.assert_allclose(g.powers_w_per_kg(SOURCE_PC)[:, 2], p, rtol=1e-12)


def test_winter_ankle_range_and_peak_velocity():
    g = load_normative()
    ank = np.degrees(g.angles_rad(SOURCE_PC)[:, 2])
    assert ank.min() == pytest.approx(-19.8, abs=0.05)
    assert 100 * SOURCE_PC[np.argmin(ank)] == pytest.approx(66)
    assert ank.max() == pytest.approx(9.6, abs=0.05)
    assert 100 * SOURCE_PC[np.argmax(ank)] == pytest.approx(44)
    vel = np.degrees(g.velocities_rad_s(np.arange(101) / 100.0)[:, 2])
    assert -vel.min() == pytest.approx(216.0, rel=0.05)  # README: 216 deg/s near 58 %
    assert 56 <= np.argmin(vel) <= 60


def test_winter_peak_vertical_grf():
    g = load_normative()
    assert g.channel("grf_z_n_per_kg", SOURCE_PC).max() == pytest.approx(10.8, abs=0.05)


def test_schwartz_free_push_off_and_bands():
    g = load_normative("schwartz2008", "Free")
    pc = np.arange(101) / 100.0
    p = g.powers_w_per_kg(pc)[:, 2]
    assert p.max() > 1.0
    assert 45 <= int(np.argmax(p)) <= 65
    # the push-off power matches moment x velocity with the metadata's estimated cycle time
    pm = g.moments_nm_per_kg(pc)[:, 2] * g.velocities_rad_s(pc)[:, 2]
    assert pm.max() == pytest.approx(p.max(), rel=0.15)
    _, sd = g.band("ankle_angle_rad", pc)
    assert np.all(sd > 0)
    assert g.speed_m_s is None


def test_phase_wraps_and_shapes():
    g = load_normative()
    ph = np.array([[0.25, 0.9], [0.0, 0.5]])
    assert g.angles_rad(ph).shape == (2, 2, 3)
    np.testing.assert_allclose(g.angles_rad(ph + 3.0), g.angles_rad(ph), atol=1e-12)
    np.testing.assert_allclose(g.angles_rad(-0.1), g.angles_rad(0.9), atol=1e-12)
    # velocity = d angle / d time by central differences of the angle
    h = 1e-6
    fd = (g.angles_rad(0.3 + h) - g.angles_rad(0.3 - h)) / (2 * h * WINTER_T_S)
    np.testing.assert_allclose(g.velocities_rad_s(0.3), fd, rtol=1e-6, atol=1e-8)
    # time-scaled cycle
    np.testing.assert_allclose(g.velocities_rad_s(0.3, cycle_time_s=2 * WINTER_T_S),
                               0.5 * g.velocities_rad_s(0.3))
    with pytest.raises(ReferenceGaitError, match="no_such"):
        g.channel("no_such_channel", 0.1)
    with pytest.raises(ReferenceGaitError, match="Fre"):
        load_normative("schwartz2008", "Fre")


# ------------------------------------------------------------------------------------------
# OpenSim storage files
# ------------------------------------------------------------------------------------------

BODY_MASS_KG = 75.0


def _write_sto(path: Path, labels, rows, in_degrees: str | None = "yes", name="coords"):
    head = [name, "version=1", f"nRows={len(rows)}", f"nColumns={len(labels)}"]
    if in_degrees is not None:
        head.append(f"inDegrees={in_degrees}")
    lines = head + ["endheader", "\t".join(labels)]
    lines += ["\t".join(f"{v:.17g}" for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")


def _winter_opensim(tmp_path: Path, knee_sign=-1.0, degrees=True, n=101):
    g = load_normative()
    ph = np.arange(n) / (n - 1)
    t = 0.35 + ph * WINTER_T_S
    ang = g.angles_rad(ph)
    mom = g.moments_nm_per_kg(ph) * BODY_MASS_KG
    f = np.degrees if degrees else (lambda x: x)
    coords = np.column_stack([t, f(ang[:, 0]), knee_sign * f(ang[:, 1]), f(ang[:, 2])])
    _write_sto(tmp_path / "ik.mot", ["time", "hip_flexion_r", "knee_angle_r", "ankle_angle_r"],
               coords, "yes" if degrees else "no")
    idr = np.column_stack([t, mom[:, 0], knee_sign * mom[:, 1], mom[:, 2]])
    _write_sto(tmp_path / "id.sto", ["time", "hip_flexion_r_moment", "knee_angle_r_moment",
                                     "ankle_angle_r_moment"], idr, "no", name="Inverse Dynamics")
    return g, coords, idr


def test_opensim_round_trip_gait2392(tmp_path):
    g, _, _ = _winter_opensim(tmp_path, knee_sign=-1.0)
    r = load_opensim_storage(tmp_path / "ik.mot", body_mass_kg=BODY_MASS_KG,
                             id_path=tmp_path / "id.sto")
    assert r.metadata["knee_flexion_sign"] == -1
    assert r.cycle_time_s == pytest.approx(WINTER_T_S, abs=1e-12)
    ph = np.random.default_rng(1).uniform(0, 1, 200)
    np.testing.assert_allclose(r.angles_rad(ph), g.angles_rad(ph), atol=1e-9)
    np.testing.assert_allclose(r.moments_nm_per_kg(ph), g.moments_nm_per_kg(ph), atol=1e-9)
    np.testing.assert_allclose(r.velocities_rad_s(ph), g.velocities_rad_s(ph), atol=1e-7)


def test_opensim_rajagopal_radians_and_cycle_window(tmp_path):
    g, coords, _ = _winter_opensim(tmp_path, knee_sign=+1.0, degrees=False)
    r = load_opensim_storage(tmp_path / "ik.mot", knee_flexion_sign=+1)
    ph = np.linspace(0, 1, 37)
    np.testing.assert_allclose(r.angles_rad(ph), g.angles_rad(ph), atol=1e-9)
    assert not r.has("ankle_moment_nm_per_kg")
    # 1.5 cycles in the file; the user names the heel strikes
    t = coords[:, 0]
    more = coords[1:51].copy()
    more[:, 0] = t[1:51] + WINTER_T_S
    _write_sto(tmp_path / "long.mot", ["time", "hip_flexion_r", "knee_angle_r", "ankle_angle_r"],
               np.vstack([coords, more]), "no")
    r2 = load_opensim_storage(tmp_path / "long.mot", knee_flexion_sign=1,
                              cycle_start_s=t[20], cycle_end_s=t[20] + WINTER_T_S)
    np.testing.assert_allclose(r2.angles_rad(ph), g.angles_rad(ph + 0.2), atol=1e-9)


def test_opensim_degrees_declared_as_radians(tmp_path):
    _winter_opensim(tmp_path, degrees=True)
    text = (tmp_path / "ik.mot").read_text().replace("inDegrees=yes", "inDegrees=no")
    (tmp_path / "bad.mot").write_text(text)
    with pytest.raises(ReferenceGaitError, match="hip_flexion_r.*degrees"):
        load_opensim_storage(tmp_path / "bad.mot")
    (tmp_path / "none.mot").write_text(text.replace("inDegrees=no\n", ""))
    with pytest.raises(ReferenceGaitError, match="inDegrees"):
        load_opensim_storage(tmp_path / "none.mot")
    r = load_opensim_storage(tmp_path / "none.mot", in_degrees=True)
    assert np.degrees(r.angles_rad(0.66)[2]) == pytest.approx(-19.8, abs=0.1)


def test_opensim_error_cases(tmp_path):
    _, coords, idr = _winter_opensim(tmp_path)
    labels = ["time", "hip_flexion_r", "knee_angle_r", "ankle_angle_r"]
    _write_sto(tmp_path / "miss.mot", labels[:3], coords[:, :3])
    with pytest.raises(ReferenceGaitError, match="ankle_angle_r"):
        load_opensim_storage(tmp_path / "miss.mot")
    back = coords.copy()
    back[[10, 11], 0] = back[[11, 10], 0]
    _write_sto(tmp_path / "back.mot", labels, back)
    with pytest.raises(ReferenceGaitError, match="'time'.*increas"):
        load_opensim_storage(tmp_path / "back.mot")
    nan = coords.copy()
    nan[5, 2] = np.nan
    _write_sto(tmp_path / "nan.mot", labels, nan)
    with pytest.raises(ReferenceGaitError, match="knee_angle_r.*nan"):
        load_opensim_storage(tmp_path / "nan.mot")
    with pytest.raises(ReferenceGaitError, match="body_mass_kg"):
        load_opensim_storage(tmp_path / "ik.mot", id_path=tmp_path / "id.sto")
    with pytest.raises(ReferenceGaitError, match="knee_flexion_sign"):
        load_opensim_storage(tmp_path / "ik.mot", knee_flexion_sign=2)
    with pytest.raises(ReferenceGaitError, match="ankle_torque"):
        load_opensim_storage(tmp_path / "ik.mot", mapping={"ankle_torque": "ankle_angle_r"})


# ------------------------------------------------------------------------------------------
# user CSV
# ------------------------------------------------------------------------------------------

def test_csv_percent_round_trip_with_mapping(tmp_path):
    g = load_normative()
    pc = np.arange(0, 101, 1.0)
    ang = np.degrees(g.angles_rad(pc / 100))
    mom = g.moments_nm_per_kg(pc / 100)
    path = tmp_path / "mine.csv"
    with path.open("w", newline="") as fh:
        fh.write("# my lab's gait, moments extensor positive in N*m for 80 kg\n")
        w = csv.writer(fh)
        w.writerow(["percent_cycle", "HipFlex", "KneeFlex", "AnkleDF", "AnkleMomPF"])
        for k in range(len(pc)):
            w.writerow([repr(float(x)) for x in (pc[k], ang[k, 0], ang[k, 1], ang[k, 2],
                                               -mom[k, 2] * 80.0)])
    r = load_reference_csv(path, {
        "hip_angle_rad": {"column": "HipFlex", "unit": "deg"},
        "knee_angle_rad": {"column": "KneeFlex", "unit": "deg"},
        "ankle_angle_rad": {"column": "AnkleDF", "unit": "deg"},
        "ankle_moment_nm_per_kg": {"column": "AnkleMomPF", "unit": "N*m", "sign": -1},
    }, body_mass_kg=80.0, cycle_time_s=WINTER_T_S)
    ph = np.linspace(0, 1, 53)
    np.testing.assert_allclose(r.angles_rad(ph), g.angles_rad(ph), atol=1e-9)
    np.testing.assert_allclose(r.channel("ankle_moment_nm_per_kg", ph),
                               g.moments_nm_per_kg(ph)[:, 2], atol=1e-9)
    np.testing.assert_allclose(r.velocities_rad_s(ph), g.velocities_rad_s(ph), atol=1e-7)


def test_csv_time_default_mapping_and_errors(tmp_path):
    g = load_normative("schwartz2008", "Free")
    ph = np.arange(101) / 100
    ang = g.angles_rad(ph)
    _, sd = g.band("ankle_angle_rad", ph)
    header = ["time_s", "hip_angle_rad", "knee_angle_rad", "ankle_angle_rad",
              "ankle_angle_rad_sd"]
    data = np.column_stack([2.0 + ph * 1.1, ang, sd])

    def write(name, arr, hdr=header):
        p = tmp_path / name
        with p.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(hdr)
            w.writerows([[repr(float(v)) for v in row] for row in arr])
        return p

    r = load_reference_csv(write("t.csv", data))
    assert r.cycle_time_s == pytest.approx(1.1)
    q = np.linspace(0, 1, 41)
    np.testing.assert_allclose(r.angles_rad(q), g.angles_rad(q), atol=1e-9)
    np.testing.assert_allclose(r.band("ankle_angle_rad", q)[1],
                               g.band("ankle_angle_rad", q)[1], atol=1e-9)
    deg = data.copy()
    deg[:, 1:4] = np.degrees(deg[:, 1:4])
    with pytest.raises(ReferenceGaitError, match="hip_angle_rad.*degrees"):
        load_reference_csv(write("deg.csv", deg))
    r2 = load_reference_csv(write("deg2.csv", deg), angle_unit="deg")
    np.testing.assert_allclose(r2.angles_rad(q), g.angles_rad(q), atol=1e-9)
    with pytest.raises(ReferenceGaitError, match="ankle_angle_rad"):
        load_reference_csv(write("miss.csv", data[:, :3], header[:3]))
    with pytest.raises(ReferenceGaitError, match="Ankle"):
        load_reference_csv(write("x.csv", data), {"hip_angle_rad": "hip_angle_rad",
                                                  "knee_angle_rad": "knee_angle_rad",
                                                  "ankle_angle_rad": "Ankle"})
    with pytest.raises(ReferenceGaitError, match="deg/s"):
        load_reference_csv(write("u.csv", data), {"ankle_angle_rad": {"column": "time_s",
                                                                      "unit": "deg/s"}})


def _percent_csv(path, pc):
    g = load_normative()
    ang = g.angles_rad(np.arange(len(pc)) / (len(pc) - 1))
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["percent_cycle", "hip_angle_rad", "knee_angle_rad", "ankle_angle_rad"])
        w.writerows([[repr(float(x)) for x in (pc[k], *ang[k])] for k in range(len(pc))])
    return path


def test_csv_percent_cycle_given_as_fraction_is_refused(tmp_path):
    """A percent_cycle column running 0..1 (a fraction) is refused, not read as 0..1 %."""
    path = _percent_csv(tmp_path / "frac.csv", np.linspace(0.0, 1.0, 51))
    with pytest.raises(ReferenceGaitError, match=r"percent_cycle' runs 0\.\.1, a fraction.*"
                                                 r"0\.\.100"):
        load_reference_csv(path)
    load_reference_csv(_percent_csv(tmp_path / "pct.csv", np.linspace(0.0, 100.0, 51)))


def test_csv_errors_show_numbers_plainly(tmp_path):
    """No numpy scalar reprs (np.float64(...)) in the messages."""
    pc = np.linspace(0.0, 100.0, 51)
    pc[10] = pc[9]
    with pytest.raises(ReferenceGaitError) as err:
        load_reference_csv(_percent_csv(tmp_path / "dup.csv", pc))
    assert "np.float64" not in str(err.value) and "(0.18 then 0.18)" in str(err.value)
