"""Gait: reference gait, gait events, controller, driver."""
