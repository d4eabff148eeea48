"""Closing the loop with measured data: load a bench record, replay it through the model,
fit declared parameters, search the effect library for what the model lacks and report the
error before and after."""
