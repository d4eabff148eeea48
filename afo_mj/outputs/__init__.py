"""Result files of a run: summary JSON, per-cycle CSV, mean-curve CSV and gait-curve figure,
written atomically (:mod:`afo_mj.outputs.gait_report`)."""
