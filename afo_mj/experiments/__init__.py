"""Experiments that run the models: bench protocols on the ankle test stand, circuit benches,
frequency sweeps, the compiled bench replay and the device comparison."""
