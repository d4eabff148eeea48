"""The hand-written kernels the generated circuits replaced, kept as the tests' independent
reference (see :mod:`kernel_reference.kernel_devices`)."""
