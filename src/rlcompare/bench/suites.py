"""What each ``rlcompare bench`` command measures, stage by stage, and the file it writes: ``bench`` alone the
kernels, the paper's study and the ports into ``bench.json``; each subcommand its own stages into its own file. The
study's configurations come from the command line, which may import the studies."""

from __future__ import annotations

from rlcompare.bench.chess import CHESS_STAGE
from rlcompare.bench.kernels import KERNEL_STAGE
from rlcompare.bench.ports import PORT_STAGE
from rlcompare.bench.study import study_stage
from rlcompare.bench.sweeps import sweep_stage
from rlcompare.bench.tables import Measured, Stage, Suite
from rlcompare.tabular.config import ExperimentConfig


def default(study_configs: list[ExperimentConfig]) -> Suite:
    """``rlcompare bench``: the kernels, then the study of ``study_configs`` (the paper's), then the ports."""
    return Suite("bench.json", (KERNEL_STAGE, study_stage(study_configs), PORT_STAGE))


def kernels() -> Suite:
    """Every method's kernel on 1 and all threads against its reference kernel and a plain Gymnasium loop."""
    return Suite("kernels.json", (KERNEL_STAGE,))


def chess() -> Suite:
    """Q-Learning on the chess endgames, rlcompare's kernel beside a plain one."""
    return Suite("chess.json", (CHESS_STAGE,))


def selfplay() -> Suite:
    """Self-play on Gardner's minichess beside pgx's game alone (the ``deep`` extra)."""
    from rlcompare.bench.selfplay import SELFPLAY_STAGE

    return Suite("selfplay.json", (SELFPLAY_STAGE,))


def atari() -> Suite:
    """The Atari 2600 pipeline on Breakout: the emulator alone and through the engine's callback, then the learner's
    cost per agent step beside Stable-Baselines3. Without the ``atari`` extra, an ``ImportError`` that says how to
    install it."""
    try:
        import ale_py  # noqa: F401
    except ImportError as error:
        raise ImportError(f"the Atari benchmark needs the atari extra: pip install -e '.[atari]' ({error})") from None
    from rlcompare.bench.atari import atari_stages

    return Suite("atari.json", atari_stages())


def envs() -> Suite:
    """Every ported environment: Gymnasium's loop, the port, the adapter."""
    return Suite("envs.json", (PORT_STAGE,))


def study(configs: list[ExperimentConfig]) -> Suite:
    """A study's configurations (the paper's) as ``reproduce`` trains them, on 1 and all threads."""
    return Suite("study.json", (study_stage(configs),))


def sweeps(address: str | None = None) -> Suite:
    """Sweeps of short trials on the local backend and on Ray (the cluster at ``address``, or a new instance)."""
    return Suite("sweeps.json", (sweep_stage(address),))


def deep(to_score: bool = False) -> Suite:
    """The deep engine beside Stable-Baselines3 on Mountain Car and MinAtar's Breakout; with ``to_score``, the wall
    time to a greedy return of 475 on CartPole after them. Without the ``deep`` extra, the
    :class:`~rlcompare.deep.DeepUnavailable` (an ``ImportError``) that says how to install it."""
    from rlcompare.bench.deep import ENV, SCORE, SCORE_ENV, deep_table, score_table
    from rlcompare.bench.minatar import MINATAR_ENV, minatar_table

    stages: tuple[Stage, ...] = (
        Stage(f"the deep engine on {ENV} beside Stable-Baselines3", lambda say: Measured(deep_table())),
        Stage(f"the deep engine on {MINATAR_ENV} beside Stable-Baselines3", lambda say: Measured(minatar_table())))
    if to_score:
        stages += (Stage(f"the wall time to a greedy return of {SCORE:g} on {SCORE_ENV}, ours beside "
                         "Stable-Baselines3 (several minutes)", lambda say: Measured(score_table())),)
    return Suite("deep.json", stages)
