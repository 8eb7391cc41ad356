"""The deep study through the CLI at a tiny size, its run directories, resuming, agents in Gymnasium, bad input."""

import json
import sys

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("jax")

import gymnasium as gym
import jax
import jax.numpy as jnp
from helpers import assert_loaded_not_trained, invoke, study_fixture

from rlcompare import load_agent
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.envs import jax_env
from rlcompare.deep.train import compiled_program
from rlcompare.experiment import store
from rlcompare.experiment.engines import load_run
from rlcompare.experiment.runner import run as deep_run
from rlcompare.studies.interface import UI
from rlcompare.validation import ConfigError

TINY = ["reproduce", "deep", "--allow-undecidable", "--seeds", "2", "--steps", "41000", "--episodes", "50", "--methods",
        "pqn_q_lambda,pqn_sarsa_lambda", "--envs", "CartPole-v1"]


study = study_fixture("deep", *TINY)


@pytest.mark.slow("trains and reports a deep study")
def test_the_study_writes_run_directories_and_a_report(study):
    out, output = study
    names = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert names == ["figures", "pqn_q_lambda-CartPole-v1", "pqn_sarsa_lambda-CartPole-v1", "tables",
                     "tabular-q_learning-CartPole-v1", "tabular-sarsa-CartPole-v1"]
    config = json.loads((out / "pqn_sarsa_lambda-CartPole-v1" / "config.json").read_text())
    assert (config["algorithm"], config["resolved"]["target"], config["resolved"]["total_steps"]) == (
        "pqn_sarsa_lambda", "sample", 41000)
    verdicts = pd.read_csv(out / "tables" / "deep_verdicts.csv")
    assert verdicts[["engine", "metric"]].to_numpy().tolist() == [["network", "final greedy return"],
                                                                  ["network", "area under the greedy curve"],
                                                                  ["table", "final greedy return"]]
    assert "CartPole-v1, network, final greedy return:" in output
    assert (out / "report.html").read_text().count("<img") == 2  # steps and seconds, CartPole only


@pytest.mark.slow("trains and reports a deep study")
def test_episodes_are_recorded_with_the_step_at_which_they_ended(study):
    results = load_run(study[0] / "pqn_q_lambda-CartPole-v1")
    for _, episodes in results.episodes.groupby("seed"):
        assert np.all(np.diff(episodes["env_step"].to_numpy()) >= 0)
        assert episodes["episode"].tolist() == list(range(len(episodes)))
        np.testing.assert_array_equal(episodes["return"], episodes["length"])  # CartPole pays 1 a step
    assert results.episodes["env_step"].max() <= 41000
    rounds = results.evaluations.groupby("seed")["round"].nunique()
    assert rounds.tolist() == [20, 20]


@pytest.mark.slow("trains and reports a deep study")
def test_a_finished_study_is_loaded_not_trained_again(study):
    out, _ = study
    assert_loaded_not_trained(out, *TINY, runs=4)


@pytest.mark.slow("trains and reports a deep study")
def test_a_deep_agent_acts_in_gymnasium_as_in_the_port(study):
    """The greedy agent from the run directory takes the same actions on Gymnasium's observations as on the
    port's, and both environments give the same episode."""
    agent = load_agent(study[0] / "pqn_q_lambda-CartPole-v1", seed=1)
    env, port = gym.make("CartPole-v1"), jax_env("CartPole-v1")
    observation, _ = env.reset(seed=3)
    state = port.reset(jax.random.key(0))._replace(physics=jnp.asarray(env.unwrapped.state, jnp.float64))
    done, length = False, 0
    while not done:
        action = agent.act(observation)
        assert action == agent.act(np.asarray(port.observe(state)))
        observation, _, terminated, truncated, _ = env.step(action)
        state, _, port_terminated, port_truncated = port.step(state, action)
        np.testing.assert_array_equal(np.asarray(port.observe(state)), observation)
        assert (bool(port_terminated), bool(port_truncated)) == (terminated, truncated)
        done, length = terminated or truncated, length + 1
    assert length > 0
    with pytest.raises(ValueError, match="observation"):
        agent.act(np.zeros(3))


@pytest.mark.slow("trains and reports a deep study")
def test_a_seed_gives_the_same_results_whatever_seeds_train_beside_it(study):
    config = DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1", seeds=(0, 1),
                        hyperparameters={"total_steps": 41000}, vmap_width=2)
    stored = load_run(study[0] / "pqn_q_lambda-CartPole-v1")
    shared = compiled_program.cache_info().hits
    alone = deep_run(DeepConfig(**{**config.__dict__, "seeds": (1,)}))  # padded with a copy of itself
    assert compiled_program.cache_info().hits == shared + 1  # the study's program, not traced again
    pd.testing.assert_frame_equal(alone.episodes, stored.episodes[stored.episodes["seed"] == 1].reset_index(drop=True))
    for name, values in alone.params.items():
        np.testing.assert_array_equal(values[0], stored.params[name][1])


@pytest.mark.parametrize(("arguments", "named"), [
    (["--methods", "pqn_q_lambda,nope"], "--methods"),
    (["--envs", "Pong-v5"], "--envs"),
    (["--steps", "100"], "--steps"),
])
def test_bad_input_is_one_message_naming_the_option(tmp_path, arguments, named):
    result = invoke("reproduce", "deep", "--allow-undecidable", "--seeds", "2", *arguments, "--out",
                    str(tmp_path / "x"), columns=None)
    assert result.exit_code == 2
    assert named in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(("fields", "named"), [
    ({"algorithm": "a2c"}, "algorithm"),
    ({"env": "Pong-v5"}, "env"),
    ({"preset": "huge"}, "preset"),
    ({"hyperparameters": {"lam": "high"}}, "hyperparameters.lam"),
    ({"hyperparameters": {"target": "sample"}}, "hyperparameters.target"),
    ({"hyperparameters": {"widths": [3]}}, "hyperparameters.widths"),
    ({"seeds": ()}, "seeds"),
])
def test_bad_deep_configurations_name_the_field(fields, named):
    with pytest.raises(ConfigError, match=named.replace(".", r"\.")):
        DeepConfig(**fields)


def test_without_jax_the_deep_study_says_how_to_install_it(monkeypatch, tmp_path):
    import rlcompare.studies

    needing_jax = ("deep", "minatar", "paired", "paired_report", "seed_blocks")
    for name in [m for m in sys.modules if m.startswith(("rlcompare.deep", *(f"rlcompare.studies.{study}"
                                                                              for study in needing_jax)))]:
        monkeypatch.delitem(sys.modules, name)
    for study in needing_jax:
        monkeypatch.delattr(rlcompare.studies, study, raising=False)
    monkeypatch.setitem(sys.modules, "jax", None)
    result = invoke("reproduce", "deep", "--allow-undecidable", "--out", str(tmp_path / "x"), columns=None)
    assert result.exit_code == 2
    assert "pip install -e '.[deep]'" in result.output
    assert "Traceback" not in result.output


@pytest.mark.slow("trains and reports a deep study")
def test_a_run_written_before_a_setting_was_added_loads_when_the_default_keeps_what_it_did(study, tmp_path):
    """A method's setting added later (PPO's value_loss, DQN's optimizer) has the default that keeps the old
    behaviour: a run directory without it reads as the configuration it was; one missing a setting its preset
    changed does not."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(study[0] / "pqn_q_lambda-CartPole-v1", run)
    config_file = run / "config.json"
    written = json.loads(config_file.read_text())
    assert written["resolved"]["gamma"] == 0.99  # PQNConfig's own default
    assert written["resolved"]["n_envs"] != 32  # the preset's, not the default

    def rewrite(config: dict) -> None:
        """config.json as an older rlcompare wrote it, recorded in meta.json as it would have been."""
        from rlcompare.experiment import rundir

        config_file.write_text(json.dumps(config))
        meta = json.loads((run / "meta.json").read_text())
        meta["contents"]["files"]["config.json"] = rundir._record_of(config_file)
        (run / "meta.json").write_text(json.dumps(meta))

    rewrite({**written, "resolved": {k: v for k, v in written["resolved"].items() if k != "gamma"}})
    loaded = load_run(run, DeepConfig.from_dict(written))
    assert loaded.config.method_config().gamma == 0.99

    rewrite({**written, "resolved": {k: v for k, v in written["resolved"].items() if k != "n_envs"}})
    with pytest.raises(store.StoreError, match="not what its preset gives now"):
        load_run(run)


@pytest.mark.slow("trains and reports a deep study")
def test_the_study_killed_with_sigkill_resumes_to_the_same_numbers(study, tmp_path):
    """``reproduce deep`` killed once one run of a network finished: the same command loads the finished runs,
    trains the rest, and every run equals the uninterrupted study's, episode by episode and parameter by
    parameter; its verdicts are the same bytes. It trains one network at a time, so the second is still compiling
    or training when the first is seen finished. The killed command runs in a process of its own (SIGKILL is what
    is tested); the same command resumes in this one (its lock left by a dead process)."""
    from helpers import assert_same_runs, finished_runs, kill_when, start

    killed, log = tmp_path / "killed", tmp_path / "killed.log"
    arguments = [*TINY, "--workers", "1", "--out", str(killed)]
    kill_when(start([sys.executable, "-m", "rlcompare.cli", *arguments], log),
              lambda: any(name.startswith("pqn") for name in finished_runs(killed)), log)
    finished = finished_runs(killed)
    assert 1 <= len(finished) < 4, finished
    again = invoke(*arguments, columns=300)
    assert again.exit_code == 0, again.output
    assert again.output.count("loaded") == len(finished)
    runs = finished_runs(study[0])
    assert finished_runs(killed) == runs
    assert_same_runs(killed, study[0], runs)
    for table in ("deep_verdicts.csv",):
        assert (killed / "tables" / table).read_bytes() == (study[0] / "tables" / table).read_bytes()


# --- the paired study written once: a third configuration, made here, trains and reports through the same code ---

def _third_study():
    """A configuration unlike deep's and MinAtar's: runs named apart from their environments, the environments in
    an order of its own, one metric, a comparison of its own after the pair's in each environment, an overall
    row, its own labels, digits and prefix."""
    from rlcompare.stats.compare import compare_paired
    from rlcompare.studies.paired_plan import Key, PairedStudy

    def others(env, beside):
        return {Key(env, "constant"): compare_paired(np.array([1.0, 2.0, 3.0]), np.array([0.0, 1.0, 2.0]), 0.5)}

    return PairedStudy("third", ("Acrobot-v1", "CartPole-v1"), {"Acrobot-v1": 25.0, "CartPole-v1": 25.0},
                       lambda key: {"task": key.env, "engine": key.engine}, label=str.upper,
                       method_order=("pqn_sarsa_lambda", "pqn_q_lambda"), tasks="tasks", digits=3,
                       metrics=("greedy_auc",), overall_margin=0.05, prefix="third-", others=others)


class _Recorded(UI):
    """A UI that keeps each finished configuration's name and whether it was loaded."""

    def __init__(self):
        self.finished = []

    def done(self, name, results, reused):
        self.finished.append((name, reused))


@pytest.mark.slow("trains and reports a deep study")
def test_a_third_configuration_of_the_paired_study_trains_and_reports_through_the_same_code(study, tmp_path):
    import shutil

    from rlcompare.studies.paired import final_returns, per_seed, run_of, train
    from rlcompare.studies.paired_plan import OVERALL, PAIR, Key, Plan
    from rlcompare.studies.paired_report import answer, difference_figure, findings, pair_finals

    third, out = _third_study(), tmp_path / "third"
    plan = Plan((0, 1), PAIR, {"balance": "CartPole-v1", "swing": "Acrobot-v1"}, 41000, workers=2)
    names = sorted(f"{method}-{name}" for method in PAIR for name in ("balance", "swing"))
    store.claim(out, store.Owner("study", "third"))
    for method in PAIR:  # CartPole's trainings are the deep study's configurations: its runs are loaded, not trained
        shutil.copytree(study[0] / f"{method}-CartPole-v1", out / f"{method}-balance",
                        ignore=shutil.ignore_patterns(".rlcompare.lock"))
    for first in (True, False):
        recorded = _Recorded()
        train(out, "third", plan, recorded)
        assert sorted(recorded.finished) == [(name, not (first and name.endswith("swing"))) for name in names]

    found = findings(out, third)
    assert found.envs == ["Acrobot-v1", "CartPole-v1"]  # the study's order, not the runs'
    assert list(found.judged) == [Key("Acrobot-v1", metric="greedy_auc"), Key("Acrobot-v1", "constant"),
                                  Key("CartPole-v1", metric="greedy_auc"), Key("CartPole-v1", "constant"),
                                  Key(OVERALL)]
    written = pd.read_csv(out / "tables" / "third_verdicts.csv")
    assert written.columns[:3].tolist() == ["task", "engine", "on - off (mean, 95% CI)"]
    assert written["on - off (mean, 95% CI)"].str.match(r"-?\d+\.\d{3} \[").all()
    # the same runs give the deep study's numbers (loaded above only where each run's configuration is the plan's)
    deep = pd.read_csv(study[0] / "tables" / "deep_verdicts.csv").set_index("metric")
    cartpole = found.judged[Key("CartPole-v1", metric="greedy_auc")].paired
    assert cartpole.difference.format(1) == deep.loc["area under the greedy curve", "on - off (mean, 95% CI)"]
    on, off = (per_seed(found.runs[f"{m}-swing"])["greedy_auc"].to_numpy() for m in PAIR)
    assert found.judged[Key("Acrobot-v1", metric="greedy_auc")].paired.difference.value == pytest.approx(
        np.mean(on - off))

    across = found.across
    assert across is not None
    assert across.envs == found.envs
    assert list(across.scores) == list(third.method_order)
    for index, env in enumerate(across.envs):  # the best method's mean is 1 where it beat the random policy
        raw, floor = max(final_returns(run_of(found.runs, env, m)).mean() for m in PAIR), across.floors[env]
        best = max(scores[index].mean() for scores in across.scores.values())
        assert best == pytest.approx(1.0 if raw > floor else raw - floor)
    overall = found.judged[Key(OVERALL)].paired
    assert overall.difference.value == pytest.approx(np.mean(
        across.scores[PAIR[0]].mean(axis=0) - across.scores[PAIR[1]].mean(axis=0)))
    assert found.files == {name: f"tables/third_{name}.csv" for name in ("verdicts", "aggregates", "improvement")}
    aggregates = pd.read_csv(out / "tables" / "third_aggregates.csv")
    assert aggregates["method"].tolist() == ["PQN_SARSA_LAMBDA", "PQN_Q_LAMBDA"]
    assert aggregates["tasks"].tolist() == [2, 2]
    assert all(path.startswith("figures/third-") and (out / path).is_file() for path, _ in found.aggregates.figures)

    sentences = answer({key.env: j for key, j in found.judged.items() if key.engine == "network"}, 2, "the tasks")
    assert sentences[0].startswith("On-policy SARSA(λ) against off-policy Q(λ), final greedy return per episode, 2 "
                                   "paired seeds: SARSA(λ) scores on Acrobot-v1 ")
    assert sentences[1].startswith("Over the tasks, in scores normalised")
    pairs = pair_finals(found.runs, found.envs)
    assert list(pairs) == found.envs
    assert len(difference_figure(pairs).axes) == 2


@pytest.mark.slow("trains and reports a deep study")
def test_a_configuration_with_one_environment_has_no_aggregates_and_no_overall_row(study, tmp_path):
    import shutil

    from rlcompare.studies.paired_plan import OVERALL, Key
    from rlcompare.studies.paired_report import findings

    out = tmp_path / "one"
    for name in ("pqn_q_lambda-CartPole-v1", "pqn_sarsa_lambda-CartPole-v1"):
        shutil.copytree(study[0] / name, out / name, ignore=shutil.ignore_patterns(".rlcompare.lock"))
    found = findings(out, _third_study())
    assert found.envs == ["CartPole-v1"]
    assert (found.across, found.aggregates) == (None, None)
    assert Key(OVERALL) not in found.judged
    assert list(found.judged) == [Key("Acrobot-v1", "constant"),  # others are asked of every environment
                                  Key("CartPole-v1", metric="greedy_auc"), Key("CartPole-v1", "constant")]
    assert found.files == {"verdicts": "tables/third_verdicts.csv"}


@pytest.mark.slow("reports a copy of a trained deep study")
def test_a_diverged_training_is_no_verdict_and_the_report_names_it(study, tmp_path):
    import shutil

    from rlcompare.studies.deep.study import DEEP
    from rlcompare.studies.paired_plan import Key
    from rlcompare.studies.paired_report import DIVERGED, findings

    out = tmp_path / "diverged"
    for name in ("pqn_q_lambda-CartPole-v1", "pqn_sarsa_lambda-CartPole-v1", "tabular-q_learning-CartPole-v1",
                 "tabular-sarsa-CartPole-v1"):
        shutil.copytree(study[0] / name, out / name, ignore=shutil.ignore_patterns(".rlcompare.lock"))
    meta_file = out / "pqn_sarsa_lambda-CartPole-v1" / "meta.json"
    meta = json.loads(meta_file.read_text())
    assert meta["diverged"] == {}  # what a training that stayed finite records
    meta_file.write_text(json.dumps({**meta, "diverged": {"1": 7}}))
    found = findings(out, DEEP)
    labels = {key: judged.label for key, judged in found.judged.items()}
    assert labels[Key("CartPole-v1", metric="greedy_return")] == DIVERGED
    assert labels[Key("CartPole-v1", metric="greedy_auc")] == DIVERGED
    assert labels[Key("CartPole-v1", "table")] != DIVERGED  # the tabular pair trained apart
    assert any("diverged in 1 of 2 seeds: 1 (from update 7)" in problem for problem in found.problems)


@pytest.mark.slow("trains and reports a deep study")
def test_the_plan_reads_what_each_comparison_could_detect_from_the_previous_runs_spread(study, tmp_path):
    """With 12 seeds over the 2-seed study's directory: each row's difference detectable at 80% power, from the
    spread of on - off its report recorded, at Holm's level over the plan's family; a table that is not the
    study's is named instead of read, and a fresh directory has no such line."""
    import shutil

    from rlcompare.formatting import number
    from rlcompare.stats.design import SIGNED_RANK, detectable_difference
    from rlcompare.studies.deep.study import study_plan
    from rlcompare.studies.registry import DeepOptions

    out, _ = study
    arguments = [*TINY[:TINY.index("--seeds")], "--seeds", "12", *TINY[TINY.index("--seeds") + 2:], "--plan"]
    planned = invoke(*arguments, "--out", str(out), columns=None)
    assert planned.exit_code == 0, planned.output
    family = study_plan(DeepOptions(seeds=12, steps=41000, episodes=50, methods="pqn_q_lambda,pqn_sarsa_lambda",
                                    envs="CartPole-v1")).questions[0].family
    verdicts = pd.read_csv(out / "tables" / "deep_verdicts.csv")
    text = " ".join(planned.output.split())
    assert f"Detectable at 80% power with 12 seeds, in each comparison's own units, from the spread of on - off in " \
           f"the previous run of 2 seeds ({out / 'tables' / 'deep_verdicts.csv'}):" in text
    for _, row in verdicts.iterrows():
        found = detectable_difference(SIGNED_RANK, row["spread of on - off (SD over seeds)"], 12, family)
        assert f"{row['env']}, {row['engine']}, {row['metric']}: {number(found)}" in text
    copied = shutil.copytree(out, tmp_path / "copied", ignore=shutil.ignore_patterns(".rlcompare.lock"))
    (copied / "tables" / "deep_verdicts.csv").write_text(
        (copied / "tables" / "deep_verdicts.csv").read_text().replace("network", "netwerk", 1))
    tampered = " ".join(invoke(*arguments, "--out", str(copied), columns=None).output.split())
    assert "No spread read from the previous run:" in tampered
    assert "does not belong to this study" in tampered
    fresh = invoke(*arguments, "--out", str(tmp_path / "fresh"), columns=None)
    assert "Detectable at 80% power" not in fresh.output
