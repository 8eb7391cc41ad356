"""Every study says before it trains whether it can decide: the families its plan counts are the ones its report
tests, the seeds it asks for are computed by hand, an undecidable design is refused unless asked for, and
``--plan`` trains and writes nothing."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from helpers import invoke

from rlcompare.stats.design import GATE, INTERVAL, SIGNED_RANK, T_TEST, smallest_p
from rlcompare.studies.chess import endgames as endgame_study
from rlcompare.studies.chess import endgames_report
from rlcompare.studies.paper.study import MOUNTAIN_CAR
from rlcompare.studies.plans import Question, StudyPlan, Training
from rlcompare.studies.registry import ChessEndgameOptions, PaperOptions


def test_the_chess_endgames_family_is_the_one_its_report_tests() -> None:
    """The plan's family against the verdict table the report builds from runs of every configuration planned
    (each seed's measures drawn at random): one direction and one equivalence test a row."""
    options = ChessEndgameOptions(seeds=4, episodes=10)
    plan = endgames_report.study_plan(options)
    configs = endgame_study.study_configs(options)
    rng = np.random.default_rng(0)
    metrics = {name: pd.DataFrame({"seed": range(4), **{m: rng.random(4) for m in endgame_study.MEASURES}})
               for name in configs}
    runs = {name: SimpleNamespace(config=config) for name, config in configs.items()}
    table = endgames_report.verdicts(runs, metrics)  # type: ignore[arg-type]
    headline = plan.questions[0]
    assert headline.family == 2 * len(table) == 2 * 8 * 5
    assert (headline.test, headline.seeds) == (SIGNED_RANK, 4)
    assert plan.questions[1].test == GATE


def test_ten_endgame_seeds_cannot_decide_and_twelve_can() -> None:
    """80 tests: Holm asks 0.05/80 = 0.000625 of the smallest p; 2/2^11 = 0.00098 is above it, 2/2^12 = 0.00049
    below."""
    ten = endgames_report.study_plan(ChessEndgameOptions(seeds=10))
    assert ten.undecidable == (ten.questions[0],)
    assert ten.seeds_needed == 12
    line = ten.first_line()
    assert line.startswith("This design cannot decide SARSA against Q-Learning")
    assert "cannot give a p below 0.002, above the 0.00063 Holm asks over 80 tests; with --seeds 12 it can." in line
    assert not endgames_report.study_plan(ChessEndgameOptions(seeds=12)).undecidable


def test_the_paper_asks_its_ten_claims_of_mountain_car_and_eight_elsewhere() -> None:
    """Ten claims at 0.005 each: 8 seeds give 2/256 = 0.0078 (cannot), 9 give 0.0039 (can). Without Mountain Car's
    position and velocity the two first-action claims are not asked."""
    plan = MOUNTAIN_CAR.study_plan(PaperOptions(seeds=8, episodes=50))
    assert [(q.test, q.family) for q in plan.questions] == [(SIGNED_RANK, 10)]
    assert plan.undecidable
    assert plan.seeds_needed == 9
    assert not MOUNTAIN_CAR.study_plan(PaperOptions(seeds=9, episodes=50)).undecidable
    trained = {t.name: (t.seeds, t.amount, t.unit) for t in plan.trainings}
    assert trained["sarsa-decay"] == (8, 50, "episodes")
    assert len(trained) == 9
    from rlcompare.studies.paper.study import CARTPOLE

    assert CARTPOLE.study_plan(PaperOptions(seeds=9)).questions[0].family == 8
    without_sarsa = MOUNTAIN_CAR.study_plan(PaperOptions(seeds=2, algorithms="q_learning"))
    assert without_sarsa.questions == ()
    assert not without_sarsa.undecidable


@pytest.mark.parametrize(("test", "seeds", "family", "decides"), [
    (SIGNED_RANK, 5, 1, False),   # 2/32 = 0.0625 > 0.05
    (SIGNED_RANK, 6, 1, True),    # 2/64 = 0.031
    (GATE, 5, 1, True),           # 1/32 = 0.031
    (GATE, 4, 1, False),          # 1/16 = 0.0625
    (T_TEST, 2, 42, True),        # a t test's p has no floor from the seeds' order
    (INTERVAL, 1, 1, False),      # no interval from one seed
])
def test_a_question_decides_where_its_smallest_p_passes_holms_first_step(test, seeds, family, decides) -> None:
    question = Question("a", test, seeds, family)
    assert question.reach.can_decide is decides
    assert question.reach.smallest_p == smallest_p(test, seeds)


def test_a_plumbing_check_and_a_figure_decide_nothing_and_are_never_refused() -> None:
    tiny = (Question("a against b", SIGNED_RANK, 2),)
    assert StudyPlan((), tiny).undecidable == tiny
    plumbing = StudyPlan((Training("x", 2, 10, "episodes"),), tiny, plumbing="too short to learn")
    assert plumbing.undecidable == ()
    assert plumbing.first_line() == "A plumbing check: no verdict is possible (too short to learn)."
    assert StudyPlan(()).first_line() == "This design draws figures and tables; no test decides a question of it."
    assert "a against b" in StudyPlan((), (Question("a against b", SIGNED_RANK, 6),)).first_line()


def test_plan_prints_the_design_and_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "study"
    result = invoke("reproduce", "chess-endgames", "--seeds", "10", "--plan", "--out", str(out))
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("This design cannot decide")
    assert "KRK-optimal-sarsa-decay: 10 seeds x 150,000 episodes" in result.output
    assert not out.exists()


@pytest.mark.slow("trains a small paper study")
def test_an_undecidable_design_is_refused_unless_asked_for(tmp_path: Path) -> None:
    out = tmp_path / "study"
    refused = invoke("reproduce", "--seeds", "3", "--episodes", "5", "--no-videos", "--out", str(out))
    assert refused.exit_code == 2
    assert "cannot decide" in refused.output
    assert "--seeds 9" in refused.output
    assert "--allow-undecidable" in refused.output
    assert "Traceback" not in refused.output
    assert not out.exists()
    allowed = invoke("reproduce", "--seeds", "3", "--episodes", "5", "--no-videos", "--allow-undecidable",
                     "--out", str(out))
    assert allowed.exit_code == 0, allowed.output
    assert allowed.output.startswith("This design cannot decide")
    assert (out / "sarsa-decay").is_dir()


def test_a_sweeps_plan_lists_each_configuration_by_its_swept_values_and_writes_nothing(tmp_path: Path) -> None:
    sweep_file = Path(__file__).parents[2] / "examples" / "sweep.toml"
    out = tmp_path / "sweep"
    result = invoke("sweep", str(sweep_file), "--plan", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert "Trainings (25):" in result.output
    assert "algorithm=q_learning, schedule=decay, env=MountainCar-v0, alpha=0.05: 10 seeds x 1,000 episodes" in (
        result.output)
    assert not out.exists()


@pytest.mark.slow("imports JAX with the MinAtar study")
def test_minatar_trains_the_pair_by_default_and_its_ablations_when_asked() -> None:
    pytest.importorskip("jax")
    from rlcompare.deep.methods import DEEP_METHODS
    from rlcompare.studies.deep import minatar
    from rlcompare.studies.registry import MinAtarOptions
    from rlcompare.validation import ConfigError

    def methods(spec: str | None = None) -> tuple[str, ...]:
        options = MinAtarOptions() if spec is None else MinAtarOptions(methods=spec)
        return minatar.plan_of(options).methods

    assert methods() == ("pqn_sarsa_lambda", "pqn_q_lambda")
    assert methods("ablations") == ("pqn_sarsa_lambda", "pqn_q_lambda", "pqn_watkins_q_lambda", "pqn_sarsa",
                                    "pqn_q_learning")
    assert methods("all") == tuple(DEEP_METHODS)
    assert methods("dqn, ppo") == ("dqn", "ppo")
    with pytest.raises(ConfigError, match="'all', 'ablations' or a comma-separated list"):
        methods("ablationz")
