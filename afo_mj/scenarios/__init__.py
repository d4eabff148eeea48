"""Walking scenarios: TOML files validated into frozen :class:`WalkScenario` objects
(:mod:`afo_mj.scenarios.walk_scenario`)."""
