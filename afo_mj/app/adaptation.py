"""``afo-mj adapt``: the adapted wearer of each condition by several independent searches,
with convergence checked and the restart-to-restart spread and the paired change against the
control reported (:mod:`afo_mj.studies.adaptation`); resumable (run again with the same
``--out`` to continue every search).

The conditions are either :data:`afo_mj.experiments.muscle_assistance.KINDS` (``none``, the
control, added first when not listed), started from ``--start`` (default the shipped
converged control, ``afo_mj/data/adapted/none.json``), or one muscle-walker scenario file
whose conditions (``no_device`` first) wear its device, started from its
``walker.reflex_set`` unless ``--start`` is given.

Raises :class:`~afo_mj.app.errors.InvalidInput` (exit 2, nothing written) for an option out of
range (named as the option), an unknown condition, kinds mixed with a scenario, a start that is
not a reflex set, an unreachable Dask scheduler, or a folder whose searches were started with
other settings.
"""

from __future__ import annotations

from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["adapt", "DEFAULT_START"]

#: the converged no-device wearer every assistance condition adapts from
DEFAULT_START = Path(__file__).resolve().parents[1] / "data" / "adapted" / "none.json"

#: protocol field -> option name, for messages
_OPTIONS = {"restarts": "--restarts", "generations": "--generations", "popsize": "--popsize",
            "sigma0": "--sigma0", "seed": "--seed", "window": "--window",
            "cost_tol": "--cost-tol", "spread_target_pct": "--spread-target-pct",
            "search_walk_s": "--search-walk-s", "score_walk_s": "--score-walk-s",
            "groups": "--groups"}


def _protocol(kw: dict):
    from afo_mj.studies.adaptation import AdaptationProtocol
    try:
        return AdaptationProtocol(**kw)
    except ValueError as exc:
        msg = str(exc)
        for field, opt in _OPTIONS.items():
            msg = msg.replace(f"AdaptationProtocol.{field} ", f"{opt} ")
        raise InvalidInput(msg) from None


def adapt(conditions, out, restarts: int = 3, generations: int = 100, popsize: int = 16,
          sigma0: float = 0.04, seed: int = 1, window: int = 10, cost_tol: float = 0.01,
          spread_target_pct: float = 1.0, search_walk_s: float = 16.0,
          score_walk_s: float = 20.0, groups: int = 1, start: str | None = None,
          workers: int | None = None,
          dask: str | None = None, overrides=None, progress=None):
    """Run (or continue) the protocol into ``out`` for ``conditions`` (kinds, or one scenario
    file); returns the :class:`~afo_mj.studies.adaptation.AdaptationResult` (also written to
    ``out/adaptation.json``). ``dask``: a Dask scheduler's address, or ``"local"`` for a
    local cluster of ``workers`` processes; ``progress(text)`` told of each search (default:
    a stage line on the progress reporter, stderr)."""
    from afo_mj import progress as _progress
    from afo_mj.studies import adaptation as ad
    stage = progress or _progress.reporter().stage
    protocol = _protocol(dict(restarts=restarts, generations=generations, popsize=popsize,
                              sigma0=sigma0, seed=seed, window=window, cost_tol=cost_tol,
                              spread_target_pct=spread_target_pct,
                              search_walk_s=search_walk_s, score_walk_s=score_walk_s,
                              groups=groups))
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise InvalidInput(f"--workers = {workers!r}; allowed: an integer >= 1")
    conditions = list(conditions or [])
    files = [c for c in conditions if c.endswith(".toml") or Path(c).is_file()]
    if not conditions:
        raise InvalidInput("no condition given; allowed: assistance kinds (none, worn_mass, "
                           "zhang, clutched_spring, hafo) or one muscle-walker scenario file")
    if files and len(conditions) > 1:
        raise InvalidInput(f"conditions {conditions!r}; allowed: assistance kinds, or one "
                           "scenario file alone (its conditions are the scenario's)")
    if overrides and not files:
        raise InvalidInput(f"--set = {overrides!r} without a scenario file; allowed: with a "
                           "scenario file only")
    try:
        if files:
            if not Path(files[0]).is_file():
                raise InvalidInput(f"scenario {files[0]}: no such file")
            conds, scenario_start = ad.scenario_conditions(files[0], protocol, overrides or ())
            start = start or scenario_start
        else:
            conds = ad.assistance_conditions(conditions, protocol)
            start = start or str(DEFAULT_START)
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    try:
        ad.load_reflex_set(start)
    except (OSError, ValueError, KeyError) as exc:
        raise InvalidInput(f"--start {start}: {exc}") from None
    client = cluster = None
    if dask:
        from afo_mj.studies.sweep import connect_scheduler
        try:
            client = connect_scheduler(dask)
        except ValueError as exc:
            raise InvalidInput(str(exc).replace("--scheduler", "--dask")) from None
        if client is None:                      # "local": a cluster on this machine
            from distributed import Client, LocalCluster
            from afo_mj.experiments.batch import default_workers
            cluster = LocalCluster(n_workers=workers or default_workers(),
                                   threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
    try:
        return ad.adapt_conditions(out, conds, start, protocol, workers=workers,
                                   client=client,
                                   progress=lambda m: stage(f"adapt: {m}"))
    except ValueError as exc:
        raise InvalidInput(str(exc)) from None
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
