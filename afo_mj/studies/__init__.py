"""Parameter studies: the study description, the resumable parallel sweep, the optimiser
and the study report (ranking, Pareto front, sensitivity indices)."""
