"""The declared tables of the scenario files (afo_mj/scenarios/schema.py): one unknown-key
error format for every table, every declared key accepted by its parser, and the defaults the
parsers take from the declarations equal to the documented ones."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from afo_mj.scenarios import bench_scenario as bs
from afo_mj.scenarios import circuit_scenario as cs
from afo_mj.scenarios import device_scenario as ds
from afo_mj.scenarios import device_source
from afo_mj.scenarios import walk_scenario as ws
from afo_mj.scenarios.schema import Key, ScenarioError, Table, check_table

T = Table("gait", (Key("strides", "integer", (1, 1000), 10), Key("reference", "string")))


def test_check_table_message_format():
    check_table({"strides": 3, "reference": "winter"}, T, "f.toml")      # declared: no error
    with pytest.raises(ScenarioError) as err:
        check_table({"strides": 3, "stride": 4}, T, "f.toml")
    assert str(err.value) == ("f.toml: unknown key 'gait.stride' (= 4) (did you mean "
                              "'gait.strides'?); allowed keys in [gait]: strides, reference")
    with pytest.raises(ScenarioError) as err:                        # nothing close: no hint
        check_table({"zzz": [1]}, T, "f.toml")
    assert str(err.value) == ("f.toml: unknown key 'gait.zzz' (= [1]); allowed keys in "
                              "[gait]: strides, reference")
    top = Table("", (Key("name"), Key("bench")), note="(no walker)")
    with pytest.raises(KeyError) as err:                               # another error class
        check_table({"nme": "x"}, top, "b.toml", error=KeyError)
    assert err.value.args[0] == ("b.toml: unknown key 'nme' (= 'x') (did you mean 'name'?); "
                                 "allowed keys: name, bench (no walker)")


def test_table_declarations_refuse_mistakes():
    with pytest.raises(ValueError, match=r"\['a'\] declared twice"):
        Table("t", (Key("a"), Key("b"), Key("a")))
    with pytest.raises(ValueError, match="kind = 'float'"):
        Key("a", "float")
    with pytest.raises(ValueError, match="lo <= hi"):
        Key("a", "number", (2.0, 1.0))
    assert T.only("reference").names == ("reference",) and T.default("strides") == 10
    with pytest.raises(KeyError, match="no key 'x'"):
        T["x"]


def _walk(text):
    return ws.parse_scenario(text, origin="f.toml")


def _device(text):
    # (device_config names the scenario by its file, else by its name)
    return ds.device_config(ws.parse_scenario(text, origin="f.toml", default_name="f.toml"))


def _bench(text):
    return bs.parse_bench_scenario(text, origin="f.toml")


def _rig(text):
    return device_source._rig_circuit(text, "f.toml", ())


HAFO = '[device]\npreset = "hafo"\n'
STIFF = '[device]\npreset = "phafo"\n[bench]\nprotocols = ["stiffness"]\n'
CIRC = '[circuit]\nlibrary = "lab_bench"\n'
RIG = '[circuit]\nlibrary = "lab_bench"\n[load]\n'

#: (parse, document with one unknown key, its dotted name, the table named in the message)
UNKNOWN = [
    (_walk, "nmae = 'x'", "nmae", ""),
    (_walk, "[gait]\nstridez = 3", "gait.stridez", "gait"),
    (_walk, "[walker]\nheight = 1.7", "walker.height", "walker"),
    (_walk, "[impairment]\nspasticity = 1", "impairment.spasticity", "impairment"),
    (_walk, "[controller]\nhip_kp = 1.0", "controller.hip_kp", "controller"),
    (_walk, "[output]\nrrd = true", "output.rrd", "output"),
    (_device, HAFO + "sidez = ['right']", "device.sidez", "device"),
    (_device, HAFO + "[assistance]\npeak_nm = 3", "assistance.peak_nm", "assistance"),
    (_bench, "[walker]\n[bench]", "walker", ""),
    (_bench, HAFO + "sides = ['right']\n[bench]", "device.sides", "device"),
    (_bench, HAFO + "[bench]\ntest = []", "bench.test", "bench"),
    (_bench, STIFF + "test = []", "bench.test", "bench"),
    (_bench, CIRC + "[bench]\nfreq_pts = 30", "bench.freq_pts", "bench"),
    (lambda t: cs.circuit_spec({"library": "lab_bench", "nodez": {}}, "f.toml"), "",
     "circuit.nodez", "circuit"),
    (_rig, RIG + "[sensorz]", "sensorz", ""),
]


@pytest.mark.parametrize("parse, text, dotted, table", UNKNOWN,
                         ids=[u[2] + ("@bench" if u[0] is _bench else "") for u in UNKNOWN])
def test_every_scenario_table_refuses_an_unknown_key_in_one_format(parse, text, dotted, table):
    with pytest.raises(ScenarioError) as err:
        parse(text)
    where = rf" in \[{table}\]" if table else ""
    assert re.match(rf"f\.toml: unknown key '{re.escape(dotted)}' \(= .*\)"
                    rf"( \(did you mean '[a-z_.]+'\?\))?; allowed keys{where}: [a-z_]+(, [a-z_]+)*",
                    str(err.value)), str(err.value)


#: (declared table, its parser, a document holding one key of it in place of ``{}``)
DECLARED = [(ws.TOP, _walk, "{} = 1"), (ws.GAIT, _walk, "[gait]\n{} = 1"),
            (ws.OUTPUT, _walk, "[output]\n{} = 1"),
            (ws.IMPAIRMENT, _walk, "[impairment]\n{} = 1"), (ds.DEVICE, _device, HAFO + "{} = 1"),
            (ds.ASSISTANCE, _device, HAFO + "[assistance]\n{} = 1"),
            (bs.TOP, _bench, "{} = 1\n[bench]"), (bs.BENCH, _bench, HAFO + "[bench]\n{} = 1"),
            (bs.BENCH, _bench, STIFF + "{} = 1"), (bs.BENCH, _bench, CIRC + "[bench]\n{} = 1"),
            (device_source.RIG, _rig, RIG + "{} = 1")]


@pytest.mark.parametrize("table, parse, template", DECLARED,
                         ids=[f"{i}:{t.name or 'top'}" for i, (t, _, _) in enumerate(DECLARED)])
def test_every_declared_key_is_known_to_its_parser(table, parse, template):
    """A declared key may still be refused for its value (1 is often the wrong type), never
    as an unknown key."""
    for name in table.names:
        if f"\n{name} =" in "\n" + template.format("") or f"[{name}]" in template:
            continue                      # the template already holds it
        try:
            parse(template.format(name))
        except ScenarioError as exc:
            assert "unknown key" not in str(exc), (name, str(exc))


def test_circuit_table_keys_are_those_circuit_descriptions_take():
    """``[circuit]`` declares the keys of ``Circuit.from_dict`` plus ``library``: every
    key of a shipped description is declared, and every declared key but library passes
    check_table on a shipped description's key set."""
    from afo_mj.circuits.library import LIBRARY
    used = set()
    for name in LIBRARY:
        used |= set(cs.library_spec(name))
    assert used <= set(cs.CIRCUIT.names) - {"library"}
    assert {"components", "nodes", "controller"} <= used


def test_defaults_read_from_the_declarations_are_the_documented_ones():
    """The documented defaults (module docstrings, docs): the stand's foot for a 75 kg,
    1.75 m wearer; the stiffness sweep's 12 deg, 0.25 Hz, 3 cycles at 0.5 ms sweeping 1, 2.5
    and 4.6 N*m/deg (the deprecated bench.kind = "stiffness": on a 25.8 kg, 1.28 m child's
    foot); Zhang's profile 40 N*m peaking at 52.9 %;
    a recording at 500 Hz (signals) and 50 Hz (transforms); 10 strides of Winter's gait."""
    hafo = _bench(HAFO + "[bench]")
    assert (hafo.body_mass_kg, hafo.height_m, hafo.timestep_s) == (75.0, 1.75, None)
    st = _bench(STIFF).stiffness
    deg = math.pi / 180.0
    assert st.amplitude_rad == pytest.approx(12.0 * deg) and st.frequency_hz == 0.25
    assert (st.cycles, st.timestep_s, st.body_mass_kg, st.height_m) == (3, 5e-4, 75.0, 1.75)
    old = _bench('[device]\npreset = "phafo"\n[bench]\nkind = "stiffness"\n').stiffness
    assert (old.cycles, old.timestep_s, old.body_mass_kg, old.height_m) == (3, 5e-4, 25.8, 1.28)
    assert [k * deg for k in st.stiffnesses_nm_per_rad] == pytest.approx([1.0, 2.5, 4.6])
    cfg = _device(HAFO)
    assert cfg.conditions == ("no_device", "transparent", "assist") and cfg.sides == ("right",)
    from afo_mj.control import assistance as asst
    assert cfg.profile == pytest.approx(asst.zhang_profile(40.0, 52.9, 26.2, 9.8))
    w = _walk("[output]\nrecord = true")
    assert (w.record_signal_rate_hz, w.record_transform_rate_hz) == (500.0, 50.0)
    assert (w.strides, w.reference, w.analyse_strides) == (10, "winter", (4, 10))


ALL_TABLES = [ws.TOP, ws.GAIT, ws.IMPAIRMENT, ws.OUTPUT, ds.DEVICE, ds.ASSISTANCE, bs.TOP,
              bs.DEVICE, bs.BENCH, cs.CIRCUIT,
              device_source.RIG]


def _within(v, rng) -> bool:
    items = v if isinstance(v, (list, tuple)) else [v]
    return all(rng[0] <= x <= rng[1] for x in items)


def test_declared_defaults_lie_in_their_declared_ranges():
    for table in ALL_TABLES:
        for key in table.keys:
            if key.range is not None and key.default is not None:
                assert _within(key.default, key.range), (table.name, key)


def test_impairment_and_circuit_bench_keys_are_their_parameter_fields():
    """[impairment] declares WalkerParams fields; a circuit bench's settings are
    LoadBenchConfig fields, whose defaults lie in the declared ranges."""
    import dataclasses

    from afo_mj.human.walker import WalkerParams
    from afo_mj.scenarios.bench_protocols import LoadBenchConfig
    assert set(ws.IMPAIRMENT.names) <= {f.name for f in dataclasses.fields(WalkerParams)}
    default = LoadBenchConfig()
    settings = [bs.BENCH[name] for name in bs.LOAD_KEYS]
    assert {k.name for k in settings} <= {f.name for f in dataclasses.fields(default)}
    for k in settings:
        assert _within(getattr(default, k.name), k.range), k


@pytest.mark.parametrize("edit,key,table", [
    (lambda t: t.replace("[load]", "[load]\ninertia_kg_m3 = 1.0", 1), "load.inertia_kg_m3",
     "[load]"),
    (lambda t: t + "\n[calibration]\nsettle = 1.0\n", "calibration.settle", "[calibration]"),
    (lambda t: t + "\n[sensors.ankle_torque_nm]\nsignl = \"torque_nm\"\n",
     "sensors.ankle_torque_nm.signl", "[sensors.ankle_torque_nm]"),
])
def test_a_rig_file_table_refuses_an_unknown_key_in_the_common_format(tmp_path, edit, key,
                                                                      table):
    """The calibration rig file's [load], [calibration] and [sensors.<channel>] are declared
    in the schema layer too: one message format, with the closest key suggested."""
    from afo_mj.calibration.calibrate import load_calibration_scenario
    from afo_mj.hydraulics.params import ParameterError
    src = (Path(__file__).resolve().parents[1] / "scenarios" / "calibration"
           / "lab_rig.toml").read_text(encoding="utf-8")
    if "[calibration]" in src and "calibration.settle" in key:
        src = src.replace("[calibration]", "[calibration]\nsettle = 1.0", 1)
    else:
        src = edit(src)
    path = tmp_path / "rig.toml"
    path.write_text(src, encoding="utf-8")
    with pytest.raises(ParameterError, match=rf"unknown key '{re.escape(key)}' \(= .*\) "
                                             rf"\(did you mean .*allowed keys in "
                                             rf"{re.escape(table)}: "):
        load_calibration_scenario(str(path))
