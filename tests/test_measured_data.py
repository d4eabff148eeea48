"""Measured-data format v1 (afo_mj.calibration.measured_data): round trips, whole-cycle splits, and
each bad input refused with a message naming the file, the channel/key and what is allowed.
Synthetic numpy signals only (fast, no simulation)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from afo_mj.calibration.measured_data import (CHANNELS, FORMAT, ChannelSpec, MeasuredDataError,
                                           MeasuredDataWarning, UnitWarning, describe,
                                           load_measured, write_measured)

DT = 0.01
N = 1000          # 10 s at 100 Hz, 10 cycles of 1 s
INPUTS = ["motor_voltage_v", "ankle_angle_rad"]
OUTPUTS = ["pressure_a_pa", "ankle_torque_nm", "ankle_angle_rad"]
SOURCE = {"scenario": "scenarios/bench_hafo.toml", "preset": "hafo",
          "description": "synthetic", "licence": "CC0-1.0"}


def signals(n: int = N) -> dict[str, np.ndarray]:
    t = np.arange(n) * DT
    rng = np.random.default_rng(0)
    return {"time_s": t,
            "motor_voltage_v": 12.0 * np.sin(2 * np.pi * t),
            "ankle_angle_rad": 0.3 * np.sin(2 * np.pi * t) + 1e-3 * rng.standard_normal(n),
            "pressure_a_pa": 5.0e6 * (1.0 + np.sin(2 * np.pi * t)) + 2e4,
            "ankle_torque_nm": 40.0 * np.sin(2 * np.pi * t + 0.3)}


def write(tmp_path, name="rec.csv", data=None, inputs=INPUTS, outputs=OUTPUTS, **kw):
    kw.setdefault("segments", {"period_s": 1.0})
    kw.setdefault("noise", {"pressure_a_pa": 2.0e4, "ankle_torque_nm": 0.5})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return write_measured(tmp_path / name, signals() if data is None else data, inputs,
                              outputs, SOURCE, **kw)


def write_raw(tmp_path, data: dict, sidecar: str, name="raw.csv"):
    """Write files by hand (bypassing write_measured's validation) to test the loader."""
    path = tmp_path / name
    cols = list(data)
    rows = np.column_stack([np.asarray(data[c], float) for c in cols])
    with open(path, "w") as f:
        f.write(",".join(cols) + "\n")
        for r in rows.tolist():
            f.write(",".join(map(repr, r)) + "\n")
    (tmp_path / name).with_suffix(".toml").write_text(sidecar)
    return path


SIDECAR = f'''format = "{FORMAT}"
inputs = ["motor_voltage_v", "ankle_angle_rad"]
outputs = ["pressure_a_pa", "ankle_torque_nm"]

[source]
preset = "hafo"
'''


def load_err(path, *, sidecar=None) -> str:
    with pytest.raises(MeasuredDataError) as exc:
        load_measured(path, sidecar)
    return str(exc.value)


# ------------------------------------------------------------------------------- channels


def test_channel_table_is_frozen_specs_with_si_names():
    assert all(isinstance(s, ChannelSpec) for s in CHANNELS.values())
    spec = CHANNELS["pressure_a_pa"]
    with pytest.raises(Exception):
        spec.unit = "bar"
    for name, s in CHANNELS.items():
        assert s.name == name and s.plausible_min < s.plausible_max
        assert s.as_input or s.as_output
    both = {n for n, s in CHANNELS.items() if s.input_and_output}
    assert both == {"ankle_angle_rad", "motor_speed_rad_s"}
    for n in ("motor_voltage_v", "motor_speed_rad_s", "valve_command", "ankle_angle_rad",
              "load_torque_nm"):
        assert CHANNELS[n].as_input
    for n in ("pressure_a_pa", "pressure_b_pa", "supply_pressure_pa", "ankle_torque_nm",
              "ankle_angle_rad", "piston_position_m", "motor_current_a", "motor_speed_rad_s",
              "fluid_temperature_k"):
        assert CHANNELS[n].as_output


# ------------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("name", ["rec.csv", "rec.parquet"])
def test_round_trip_values_equal(tmp_path, name):
    written = write(tmp_path, name)
    assert (tmp_path / name).with_suffix(".toml").is_file()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = load_measured(tmp_path / name)
    src = signals()
    np.testing.assert_array_equal(d.time_s, src["time_s"])
    for k in ("motor_voltage_v", "ankle_angle_rad", "pressure_a_pa", "ankle_torque_nm"):
        np.testing.assert_array_equal(d.channels[k], src[k])
    assert d.inputs == tuple(INPUTS) and d.outputs == tuple(OUTPUTS)
    assert dict(d.noise) == {"pressure_a_pa": 2.0e4, "ankle_torque_nm": 0.5}
    assert dict(d.source) == SOURCE
    assert d.sample_period_s == pytest.approx(DT)
    assert d.segments["period_s"] == 1.0
    assert d.n_samples == N and d.duration_s == pytest.approx(10.0)
    assert written.path == tmp_path / name
    assert not d.time_s.flags.writeable
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, "rec.toml"])


def test_explicit_sidecar_and_describe(tmp_path):
    write(tmp_path, "rec.csv")
    (tmp_path / "rec.toml").rename(tmp_path / "meta.toml")
    d = load_measured(tmp_path / "rec.csv", tmp_path / "meta.toml")
    text = describe(d)
    assert "100 Hz" in text and "10 s" in text and "10 whole cycles" in text
    assert "pressure_a_pa" in text and "[Pa]" in text and "in+out" in text
    assert "preset 'hafo'" in text


# ------------------------------------------------------------------------------- split


def test_split_by_cycles_whole_contiguous_fraction(tmp_path):
    d = load_measured(write(tmp_path).path)
    train, test = d.split(0.3, by="cycles")
    assert train.time_s[0] == 0.0 and train.time_s[-1] == pytest.approx(6.99)
    assert test.time_s[0] == pytest.approx(7.0) and test.time_s[-1] == pytest.approx(9.99)
    assert train.n_samples + test.n_samples == N
    assert train.time_s[-1] < test.time_s[0]                     # not interleaved
    for part in (train, test):
        assert np.all(np.diff(part.time_s) > 0)
        assert part.duration_s == pytest.approx(round(part.duration_s))  # whole cycles
    assert test.duration_s / d.duration_s == pytest.approx(0.3)
    np.testing.assert_array_equal(test.channels["pressure_a_pa"],
                                  d.channels["pressure_a_pa"][700:])


def test_split_by_explicit_cycle_starts_drops_partial_cycles(tmp_path):
    starts = [0.25, 1.35, 2.4, 3.5, 4.55, 5.6, 6.7, 7.75, 8.85]   # last cycle 8.85… partial
    d = load_measured(write(tmp_path, segments={"cycle_starts_s": starts}).path)
    assert len(d.cycles_s()) == 8
    train, test = d.split(0.25, by="cycles")          # 2 of 8 cycles held out
    assert train.time_s[0] == pytest.approx(0.25)
    assert test.time_s[0] == pytest.approx(6.7) and test.time_s[-1] == pytest.approx(8.84)
    assert train.time_s[-1] == pytest.approx(6.69)
    assert test.segments["cycle_starts_s"] == (6.7, 7.75, 8.85)


def test_split_by_segments_and_tail(tmp_path):
    d = load_measured(write(tmp_path, segments={"boundaries_s": [0.0, 2.0, 5.0, 9.0]}).path)
    train, test = d.split(0.3, by="segments")         # round(0.3·4) = 1 segment: 9 s … end
    assert test.time_s[0] == pytest.approx(9.0) and test.time_s[-1] == pytest.approx(9.99)
    assert train.time_s[-1] == pytest.approx(8.99)
    train, test = d.split(0.2, by="tail")
    assert train.n_samples == 800 and test.n_samples == 200
    assert train.time_s[-1] < test.time_s[0]


def test_split_refuses_without_cycles_or_bad_fraction(tmp_path):
    d = load_measured(write(tmp_path, segments={}).path)
    with pytest.raises(MeasuredDataError, match="cycle_starts_s or segments.period_s"):
        d.split(0.3)
    d = load_measured(write(tmp_path, segments={"period_s": 1.0}).path)
    with pytest.raises(MeasuredDataError, match=r"held_out_fraction.*\(0, 1\)"):
        d.split(1.0)
    with pytest.raises(MeasuredDataError, match="'cycles', 'segments', 'tail'"):
        d.split(0.3, by="samples")
    with pytest.raises(MeasuredDataError, match="window"):
        d.window(20.0, 21.0)


# ------------------------------------------------------------------------------- channels errors


def test_unknown_channel_suggests_closest(tmp_path):
    data = signals()
    data["presure_a_pa"] = data.pop("pressure_a_pa")
    path = write_raw(tmp_path, data, SIDECAR)
    msg = load_err(path)
    assert "presure_a_pa" in msg and "did you mean 'pressure_a_pa'" in msg
    assert "Known channels:" in msg and "fluid_temperature_k" in msg and str(path) in msg


def test_listed_channel_missing_from_file(tmp_path):
    data = signals()
    del data["ankle_torque_nm"]
    path = write_raw(tmp_path, data, SIDECAR)
    msg = load_err(path)
    assert "outputs: ankle_torque_nm" in msg and "not a column" in msg
    assert "raw.toml" in msg and "pressure_a_pa" in msg


def test_input_and_output_only_where_allowed(tmp_path):
    data = signals()
    side = SIDECAR.replace('outputs = ["pressure_a_pa", "ankle_torque_nm"]',
                           'outputs = ["pressure_a_pa", "motor_voltage_v"]')
    msg = load_err(write_raw(tmp_path, data, side))
    assert "motor_voltage_v" in msg and "both input and output" in msg
    assert "ankle_angle_rad" in msg                   # names the ones that may be both
    side = SIDECAR.replace('"ankle_torque_nm"]', '"ankle_torque_nm", "ankle_angle_rad"]')
    d = load_measured(write_raw(tmp_path, data, side))
    assert "ankle_angle_rad" in d.inputs and "ankle_angle_rad" in d.outputs


def test_output_only_channel_as_input_refused(tmp_path):
    side = SIDECAR.replace('inputs = ["motor_voltage_v", "ankle_angle_rad"]',
                           'inputs = ["pressure_a_pa"]')
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "inputs" in msg and "'pressure_a_pa' cannot drive the model" in msg
    assert "motor_voltage_v" in msg


def test_unused_columns_warn(tmp_path):
    data = signals()
    data["motor_current_a"] = 3.0 * np.sin(data["time_s"])
    with pytest.warns(MeasuredDataWarning, match="motor_current_a.*neither inputs nor"):
        d = load_measured(write_raw(tmp_path, data, SIDECAR))
    assert "motor_current_a" in d.channels
    assert "unused" in describe(d)


# ------------------------------------------------------------------------------- time errors


def test_time_not_increasing_names_row(tmp_path):
    data = signals()
    data["time_s"] = data["time_s"].copy()
    data["time_s"][120] = data["time_s"][119]
    msg = load_err(write_raw(tmp_path, data, SIDECAR))
    assert "time_s" in msg and "not strictly increasing" in msg
    assert "row 120 (line 122 of the CSV)" in msg


def test_gap_in_sampling_reported(tmp_path):
    data = signals()
    keep = np.ones(N, bool)
    keep[500:530] = False                              # a 0.31 s hole
    data = {k: v[keep] for k, v in data.items()}
    msg = load_err(write_raw(tmp_path, data, SIDECAR))
    assert "non-uniform sampling" in msg and "largest gap 0.31 s" in msg
    assert "row 500" in msg and "t = 5.3 s" in msg


def test_too_few_samples(tmp_path):
    data = {k: v[:30] for k, v in signals().items()}
    msg = load_err(write_raw(tmp_path, data, SIDECAR))
    assert "30 samples" in msg and "at least 50" in msg


def test_time_must_be_first_column(tmp_path):
    data = signals()
    data = {"motor_voltage_v": data.pop("motor_voltage_v"), **data}
    msg = load_err(write_raw(tmp_path, data, SIDECAR))
    assert "first column must be time_s" in msg and "column 1" in msg


def test_non_numeric_field_names_row_and_channel(tmp_path):
    path = write_raw(tmp_path, signals(), SIDECAR)
    lines = path.read_text().splitlines()
    fields = lines[11].split(",")
    fields[3] = "3.2 bar"
    lines[11] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    msg = load_err(path)
    assert "pressure_a_pa" in msg and "'3.2 bar'" in msg and "row 10 (line 12" in msg


# ------------------------------------------------------------------------------- values


def test_nan_and_inf_named_with_first_row_and_count(tmp_path):
    data = signals()
    data["ankle_torque_nm"] = data["ankle_torque_nm"].copy()
    data["ankle_torque_nm"][[40, 41, 300]] = [np.nan, np.inf, np.nan]
    msg = load_err(write_raw(tmp_path, data, SIDECAR))
    assert "ankle_torque_nm" in msg and "3 non-finite" in msg and "row 40" in msg
    assert "nan" in msg


@pytest.mark.parametrize("channel, transform, expect", [
    ("pressure_a_pa", lambda x: x / 1e5, "looks like bar (multiply by 1e5)"),
    ("ankle_angle_rad", np.degrees, "looks like degrees"),
    ("ankle_torque_nm", lambda x: x * 1e3, "looks like N·mm"),
])
def test_unit_mistakes_caught(tmp_path, channel, transform, expect):
    data = signals()
    data[channel] = transform(data[channel])
    msg = load_err(write_raw(tmp_path, data, SIDECAR))
    assert channel in msg and expect in msg and "expected" in msg


@pytest.mark.parametrize("channel, values, expect", [
    ("fluid_temperature_k", lambda t: 35.0 + 5 * np.sin(t), "looks like °C (add 273.15"),
    ("piston_position_m", lambda t: 20.0 * np.sin(t), "looks like mm (multiply by 1e-3)"),
    ("motor_speed_rad_s", lambda t: 3.0e4 * np.sin(t), "looks like rpm"),
    ("ankle_velocity_rad_s", lambda t: 300 * np.sin(t), "looks like deg/s"),
    ("motor_current_a", lambda t: 5000 * np.sin(t), "looks like mA"),
    ("valve_command", lambda t: 80 * np.sin(t), "looks like percent"),
])
def test_unit_mistakes_of_other_channels(tmp_path, channel, values, expect):
    data = signals()
    data[channel] = values(data["time_s"])
    side = SIDECAR.replace('"ankle_torque_nm"]', f'"ankle_torque_nm", "{channel}"]')
    if not CHANNELS[channel].as_output:
        side = SIDECAR.replace('"ankle_angle_rad"]', f'"ankle_angle_rad", "{channel}"]')
    msg = load_err(write_raw(tmp_path, data, side))
    assert channel in msg and expect in msg


def test_implausible_but_possible_warns_and_unit_checks_off(tmp_path):
    data = signals()
    data["ankle_angle_rad"] = 1.35 * np.sin(data["time_s"])  # 1.35 rad: beyond the ankle
    path = write_raw(tmp_path, data, SIDECAR)
    with pytest.warns(UnitWarning, match="ankle_angle_rad.*outside the plausible"):
        load_measured(path)
    data["pressure_a_pa"] = data["pressure_a_pa"] / 1e5
    path = write_raw(tmp_path, data, SIDECAR)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = load_measured(path, unit_checks=False)
    assert d.channels["pressure_a_pa"].max() < 1000


# ------------------------------------------------------------------------------- sidecar errors


def test_missing_sidecar(tmp_path):
    path = write_raw(tmp_path, signals(), SIDECAR)
    path.with_suffix(".toml").unlink()
    msg = load_err(path)
    assert "raw.toml" in msg and "sidecar" in msg and "missing" in msg


def test_bad_toml(tmp_path):
    msg = load_err(write_raw(tmp_path, signals(), SIDECAR + "noise = [\n"))
    assert "raw.toml" in msg and "not valid TOML" in msg


def test_wrong_format(tmp_path):
    msg = load_err(write_raw(tmp_path, signals(),
                             SIDECAR.replace(FORMAT, "afo_mj measured data v0")))
    assert "format" in msg and "'afo_mj measured data v0'" in msg and FORMAT in msg


def test_unknown_top_key(tmp_path):
    msg = load_err(write_raw(tmp_path, signals(), "outptus = []\n" + SIDECAR))
    assert "outptus" in msg and "did you mean 'outputs'" in msg and "Allowed:" in msg


def test_unknown_source_key_and_missing_source(tmp_path):
    side = SIDECAR + 'license = "MIT"\n'
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "source.license" in msg and "did you mean 'licence'" in msg
    side = SIDECAR.replace('preset = "hafo"', 'description = "x"')
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "source" in msg and "scenario" in msg and "preset" in msg


def test_noise_errors(tmp_path):
    side = SIDECAR + "\n[noise]\npressure_b_pa = 1e4\n"
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "noise.pressure_b_pa" in msg and "not in the data file" in msg
    side = SIDECAR + "\n[noise]\nankle_torque_nm = -0.5\n"
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "noise.ankle_torque_nm" in msg and "-0.5" in msg and "> 0" in msg and "N·m" in msg
    side = SIDECAR + "\n[noise]\nankle_torqe_nm = 0.5\n"
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "did you mean 'ankle_torque_nm'" in msg


def test_segment_errors(tmp_path):
    side = SIDECAR + "\n[segments]\ncycle_starts_s = [0.0, 3.0, 2.0]\n"
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "segments.cycle_starts_s" in msg and "strictly increase" in msg
    side = SIDECAR + "\n[segments]\nperiod_s = 1.0\ncycle_starts_s = [0.0, 1.0]\n"
    assert "give one of them" in load_err(write_raw(tmp_path, signals(), side))
    side = SIDECAR + "\n[segments]\nperiods = 1.0\n"
    msg = load_err(write_raw(tmp_path, signals(), side))
    assert "segments.periods" in msg and "did you mean 'period_s'" in msg
    side = SIDECAR + "\n[segments]\nboundaries_s = [0.0, 50.0]\n"
    assert "outside the record" in load_err(write_raw(tmp_path, signals(), side))


# ------------------------------------------------------------------------------- writing


@pytest.mark.parametrize("name", ["bad.csv", "bad.parquet"])
def test_write_refuses_before_writing_anything(tmp_path, name):
    data = signals()
    data["pressure_a_pa"] = data["pressure_a_pa"].copy()
    data["pressure_a_pa"][7] = np.nan
    with pytest.raises(MeasuredDataError, match="pressure_a_pa.*non-finite.*row 7"):
        write_measured(tmp_path / name, data, INPUTS, OUTPUTS, SOURCE)
    data = signals()
    data["pressure_a_pa"] = data["pressure_a_pa"] / 1e5
    with pytest.raises(MeasuredDataError, match="bar"):
        write_measured(tmp_path / name, data, INPUTS, OUTPUTS, SOURCE)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_previous_files_intact(tmp_path, monkeypatch):
    write(tmp_path, "rec.csv")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    import afo_mj.calibration.measured_data as md

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(md.os, "replace", boom)
    data = signals()
    data["ankle_torque_nm"] = data["ankle_torque_nm"] * 2.0
    with pytest.raises(OSError, match="disk full"):
        write_measured(tmp_path / "rec.csv", data, INPUTS, OUTPUTS, SOURCE)
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after == before                            # no temp files left, old pair intact


def test_write_fmt_must_match_suffix_and_lengths(tmp_path):
    with pytest.raises(MeasuredDataError, match="fmt.*'parquet'.*suffix says 'csv'"):
        write_measured(tmp_path / "a.csv", signals(), INPUTS, OUTPUTS, SOURCE, fmt="parquet")
    data = signals()
    data["ankle_torque_nm"] = data["ankle_torque_nm"][:-1]
    with pytest.raises(MeasuredDataError, match="differ in length"):
        write_measured(tmp_path / "a.csv", data, INPUTS, OUTPUTS, SOURCE)
    with pytest.raises(MeasuredDataError, match=r"\.csv or \.parquet"):
        write_measured(tmp_path / "a.txt", signals(), INPUTS, OUTPUTS, SOURCE)
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------- unit mistakes in a real (synthetic) record


@pytest.fixture(scope="module")
def bench_record(tmp_path_factory):
    """A 2 s synthetic HAFO bench record (columns as arrays, and its sidecar text)."""
    from afo_mj.calibration.synthetic_records import generate_record
    path = tmp_path_factory.mktemp("bench") / "rec.csv"
    d = generate_record(path, duration_s=2.0)
    table = {"time_s": np.array(d.time_s), **{k: np.array(v) for k, v in d.channels.items()}}
    return table, path.with_suffix(".toml").read_text()


def _corrupt(bench_record, tmp_path, how):
    table, side = bench_record
    table = {k: v.copy() for k, v in table.items()}
    how(table)
    return write_raw(tmp_path, table, side, name="bad.csv")


def _deg(table):
    table["ankle_angle_rad"] = np.degrees(table["ankle_angle_rad"])


def _absolute(table):
    for k in ("pressure_a_pa", "pressure_b_pa"):  # a line at rest reads 1 atm absolute
        table[k] = table[k] - table[k].min() + 101325.0


def _ms(table):
    table["time_s"] = table["time_s"] * 1e3


@pytest.mark.parametrize("how, column, expect", [
    (_deg, "ankle_angle_rad", ["looks like degrees", "expected rad", "-6.1"]),
    (_absolute, "pressure_a_pa", ["absolute", "gauge", "101325…"]),
    (_ms, "time_s", ["milliseconds", "expected s", "0…1999"]),
], ids=["degrees", "absolute-pressure", "milliseconds"])
def test_unit_mistakes_in_a_bench_record_are_refused(bench_record, tmp_path, how, column,
                                                      expect):
    """Issue 19 item 3: degrees, absolute pressure and ms time are errors naming the column,
    the range seen and the unit expected (not a warning, not a confident fit)."""
    assert load_measured(write_raw(tmp_path, *bench_record, name="ok.csv")).n_samples > 0
    msg = load_err(_corrupt(bench_record, tmp_path, how))
    assert f"{column}:" in msg
    for e in expect:
        assert e in msg, (e, msg)


def test_calibrate_refuses_a_record_in_degrees(bench_record, tmp_path, capsys):
    """``afo-mj calibrate`` on a record with the angle in degrees: exit 2, nothing written."""
    from afo_mj import cli
    path = _corrupt(bench_record, tmp_path, _deg)
    out = tmp_path / "cal"
    rc = cli.main(["calibrate", "--scenario", "hafo", "--data", str(path), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and not out.exists()
    assert "ankle_angle_rad" in err and "degrees" in err
