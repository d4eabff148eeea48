"""The application layer: what a user does with afo_mj, as functions returning typed results.

Each workflow (run a scenario, a bench, a comparison, a calibration, a design, a rendering)
loads and checks its input, runs the experiment, writes its results directory when asked and
returns a result object; bad input raises :class:`afo_mj.app.errors.InvalidInput` (exit 2,
nothing written) and a failed run :class:`afo_mj.app.errors.RunFailed` (exit 1, nothing
written). The command line (:mod:`afo_mj.cli`) parses arguments, calls these and prints;
sweeps and the optimiser call them in-process without figures.
"""
