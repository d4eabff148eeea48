"""A described rig's declared set (issue 41 item 2): every numeric value of the description,
each with a tolerance by kind or stated in ``[calibration.tolerances]``, and the packed row of
any values of it, checked against building the modified description."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SECOND = ROOT / "scenarios" / "calibration" / "second_rig.toml"


def _setup(tmp_path, text: str):
    from afo_mj.calibration.calibration_setup import load_calibration_scenario
    p = tmp_path / "rig.toml"
    p.write_text(text, encoding="utf-8")
    return load_calibration_scenario(str(p))


def _numeric_names(obj, prefix):
    from afo_mj.hydraulics.params import describe
    return {f"{prefix}.{r['name']}" for r in describe(obj) if r["kind"] == "number"}


def test_the_declared_set_is_every_numeric_value_of_the_description():
    """Each numeric field of each component, the oil, the thermal node and the simulated
    load appears once (walked here with params.describe), either screened or excluded with a
    reason; the cable's compliance is screened with the compliance tolerance (±30 %)."""
    from afo_mj.calibration.calibration_setup import load_calibration_scenario
    from afo_mj.calibration.declared_set import described_parameters
    setup = load_calibration_scenario(str(SECOND))
    replay = setup.replay()
    circuit = replay.circuit          # the replayed circuit (the candidates' drains included)
    want = _numeric_names(circuit.fluid, "fluid") | _numeric_names(circuit.thermal, "thermal")
    for comp in circuit.components:
        want |= _numeric_names(comp.params, comp.name)
    want |= {"load.inertia_kg_m2", "load.stiffness_nm_rad", "load.damping_nm_s_rad"}
    ds = described_parameters(replay)
    names = [r["name"] for r in ds.table]
    assert len(names) == len(set(names)) and set(names) == want
    screened = {d.name: d for d in ds.parameters}
    assert set(screened) | set(ds.excluded) == want and not set(screened) & set(ds.excluded)
    assert len(want) > 3 * 13                       # not the old fixed list of 13
    cable = screened["cylinder.series_compliance_rad_per_nm"]
    assert cable.tolerance == 0.3 and cable.labels == ("cylinder.series_compliance",)
    assert cable.value == pytest.approx(5.442e-4)
    # switched-off effects and metadata reach nothing the replay runs; smoothing is no
    # datasheet value
    assert "switched off" in ds.excluded["pump.coulomb_coefficient"]
    assert "not a datasheet value" in ds.excluded["motor.motor.smoothing_speed_rad_s"]


def test_row_of_moved_values_equals_building_the_moved_description(tmp_path):
    """Moving the bore (16 → 16.4 mm), a cable seal's Coulomb scale and the cable compliance
    through the declared set gives the same packed row as writing those values into the TOML
    and generating the circuit again (every entry, 1e-12 relative)."""
    from afo_mj.calibration.declared_set import described_parameters
    from afo_mj.circuits.codegen import generate
    text = SECOND.read_text(encoding="utf-8")
    base = _setup(tmp_path, text)
    ds = described_parameters(base.replay())
    moved = text.replace('"cylinder.bore_m" = 16.0e-3', '"cylinder.bore_m" = 16.4e-3')
    moved = moved.replace('"cylinder.rod_seal.coulomb_scale" = 4.096',
                          '"cylinder.rod_seal.coulomb_scale" = 6.0')
    moved = moved.replace("series_compliance_rad_per_nm = 5.442e-4",
                          "series_compliance_rad_per_nm = 1.2e-3")
    assert moved.count("16.4e-3") == 1 and "= 6.0" in moved and "1.2e-3" in moved
    _, g, _ = generate(_setup(tmp_path, moved).circuit)
    _, g0, _ = generate(base.circuit)
    want = {lab: v for lab, v, v0 in zip(g.P_labels, g.P, g0.P) if v != v0}
    got = ds.row({"cylinder.cylinder.bore_m": 16.4e-3,
                  "cylinder.cylinder.rod_seal.coulomb_scale": 6.0,
                  "cylinder.series_compliance_rad_per_nm": 1.2e-3})
    assert set(got) == set(want) >= {"cylinder.area", "cylinder.seal_fc",
                                     "cylinder.series_compliance"}
    for lab in want:
        assert got[lab] == pytest.approx(want[lab], rel=1e-12), lab


def test_tolerances_and_fixed_values_from_the_scenario(tmp_path):
    """``[calibration.tolerances]`` sets a value's tolerance (and brings a non-datasheet
    value in), ``fixed`` holds one out; the report's table says where each came from."""
    from afo_mj.calibration.declared_set import described_parameters
    text = SECOND.read_text(encoding="utf-8") + (
        'fixed = ["load.damping_nm_s_rad"]\n'
        "[calibration.tolerances]\n"
        '"cylinder.series_compliance_rad_per_nm" = 0.05\n'
        '"check_a.band_pa" = 0.5\n')
    setup = _setup(tmp_path, text)
    assert dict(setup.options.tolerances)["cylinder.series_compliance_rad_per_nm"] == 0.05
    ds = described_parameters(setup.replay(), dict(setup.options.tolerances),
                              setup.options.fixed)
    by = {d.name: d for d in ds.parameters}
    assert by["cylinder.series_compliance_rad_per_nm"].tolerance == 0.05
    assert by["check_a.band_pa"].tolerance == 0.5               # a smoothing band, opted in
    assert "fixed by the user" in ds.excluded["load.damping_nm_s_rad"]
    row = {r["name"]: r for r in ds.table}
    assert row["cylinder.series_compliance_rad_per_nm"]["tolerance_source"] == \
        "[calibration.tolerances]"
    assert row["fluid.liquid_bulk_modulus_pa"]["tolerance_source"] == "default for compliance"


@pytest.mark.parametrize("table, match", [
    ('"cylinder.series_compliance_rad_per_nm" = -0.1', r"tolerances\.cylinder\.series_"
                                                        r"compliance_rad_per_nm = -0\.1; "
                                                        r"allowed: a relative tolerance"),
    ('"fluid.air_fraction" = "ten"', r"fluid\.air_fraction = 'ten'; allowed"),
    ('"fluid.air_fraction" = 0.0', r"fluid\.air_fraction = 0\.0; allowed"),
])
def test_bad_tolerance_values_are_refused_at_load(tmp_path, table, match):
    from afo_mj.hydraulics.params import ParameterError
    text = SECOND.read_text(encoding="utf-8") + "[calibration.tolerances]\n" + table + "\n"
    with pytest.raises(ParameterError, match=match):
        _setup(tmp_path, text)


def test_unknown_tolerance_name_is_refused_with_the_allowed_ones(tmp_path):
    from afo_mj.calibration.declared_set import described_parameters
    from afo_mj.hydraulics.params import ParameterError
    setup = _setup(tmp_path, SECOND.read_text(encoding="utf-8"))
    with pytest.raises(ParameterError, match=re.escape(
            "calibration.tolerances: 'cylinder.cable_k' is not a numeric value of the "
            "description; allowed: fluid.density_kg_m3,")) as err:
        described_parameters(setup.replay(), {"cylinder.cable_k": 0.1})
    assert "cylinder.series_compliance_rad_per_nm" in str(err.value)
    with pytest.raises(ParameterError, match="calibration.fixed: 'motor.R'"):
        described_parameters(setup.replay(), {}, ["motor.R"])


def test_screen_orders_by_the_change_over_one_tolerance():
    """Two columns of which the second is the first plus 1 % of another direction: per unit
    change the first (10× larger) pivots first and the second is held as its combination;
    scaled by tolerances of 2 % and 30 % the second's output change over its tolerance is
    larger and it is the one fitted. A parameter the record would know no better than its
    tolerance (predicted SE above it) is held with that reason."""
    from afo_mj.calibration.identifiability import select_parameters
    rng = np.random.default_rng(0)
    a, u = rng.normal(size=(2, 4000))
    J = np.column_stack([10.0 * a, a + 0.001 * u])
    w = np.ones(4000)
    plain = select_parameters(J, ["bore", "cable"], w)
    assert plain.selected == (0,) and "combination of bore" in plain.rows[1].reason
    scaled = select_parameters(J, ["bore", "cable"], w, tolerances=[0.02, 0.3])
    assert scaled.selected == (1,) and "combination of cable" in scaled.rows[0].reason
    weak = select_parameters(np.column_stack([a * 1e-3]), ["k"], w * 1e-1,
                             tolerances=[0.01], max_relative_se=0.5)
    assert weak.selected == () and "datasheet tolerance" in weak.rows[0].reason


def test_a_seal_breakaway_velocity_is_numerics_without_its_stribeck_peak(tmp_path):
    """The seal's ``breakaway_velocity_m_s`` sets the Stribeck velocity v_St = √2 v_brk and the
    Coulomb smoothing velocity v_C = v_brk/10 (hydraulics/seal.py). With the peak switched off
    (the second rig's description) only v_C acts: not fitted by default, with that reason;
    with the peak on it is a friction figure (±50 %), and a stated tolerance brings it in."""
    from afo_mj.calibration.declared_set import described_parameters
    name = "cylinder.cylinder.piston_seal.breakaway_velocity_m_s"
    text = SECOND.read_text(encoding="utf-8")
    ds = described_parameters(_setup(tmp_path, text).replay())
    assert "Coulomb smoothing velocity" in ds.excluded[name]
    assert "Stribeck peak switched off" in ds.excluded[name]
    assert {r["name"]: r for r in ds.table}[name]["kind"] == "numerical"
    ds = described_parameters(_setup(tmp_path, text).replay(), {name: 0.5})
    assert {d.name: d for d in ds.parameters}[name].tolerance == 0.5
    on = text.replace('"cylinder.piston_seal.stribeck_enabled" = false',
                      '"cylinder.piston_seal.stribeck_enabled" = true')
    assert on != text
    ds = described_parameters(_setup(tmp_path, on).replay())
    d = {d.name: d for d in ds.parameters}[name]
    assert d.kind == "friction" and d.tolerance == 0.5
