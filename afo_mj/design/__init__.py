"""System design: requirements from gait, component models and the minimum-weight sizing
of a hydraulic orthosis."""
