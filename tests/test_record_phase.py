"""The gait phase from recorded heel strikes (afo_mj.gait.record.phase_from_events, vectorised)
against a direct transcription of its definition: per leg, for every stride [a, b) → the
next [b, c), the phase in [b, c) is (t − b)/(b − a) clipped to [0, 1], 0 before the second
heel strike."""

from __future__ import annotations

import numpy as np

from afo_mj.gait.record import GaitEvents, phase_from_events


def _definition(time_s, events):
    out = np.zeros((len(time_s), 2))
    for s in range(2):
        hs = list(events.heel_strikes_s[s])
        for j in range(1, len(hs)):
            a, b = hs[j - 1], hs[j]
            c = hs[j + 1] if j + 1 < len(hs) else np.inf
            for i, t in enumerate(time_s):
                if b <= t < c:
                    out[i, s] = min(max((t - b) / (b - a), 0.0), 1.0)
    return out


def test_phase_from_events_is_its_definition():
    rng = np.random.default_rng(7)
    t = np.arange(3001) * 1e-3
    for _ in range(40):
        e = GaitEvents()
        for s in range(2):
            e.heel_strikes_s[s].extend(sorted(rng.uniform(0.0, 3.0, rng.integers(0, 6))
                                              .round(3).tolist()))
        assert np.array_equal(phase_from_events(t, e), _definition(t, e))
    # events exactly on samples, and none
    e = GaitEvents(heel_strikes_s=([0.5, 1.5, 2.5], []))
    got = phase_from_events(t, e)
    assert got[1499, 0] == 0.0 and got[1500, 0] == 0.0 and got[2500, 0] == 0.0
    assert abs(got[2499, 0] - 0.999) < 1e-12 and abs(got[3000, 0] - 0.5) < 1e-12
    assert not got[:, 1].any()
