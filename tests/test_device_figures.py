"""Device-run figures: one short HAFO gait scenario (3 conditions), every PNG written and drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from afo_mj.outputs.device_figures import DEVICE_FIGURES, plot_device_run
from afo_mj.experiments.device_walk import run_device_scenario
from afo_mj.scenarios.device_scenario import device_config
from afo_mj.scenarios.walk_scenario import load_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "gait_assist_hafo.toml"


@pytest.fixture(scope="module")
def device_run():
    sc = load_scenario(SCENARIO, overrides=["gait.strides=3", "gait.analyse_strides=[2, 3]"])
    cfg = device_config(sc)
    ref = sc.load_reference()
    summary, results = run_device_scenario(sc, ref, cfg)
    return summary, results, ref


def _check_png(path: Path) -> None:
    import matplotlib.image as mpimg
    assert path.is_file()
    data = path.read_bytes()
    assert data[:4] == b"\x89PNG"
    assert len(data) > 10_000
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 300
    assert float(np.std(img[..., :3])) > 0.05          # not blank
    # something drawn beyond the white background: a fair share of non-white pixels
    assert float(np.mean(np.any(img[..., :3] < 0.9, axis=-1))) > 0.02


def test_all_figures_written(device_run, tmp_path):
    summary, results, ref = device_run
    assert set(results) == {"no_device", "transparent", "assist"}
    assert all(a is not None for _, a, _ in results.values())
    paths = plot_device_run(tmp_path / "out", results, ref, summary, "gait_assist_hafo: test")
    assert [p.name for p in paths] == list(DEVICE_FIGURES)
    assert all(p.parent == tmp_path / "out" for p in paths)
    for p in paths:
        _check_png(p)


def test_condition_without_analysis_is_skipped(device_run, tmp_path):
    summary, results, ref = device_run
    rec, _, dev = results["assist"]
    partial = dict(results, assist=(rec, None, dev))      # the walker "fell" with assistance
    paths = plot_device_run(tmp_path, partial, ref, summary, "t")
    assert [p.name for p in paths] == list(DEVICE_FIGURES)   # transparent still has a device
    for p in paths:
        _check_png(p)
    only_no_device = {"no_device": results["no_device"]}
    paths = plot_device_run(tmp_path / "nd", only_no_device, ref, summary, "t")
    assert [p.name for p in paths] == ["ankle_angle_conditions.png"]
    _check_png(paths[0])
    assert plot_device_run(tmp_path / "none", {"assist": (rec, None, dev)}, ref, summary,
                           "t") == []
