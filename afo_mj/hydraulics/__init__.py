"""Small-scale hydraulic component library (10–1000 W), pure Python/numpy, no MuJoCo.

Conventions every component module follows
------------------------------------------
* One component (or one closely related family) per module. Its parameters are a frozen
  dataclass derived from :class:`~afo_mj.hydraulics.params.Parameters`, fields declared with
  ``param(default, unit=..., lo=..., hi=...)`` in SI units with the unit in the name
  (``bore_m``, ``pressure_pa``); optional physical effects are ``effect(...)`` switches named
  ``*_enabled``. Bad values raise :class:`~afo_mj.hydraulics.params.ParameterError` at
  construction.
* Pressures are absolute Pa unless a name says ``gauge`` or ``dp`` (a difference).
* Component methods are vectorised: they take floats or numpy arrays and contain no Python
  branching on values (``np.where``/``np.clip`` instead), because circuits evaluate a batch of
  states at once to form their finite-difference Jacobian.
* Each component reports its power flows as a :class:`~afo_mj.hydraulics.power.PowerFlow`
  (``in_w = out_w + heat_w + stored_w``), so circuits can close an energy balance.
* Each equation's docstring states the equation, its source (seed section, standard, paper)
  and an example.
"""

from .params import (ParameterError, Parameters, effect_switches, flatten, param, effect,
                     replace_named)
from .power import PowerFlow
from .fluid import ATMOSPHERIC_PRESSURE_PA, Fluid, FluidParams, FLUID_PRESETS, ISO_VG32, ISO_VG46

__all__ = [
    "ParameterError", "Parameters", "effect_switches", "flatten", "param", "effect",
    "replace_named", "PowerFlow", "ATMOSPHERIC_PRESSURE_PA", "Fluid", "FluidParams",
    "FLUID_PRESETS", "ISO_VG32", "ISO_VG46",
]
