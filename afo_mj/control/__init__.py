"""Controllers of the orthoses: assistance profiles, gait-phase estimation."""
