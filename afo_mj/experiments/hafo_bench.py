"""The stand's torque–velocity protocol by HAFO parameter set, for callers that hold a
:class:`~afo_mj.devices.hafo.PumpAnkleParams` rather than a device spec (the design tool's
verification of a sized pump-controlled design, :mod:`afo_mj.design.system_design`). The
protocol itself is :func:`afo_mj.experiments.bench_stand.torque_velocity`."""

from __future__ import annotations

from afo_mj.devices.hafo import PumpAnkleParams, hafo_spec
from afo_mj.experiments import bench_stand
from afo_mj.scenarios.bench_protocols import BenchError

__all__ = ["torque_velocity"]


def torque_velocity(params: PumpAnkleParams, *args, **kwargs) -> tuple[dict, dict]:
    """:func:`afo_mj.experiments.bench_stand.torque_velocity` on the HAFO of ``params``."""
    if type(params) is not PumpAnkleParams:      # (a valve circuit's params subclass it)
        raise BenchError(f"params = {type(params).__name__}; allowed: a PumpAnkleParams "
                         "(afo_mj.devices.hafo.hafo_params({...}))")
    return bench_stand.torque_velocity(hafo_spec(params), *args, **kwargs)
