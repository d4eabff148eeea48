"""Power flows a component reports, so circuits can close an energy balance.

Sign convention (all in W, arrays broadcast like the component's inputs):

* ``in_w``     power entering the component through its driving port (electrical, shaft or
  hydraulic, whichever is its input for the present direction of flow);
* ``out_w``    power leaving through its driven port;
* ``heat_w``   power dissipated as heat (always >= 0);
* ``stored_w`` rate of change of energy stored inside (compression, gas, spring, inductance,
  kinetic), positive when charging.

For each component ``in_w = out_w + heat_w + stored_w`` holds at every instant; tests check it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class PowerFlow(NamedTuple):
    in_w: np.ndarray | float
    out_w: np.ndarray | float
    heat_w: np.ndarray | float
    stored_w: np.ndarray | float = 0.0

    @property
    def residual_w(self):
        """``in - out - heat - stored``: zero for a consistent component."""
        return self.in_w - self.out_w - self.heat_w - self.stored_w
