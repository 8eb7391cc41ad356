"""``rlcompare uci RUN_DIR``: a network trained at chess as a UCI engine on standard input and output.

A chess program starts the engine and sends ``uci`` at once, and python-chess's client gives up after 10 s, so
:func:`rlcompare.cli.main` builds this command alone (:func:`uci_app`), without the other commands' imports, and the
command checks the run from its ``config.json`` alone: nothing of JAX is imported before ``uciok``. The network is
loaded and compiled at ``isready`` (:class:`rlcompare.players.uci.Deferred`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from rlcompare.cli.app_help import SUMMARIES, PlainCommand, new_app

NETWORK_STAGES = ("early", "middle", "final")
"""The stages of learning a deep run keeps (:data:`rlcompare.deep.rollout.STAGES` and ``final``), named here so that
``uci`` checks its options without importing JAX."""


def refusal(config: dict[str, Any]) -> str | None:
    """Why ``config`` (a run's ``config.json``) is not a run ``uci`` serves, or None for a deep run of chess."""
    from rlcompare.envs.chess.endgames import ENDGAMES

    env, seeds = config.get("env"), config.get("seeds") or []
    if isinstance(env, str) and env.split(":")[0] in ENDGAMES:
        return (f"a table learnt in the {env.split(':')[0]} endgame, which plays White's moves in that endgame only; "
                "allowed: a run of a network trained at chess")
    if env != "chess" or config.get("engine", "deep") != "deep" or not seeds:
        return f"a run of {env or 'nothing rlcompare reads'}; allowed: a run of a network trained at chess"
    return None


def uci(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", help="A run directory of a network trained at chess "
                                                                   "(rlcompare reproduce chess --game chess).")],
    seed: Annotated[int | None, typer.Option(help="Which seed's network (default: the run's first).")] = None,
    stage: Annotated[str, typer.Option(help="Which stage of learning: early, middle or final.")] = "final",
) -> None:
    """Serve a network trained at chess as a UCI engine on standard input and output: cutechess-cli, a GUI or
    python-chess's engine client runs it as 'rlcompare uci RUN_DIR'. Malformed input is answered with an 'info
    string' line, never a crash."""
    import sys

    from rlcompare.experiment import store
    from rlcompare.players.uci import Deferred, serve

    if not run_dir.is_dir():
        raise typer.BadParameter(f"{run_dir} is not a directory; allowed: a run directory of a network trained at "
                                 "chess", param_hint="'RUN_DIR'")
    store.refuse_while_written(run_dir)  # a run being trained names its writer, as report does
    config = store.read_json(run_dir / "config.json") if (run_dir / "config.json").is_file() else {}
    refused = refusal(config)
    if refused:
        raise typer.BadParameter(f"{run_dir} holds {refused}", param_hint="'RUN_DIR'")
    seeds = config["seeds"]
    if stage not in NETWORK_STAGES:
        raise typer.BadParameter(f"got {stage!r}; allowed: {', '.join(NETWORK_STAGES)}", param_hint="'--stage'")
    if seed is not None and seed not in seeds:
        raise typer.BadParameter(f"got {seed}; allowed: one of the run's seeds ({', '.join(map(str, seeds))})",
                                 param_hint="'--seed'")
    chosen = seeds[0] if seed is None else seed
    name = f"rlcompare {config.get('algorithm')}-chess seed {chosen} {stage}"  # the agent's own name, unloaded
    serve(Deferred(name, lambda: load(run_dir, chosen, stage)), sys.stdin, sys.stdout)


def load(run_dir: Path, seed: int, stage: str) -> Any:
    """The run's agent, JAX imported here (at ``isready``). Every program it compiles, pgx's many small ones at
    import included, is kept in JAX's persistent cache, so that a later start reads them: ``readyok`` came 3.9-4.5 s
    after ``isready`` here, not 8.7-10 s."""
    import jax

    from rlcompare.deep import use_compilation_cache
    from rlcompare.experiment.engines import load_agent

    use_compilation_cache()
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # this process's setting only
    return load_agent(run_dir, seed, stage)


def uci_app() -> typer.Typer:
    """The ``rlcompare`` app with ``uci`` alone: what ``rlcompare uci ...`` runs."""
    from rlcompare.cli.console import one_line_errors

    app = new_app()
    app.command("uci", short_help=SUMMARIES["uci"], cls=PlainCommand)(one_line_errors(uci))
    return app
