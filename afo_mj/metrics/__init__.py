"""Metrics computed from simulated or measured records: gait cycles against a reference,
step and frequency responses, emulated stiffness, kinetics filtering for display and the
device's derived signals. Reads records; runs no simulation."""
