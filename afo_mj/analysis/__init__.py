"""Analysis of simulated gait: per-cycle metrics, mean ± SD over strides, comparison with a
reference gait (:mod:`afo_mj.analysis.gait_metrics`)."""
