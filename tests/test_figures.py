"""Every scenario kind writes its figures next to ``summary.json``: each PNG named in
:data:`afo_mj.outputs.device_figures.FIGURES_BY_KIND` exists, is a valid PNG of a sensible
size and is not blank. One short run per kind (module-scoped fixtures), through the CLI.

Their look is checked by eye; samples are kept in ``docs/figures/`` (README there).
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from afo_mj import cli
from afo_mj.outputs.device_figures import DEVICE_FIGURES, FIGURES_BY_KIND

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios"
SHORT = ["--set", "gait.strides=3", "--set", "gait.analyse_strides=[2, 3]"]

#: kind -> (CLI arguments after the command, command): one short run each
RUNS = {
    "walk": ("run", [str(SCEN / "walk_healthy.toml"), *SHORT]),
    "device_hafo": ("run", [str(SCEN / "gait_assist_hafo.toml"), *SHORT]),
    "device_valve": ("run", [str(SCEN / "gait_assist_valve.toml"), *SHORT]),
    "device_stiffness_emulation": ("run", [str(SCEN / "gait_stiffness_emulation.toml"),
                                           *SHORT]),
    # the HAFO bench's four tests in full take ~15 s; all four are kept (each draws a figure)
    "bench_hafo": ("run", [str(SCEN / "bench_hafo.toml")]),
    # two stiffnesses, two cycles: the figures' content is the same kind
    "bench_stiffness": ("run", [str(SCEN / "stiffness_bench.toml"), "--set",
                                "bench.stiffnesses_nm_per_deg=[1.0, 4.6]", "--set",
                                "bench.cycles=2"]),
    "compare": ("compare", [str(SCEN / "gait_assist_hafo.toml"), "--strides", "3"]),
}


def test_every_kind_is_run_here():
    assert set(RUNS) == set(FIGURES_BY_KIND)
    for kind in ("device_hafo", "device_valve", "device_stiffness_emulation"):
        assert set(DEVICE_FIGURES) <= set(FIGURES_BY_KIND[kind])


#: the longest runs (the HAFO bench in full, ~11 s; the stiffness emulator's walks, ~8 s) are
#: checked in the full suite only; -m "not slow" checks the other kinds
SLOW_KINDS = ("bench_hafo", "device_stiffness_emulation")


@pytest.fixture(scope="module", params=[pytest.param(k, marks=pytest.mark.slow)
                                        if k in SLOW_KINDS else k for k in RUNS])
def run_dir(request, tmp_path_factory):
    kind = request.param
    command, args = RUNS[kind]
    out = tmp_path_factory.mktemp(kind) / "out"
    buf_out, buf_err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf_out), contextlib.redirect_stderr(buf_err):
        rc = cli.main([command, *args, "--out", str(out)])
    assert rc == 0, buf_err.getvalue()
    return kind, out


def _check_png(path: Path) -> None:
    import matplotlib.image as mpimg
    assert path.is_file(), f"{path.name} not written"
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name} is not a PNG"
    assert 10_000 < len(data) < 3_000_000, f"{path.name}: {len(data)} bytes"
    img = mpimg.imread(path)
    assert img.ndim == 3, path.name
    h, w = img.shape[:2]
    assert 300 <= h <= 3000 and 300 <= w <= 4000, f"{path.name}: {w}x{h} px"
    rgb = img[..., :3]
    assert float(np.std(rgb)) > 0.05, f"{path.name} is blank"
    # drawn beyond the white background and the axes: a fair share of non-white pixels,
    # and some colour (curves, bars), not only black text on white
    assert float(np.mean(np.any(rgb < 0.9, axis=-1))) > 0.02, f"{path.name} nearly empty"
    chroma = rgb.max(axis=-1) - rgb.min(axis=-1)
    assert float(np.mean(chroma > 0.2)) > 0.002, f"{path.name} has no coloured data"


def test_figures_written_next_to_summary(run_dir):
    kind, out = run_dir
    summary = "comparison.json" if kind == "compare" else "summary.json"
    assert (out / summary).is_file()
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert set(FIGURES_BY_KIND[kind]) <= set(pngs), (kind, pngs)
    for name in FIGURES_BY_KIND[kind]:
        _check_png(out / name)
    # nothing drawn that the table does not list (keeps FIGURES_BY_KIND the documentation)
    assert set(pngs) == set(FIGURES_BY_KIND[kind]), (kind, pngs)
