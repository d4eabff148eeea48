"""docs/circuits.md: the catalogue section is the code's, and the worked example runs."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from afo_mj.circuits.catalogue import COMPONENT_KINDS, CONTROLLER_KINDS, catalogue_markdown

DOC = Path(__file__).resolve().parents[1] / "docs" / "circuits.md"


def test_catalogue_section_is_current():
    text = DOC.read_text()
    section = text.split("<!-- catalogue:begin -->\n")[1].split("<!-- catalogue:end -->")[0]
    assert section == catalogue_markdown(), (
        "docs/circuits.md's catalogue is stale: regenerate it from "
        "afo_mj.circuits.catalogue.catalogue_markdown()")
    for kind in COMPONENT_KINDS:
        assert f"### `{kind}`" in section
    for kind in CONTROLLER_KINDS:
        assert f"### controller `{kind}`" in section


@pytest.mark.slow
def test_worked_example_runs_and_settles_on_the_spring(capsys):
    """The example as a user copies it: it builds, runs, closes its ledger, and the foot
    ends where the spring balances the cylinder (torque = k θ within the damper's share)."""
    code = re.search(r"```python\n(.*?)```", DOC.read_text(), re.S).group(1)
    scope: dict = {}
    exec(compile(code, str(DOC), "exec"), scope)
    log, ledger = scope["log"], scope["ledger"]
    assert abs(ledger["balance_error_rel"]) < 1e-9
    theta, tau, thd = log["angle_rad"][-1], log["torque_nm"][-1], log["velocity_rad_s"][-1]
    # load: J θ̈ = τ − k θ − c θ̇; at the end the foot is nearly still
    assert tau == pytest.approx(50.0 * theta + 0.5 * thd, rel=0.05)
    assert np.degrees(theta) < -5.0          # line a pressurised: plantarflexion
    assert "ledger residual" in capsys.readouterr().out
