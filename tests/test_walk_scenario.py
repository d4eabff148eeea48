"""Walking scenario files: shipped ones load; bad ones give one clear ScenarioError."""

from __future__ import annotations

from pathlib import Path

import pytest

from afo_mj.human.walker import WalkerParams
from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario, parse_scenario

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
SHIPPED = sorted(SCENARIO_DIR.glob("*.toml"))

BASE = """\
name = "t"
[walker]
body_mass_kg = 70.0
[gait]
reference = "winter"
strides = 10
analyse_strides = [4, 10]
[impairment]
plantarflexor_strength_fraction = 0.8
"""


def test_every_shipped_scenario_loads():
    names = {p.stem for p in SHIPPED}
    assert {"walk_healthy", "walk_weak_plantarflexors", "walk_foot_drop", "walk_spastic_ankle",
            "walk_schwartz_free", "walk_schwartz_fast"} <= names
    from afo_mj.scenarios.bench_scenario import is_bench_document, load_bench_scenario
    for p in SHIPPED:
        if is_bench_document(p.read_text(encoding="utf-8")):
            bs = load_bench_scenario(p)         # a device on the test stand, no walker
            assert bs.name == p.stem and bs.description
            # a device, its protocols and the rig's settings (the stiffness sweep with it)
            assert bs.protocols and bs.rig in ("stand", "load") and not bs.notes, p
            assert (bs.stiffness is not None) == ("stiffness" in bs.protocols
                                                  and bs.rig == "stand"), p
            assert (bs.load is not None) == (bs.rig == "load"), p
            continue
        sc = load_scenario(p)
        assert sc.name == p.stem
        assert sc.description
        assert isinstance(sc.walker, WalkerParams)
        ref = sc.load_reference()
        assert sc.cycle_time_s(ref) > 0.5
        assert 1 <= sc.analyse_strides[0] <= sc.analyse_strides[1] <= sc.strides
        assert sc.text == p.read_text(encoding="utf-8")


def test_shipped_impairments_map_to_walker_params():
    get = lambda n: load_scenario(SCENARIO_DIR / f"{n}.toml").walker  # noqa: E731
    assert get("walk_healthy") == WalkerParams(body_mass_kg=75.0, height_m=1.75)
    assert get("walk_weak_plantarflexors").plantarflexor_strength_fraction == 0.5
    assert get("walk_foot_drop").dorsiflexor_strength_fraction == 0.02
    spastic = get("walk_spastic_ankle")
    assert spastic.ankle_passive_stiffness_nm_per_rad == 150.0
    assert spastic.ankle_passive_damping_nm_s_per_rad == 3.0
    free = load_scenario(SCENARIO_DIR / "walk_schwartz_free.toml")
    assert (free.reference, free.condition) == ("winter", "normal")
    assert free.band_references == (("schwartz2008", "Free"),)
    fast = load_scenario(SCENARIO_DIR / "walk_schwartz_fast.toml")
    assert fast.cycle_time_s() < free.cycle_time_s()


def test_defaults_and_parse(tmp_path):
    sc = parse_scenario(BASE, origin="x.toml")
    assert sc.walker.body_mass_kg == 70.0 and sc.walker.plantarflexor_strength_fraction == 0.8
    assert (sc.reference, sc.condition, sc.cadence_steps_per_min) == ("winter", "normal", None)
    assert sc.cycle_time_s() == pytest.approx(1.1396)
    bare = parse_scenario("", default_name="bare")
    assert (bare.name, bare.strides, bare.analyse_strides) == ("bare", 10, (4, 10))
    fast = parse_scenario('[gait]\ncadence_steps_per_min = 120\nstrides = 3\n')
    assert fast.cycle_time_s() == pytest.approx(1.0) and fast.analyse_strides == (3, 3)


def _error(text: str, tmp_path: Path) -> str:
    p = tmp_path / "bad.toml"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    msg = str(info.value)
    assert str(p) in msg            # names the file
    return msg


@pytest.mark.parametrize("text, key, value", [
    ("colour = 'red'\n" + BASE, "colour", "'red'"),
    (BASE.replace("[walker]\n", "[walker]\nshoe_size = 42\n"), "walker.shoe_size", "42"),
    (BASE.replace("strides = 10\n", "strides = 10\nspeed_m_s = 1.2\n"), "gait.speed_m_s", "1.2"),
    (BASE.replace("[impairment]\n", "[impairment]\nknee_stiffness = 3.0\n"),
     "impairment.knee_stiffness", "3.0"),
    (BASE + "[controller]\nmagic_gain = 1.0\n", "controller.magic_gain", "1.0"),
])
def test_unknown_key(tmp_path, text, key, value):
    msg = _error(text, tmp_path)
    assert "unknown key" in msg and repr(key) in msg and value in msg


@pytest.mark.parametrize("text, key, value", [
    (BASE.replace("strides = 10", 'strides = "ten"'), "gait.strides", "'ten'"),
    (BASE.replace("strides = 10", "strides = 10.0"), "gait.strides", "10.0"),
    (BASE.replace("body_mass_kg = 70.0", 'body_mass_kg = "heavy"'), "walker.body_mass_kg",
     "'heavy'"),
    (BASE.replace('reference = "winter"', "reference = 1"), "gait.reference", "1"),
    (BASE.replace("analyse_strides = [4, 10]", 'analyse_strides = "4-10"'),
     "gait.analyse_strides", "'4-10'"),
    (BASE.replace("plantarflexor_strength_fraction = 0.8",
                  "plantarflexor_strength_fraction = true"),
     "impairment.plantarflexor_strength_fraction", "True"),
    ('name = 3\n', "name", "3"),
])
def test_wrong_type(tmp_path, text, key, value):
    msg = _error(text, tmp_path)
    assert f"{key} = {value}" in msg and "allowed" in msg


@pytest.mark.parametrize("text, key, value", [
    (BASE.replace("0.8", "1.5"), "impairment.plantarflexor_strength_fraction", "1.5"),
    (BASE.replace("body_mass_kg = 70.0", "body_mass_kg = 500.0"), "walker.body_mass_kg", "500.0"),
    (BASE.replace("strides = 10", "strides = 0"), "gait.strides", "0"),
    (BASE.replace("[4, 10]", "[4, 20]"), "gait.analyse_strides", "[4, 20]"),
    (BASE.replace("[4, 10]", "[6, 5]"), "gait.analyse_strides", "[6, 5]"),
    (BASE.replace("strides = 10", "strides = 10\ncadence_steps_per_min = 500"),
     "gait.cadence_steps_per_min", "500"),
    (BASE.replace('reference = "winter"', 'reference = "perry"'), "gait.reference", "'perry'"),
    (BASE.replace('reference = "winter"', 'reference = "winter"\ncondition = "Fast"'),
     "gait.condition", "'Fast'"),
    (BASE + "[controller]\nankle_feedforward = 9.0\n", "controller.ankle_feedforward", "9.0"),
])
def test_out_of_range(tmp_path, text, key, value):
    msg = _error(text, tmp_path)
    assert f"{key} = {value}" in msg and "allowed" in msg


def test_other_errors(tmp_path):
    assert "not valid TOML" in _error("name = \n", tmp_path)
    msg = _error(BASE.replace("[walker]\n", "[walker]\nplantarflexor_strength_fraction = 0.7\n"),
                 tmp_path)
    assert "impairment.plantarflexor_strength_fraction" in msg and "walker.plantarflexor" in msg
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.toml")


def test_controller_overrides_are_validated(tmp_path):
    sc = parse_scenario(BASE + "[controller]\nankle_feedforward = 0.5\n")
    assert dict(sc.controller) == {"ankle_feedforward": 0.5}
    assert sc.controller_params().ankle_feedforward == 0.5


def test_reference_path(tmp_path):
    rows = ["percent_cycle,hip_angle_deg,knee_angle_deg,ankle_angle_deg"]
    rows += [f"{p},{20 - 0.4 * p},{30 * (p > 60)},{5 - 0.1 * p}" for p in range(0, 100, 5)]
    (tmp_path / "mine.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    p = tmp_path / "user.toml"
    p.write_text('[gait]\nreference_path = "mine.csv"\ncadence_steps_per_min = 100\n',
                 encoding="utf-8")
    sc = load_scenario(p)
    assert sc.reference == "file" and sc.reference_path == tmp_path / "mine.csv"
    assert sc.load_reference().has("ankle_angle_rad")
    assert sc.cycle_time_s() == pytest.approx(1.2)
    msg = _error('[gait]\nreference_path = "nope.csv"\n', tmp_path)
    assert "gait.reference_path = 'nope.csv'" in msg and "does not exist" in msg
    msg = _error('[gait]\nreference = "winter"\nreference_path = "mine.csv"\n', tmp_path)
    assert "gait.reference = 'winter'" in msg
    (tmp_path / "broken.csv").write_text("a,b\n1,2\n", encoding="utf-8")
    msg = _error('[gait]\nreference_path = "broken.csv"\n', tmp_path)
    assert "gait.reference_path = 'broken.csv' cannot be used" in msg


def test_band_references_are_validated():
    bad = BASE.replace('[gait]', '[gait]\nband_references = ["schwartz2008:Jogging"]')
    with pytest.raises(ScenarioError, match="band_references.*Jogging"):
        parse_scenario(bad, origin="x.toml")


def test_reference_id_path_needs_an_opensim_reference_path(tmp_path):
    (tmp_path / "id.sto").write_text("x\n")
    with pytest.raises(ScenarioError, match="reference_id_path.*without gait.reference_path"):
        parse_scenario('[gait]\nreference_id_path = "id.sto"\n', origin="x.toml",
                       base_dir=tmp_path)


HAFO = SCENARIO_DIR / "gait_assist_hafo.toml"


def test_set_strides_moves_the_analysed_window():
    """`--set gait.strides=6` on a file analysing [4, 10]: the window follows (start kept, end
    clipped), with a note; both set and inconsistent stays an error."""
    sc = load_scenario(HAFO, overrides=["gait.strides=6"])
    assert (sc.strides, sc.analyse_strides) == (6, (4, 6))
    assert any("gait.analyse_strides = [4, 10] -> [4, 6]" in n for n in sc.notes)
    sc = load_scenario(SCENARIO_DIR / "walk_healthy.toml", overrides=["gait.strides=3"])
    assert sc.analyse_strides == (2, 3)
    sc = load_scenario(SCENARIO_DIR / "walk_healthy.toml", overrides=["gait.strides=14"])
    assert sc.analyse_strides == (4, 14)                  # the window ended at the last stride
    assert load_scenario(HAFO).notes == ()
    with pytest.raises(ScenarioError, match=r"gait.analyse_strides = \[4, 10\] is out of range"
                                            r".*gait.strides \(6\)"):
        load_scenario(HAFO, overrides=["gait.strides=6", "gait.analyse_strides=[4, 10]"])


def test_device_key_on_a_scenario_without_device_is_an_error():
    with pytest.raises(ScenarioError, match=r"--set device.params.hose.length_m: this scenario "
                                            r"has no device"):
        load_scenario(SCENARIO_DIR / "walk_healthy.toml",
                      overrides=["device.params.hose.length_m=2.2"])
    with pytest.raises(ScenarioError, match="--set device.preset"):
        parse_scenario(BASE, overrides=["device.preset=hafo"])
    sc = load_scenario(HAFO, overrides=["device.params.hose.length_m=2.2"])
    assert sc.device["params"]["hose.length_m"] == 2.2


def test_unknown_key_suggests_the_close_one():
    with pytest.raises(ScenarioError, match=r"unknown key 'gait.stride'.*did you mean "
                                            r"'gait.strides'\?"):
        parse_scenario(BASE, overrides=["gait.stride=3"])
    with pytest.raises(ScenarioError, match=r"did you mean 'walker.body_mass_kg'\?"):
        parse_scenario(BASE.replace("body_mass_kg", "body_mas_kg"))
    with pytest.raises(ScenarioError, match=r"did you mean 'impairment'\?"):
        parse_scenario(BASE + "[impairement]\nx = 1\n")
    with pytest.raises(ScenarioError) as err:
        parse_scenario(BASE, overrides=["zzz.q=1"])
    assert "did you mean" not in str(err.value)


def test_empty_scenario_file_is_refused(tmp_path):
    for text in ("", "# only a comment\n\n"):
        p = tmp_path / "empty.toml"
        p.write_text(text, encoding="utf-8")
        with pytest.raises(ScenarioError, match=r"empty\.toml: empty scenario"):
            load_scenario(p)
