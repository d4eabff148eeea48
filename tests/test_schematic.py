"""ISO 1219-1-style schematics (afo_mj.outputs.schematic, ``afo-mj schematic``): every shipped
circuit drawn and read back to the topology of its description, every catalogue kind with a
symbol of its own, the layout free of overlaps, the reader's checks, the command."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from afo_mj.app.schematic import SCENARIO_CIRCUITS, circuit_of, shipped_circuits
from afo_mj.circuits.catalogue import COMPONENT_KINDS
from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.components import BUS, HYDRAULIC, JOINT, SHAFT, Component
from afo_mj.circuits.controllers import OpenLoop
from afo_mj.circuits.library import LIBRARY
from afo_mj.devices.hafo import PRESETS
from afo_mj.devices.valve_afo import VALVE_PRESETS
from afo_mj.outputs.schematic import (LABELS, SYMBOLS, SchematicError, layout_problems,
                                      read_schematic_topology, schematic_svg, symbol_svg,
                                      write_schematic)

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = shipped_circuits(ROOT)


def _described(circuit) -> dict:
    """The topology as the description states it (the Circuit's own lists, not the
    drawing's)."""
    return {"components": {c.name: c.kind for c in circuit.components},
            "nodes": {node: set(refs) for node, refs in circuit.nodes.items()}}


def test_every_preset_library_and_scenario_circuit_is_shipped():
    names = set(SHIPPED)
    assert set(PRESETS) | set(VALVE_PRESETS) | set(LIBRARY) <= names
    assert {f"scenario_{Path(r).stem}" for r in SCENARIO_CIRCUITS} <= names


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_drawing_reads_back_to_the_description(name):
    circuit = SHIPPED[name]
    svg = schematic_svg(circuit, title=name)
    assert read_schematic_topology(svg) == _described(circuit)
    assert layout_problems(svg) == []
    # every port of every component is drawn on exactly one node
    drawn = [ref for refs in read_schematic_topology(svg)["nodes"].values() for ref in refs]
    ports = [f"{c.name}.{p}" for c in circuit.components for p in c.ports]
    assert sorted(drawn) == sorted(ports)


def test_scenario_circuit_reads_back_to_its_toml_text():
    # the reference is the TOML file itself, parsed here, not the Circuit built from it
    rel = SCENARIO_CIRCUITS[0]
    table = tomllib.loads((ROOT / rel).read_text(encoding="utf-8"))["circuit"]
    circuit, _ = circuit_of(str(ROOT / rel))
    got = read_schematic_topology(schematic_svg(circuit))
    assert got["components"] == {n: c["kind"] for n, c in table["components"].items()}
    assert got["nodes"] == {n: set(refs) for n, refs in table["nodes"].items()}


def test_every_catalogue_kind_has_its_own_symbol_and_labels():
    marks = {}
    for kind in COMPONENT_KINDS:
        assert kind in SYMBOLS, f"{kind}: no symbol (it would be drawn as the generic box)"
        assert kind in LABELS, f"{kind}: no key-parameter labels"
        name, markup = symbol_svg(kind)
        assert name == kind, f"{kind} falls back to the {name} symbol"
        marks[kind] = markup
    assert symbol_svg("no_such_kind")[0] == "generic"
    # no two kinds share a drawing
    by_markup = {}
    for kind, m in marks.items():
        assert m not in by_markup, f"{kind} is drawn as {by_markup.get(m)}"
        by_markup[m] = kind


def _every_kind_circuit():
    """One component of every catalogue kind, ports joined by domain (hydraulic ports dealt
    round four nodes): a topology no shipped circuit has."""
    comps, nodes = [], {"bus": [], "shaft": [], "ankle": []}
    hyd = [f"h{i}" for i in range(4)]
    for h in hyd:
        nodes[h] = []
    k = 0
    for kind, cls in COMPONENT_KINDS.items():
        c = cls(f"{kind}_1")
        comps.append(c)
        for port, dom in c.ports.items():
            if dom == HYDRAULIC:
                nodes[hyd[k % 4]].append(f"{c.name}.{port}")
                k += 1
            else:
                nodes[{BUS: "bus", SHAFT: "shaft", JOINT: "ankle"}[dom]].append(
                    f"{c.name}.{port}")
    return Circuit("every_kind", comps, nodes, OpenLoop())


def test_every_kind_in_one_circuit_is_drawn_with_its_symbol():
    circuit = _every_kind_circuit()
    svg = schematic_svg(circuit)
    assert read_schematic_topology(svg) == _described(circuit)
    assert layout_problems(svg) == []
    for kind in COMPONENT_KINDS:
        assert f'id="comp-{kind}_1" class="component" data-kind="{kind}" ' \
               f'data-symbol="{kind}"' in svg


class _Mystery(Component):
    kind = "mystery"
    ports = {"a": HYDRAULIC, "b": HYDRAULIC, "c": HYDRAULIC}


def test_unknown_kind_is_a_generic_labelled_box():
    circuit = _every_kind_circuit()
    comps = circuit.components + [_Mystery("odd")]
    nodes = {n: list(r) for n, r in circuit.nodes.items()}
    nodes["h0"] += ["odd.a"]
    nodes["h1"] += ["odd.b"]
    nodes["h2"] += ["odd.c"]
    c2 = Circuit("with_mystery", comps, nodes, OpenLoop())
    svg = schematic_svg(c2)
    assert 'id="comp-odd" class="component" data-kind="mystery" data-symbol="generic"' in svg
    assert ">kind mystery<" in svg
    assert read_schematic_topology(svg) == _described(c2)


def test_labels_carry_key_parameters_with_units():
    svg = schematic_svg(SHIPPED["hafo"])
    for text in ("0.2 cm³/rev (gear)", "1.1 m × Ø3.2 mm", "cracks at 140 bar",
                 "2 × Ø10.4 mm, stroke 45 mm", "pulley r 40 mm", "15 bar"):
        assert text in svg, text


def test_reader_refuses_a_drawing_that_does_not_join_up():
    svg = schematic_svg(LIBRARY["lab_bench"]())
    # a stub claiming another node's port: the node's data-ports no longer match its stubs
    bad = svg.replace('data-node="line_a" data-ports="pump.a"',
                      'data-node="line_a" data-ports="pump.b"', 1)
    assert bad != svg
    with pytest.raises(SchematicError, match="line_a"):
        read_schematic_topology(bad)
    # a junction line moved away from the stubs that end on it
    start = svg.index('class="w-hydraulic wire" data-node="chamber_a"')
    x1 = svg.index('x1="', start) + 4
    end = svg.index('"', x1)
    moved = svg[:x1] + str(float(svg[x1:end]) + 40) + svg[end:]
    with pytest.raises(SchematicError, match="chamber_a"):
        read_schematic_topology(moved)


def test_png_written_or_refused_with_the_reason(tmp_path):
    try:
        import cairosvg  # noqa: F401
        have = True
    except (ImportError, OSError):
        have = False
    out = tmp_path / "c.png"
    if have:
        write_schematic(LIBRARY["spring_return"](), out)
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    else:
        with pytest.raises(SchematicError, match="cairosvg"):
            write_schematic(LIBRARY["spring_return"](), out)
        assert not out.exists()
    with pytest.raises(SchematicError, match=r"\.svg or \.png"):
        write_schematic(LIBRARY["spring_return"](), tmp_path / "c.pdf")


def test_cli_draws_a_scenario_and_refuses_bad_input(tmp_path, capsys):
    from afo_mj.cli import main
    out = tmp_path / "bench.svg"
    assert main(["schematic", str(ROOT / "scenarios/bench_lab_bench.toml"), "--out",
                 str(out)]) == 0
    assert read_schematic_topology(out.read_text()) == _described(LIBRARY["lab_bench"]())
    # a [device] preset with its params overrides
    out2 = tmp_path / "phafo.svg"
    assert main(["schematic", str(ROOT / "scenarios/stiffness_bench.toml"), "--out",
                 str(out2)]) == 0
    assert "cracks at 155 bar" in out2.read_text()
    capsys.readouterr()
    for argv in (["schematic", "no_such_circuit", "--out", str(tmp_path / "x.svg")],
                 ["schematic", str(ROOT / "scenarios/gait_muscle_clutched_spring.toml"),
                  "--out", str(tmp_path / "x.svg")],
                 ["schematic", str(ROOT / "scenarios/walk_healthy.toml"), "--out",
                  str(tmp_path / "x.svg")],
                 ["schematic", "hafo", "--out", str(tmp_path / "x.pdf")]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("afo-mj schematic: "), err
    assert not (tmp_path / "x.svg").exists() and not (tmp_path / "x.pdf").exists()


def test_a_device_run_writes_the_schematic_of_the_circuit_it_wore(tmp_path):
    """``afo-mj run`` of a device scenario writes ``circuit.svg``: the worn circuit (here the
    lab bench under the scenario's pump_torque override, read from the TOML text), drawn and
    read back to its description."""
    from afo_mj.app.run import run_scenario
    rel = ROOT / "scenarios" / "gait_lab_bench.toml"
    run_scenario(rel, overrides=["gait.strides=2", "gait.analyse_strides=[1, 2]",
                                 'device.conditions=["transparent"]'],
                 out_dir=tmp_path / "r", figures=False)
    got = read_schematic_topology((tmp_path / "r" / "circuit.svg").read_text(encoding="utf-8"))
    lab = LIBRARY["lab_bench"]()
    assert got == _described(lab)
    ctrl = tomllib.loads(rel.read_text(encoding="utf-8"))["circuit"]["controller"]["kind"]
    assert ctrl == "pump_torque"


def test_the_command_takes_overrides_as_run_does(tmp_path):
    """``afo-mj schematic hafo --set device.params.hose.length_m=2.2`` draws the HAFO with its
    2.2 m hoses (the hose label states length and bore); a walking scenario takes scenario
    keys; a key that is no device parameter of a preset is refused, nothing written."""
    from afo_mj.cli import main
    out = tmp_path / "h.svg"
    assert main(["schematic", "hafo", "--out", str(out), "--quiet",
                 "--set", "device.params.hose.length_m=2.2"]) == 0
    assert "2.2 m × Ø3.2 mm" in out.read_text(encoding="utf-8")
    assert "2.2 m" not in schematic_svg(SHIPPED["hafo"])
    out2 = tmp_path / "v.svg"
    scen = ROOT / "scenarios" / "gait_assist_hafo.toml"
    assert main(["schematic", str(scen), "--out", str(out2), "--quiet",
                 "--set", "device.params.hose.length_m=1.7"]) == 0
    assert "1.7 m" in out2.read_text(encoding="utf-8")
    bad = tmp_path / "x.svg"
    assert main(["schematic", "hafo", "--out", str(bad), "--quiet",
                 "--set", "gait.strides=3"]) == 2
    assert not bad.exists()
