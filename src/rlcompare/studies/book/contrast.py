"""On- against off-policy across problems: SARSA minus Q-Learning, online and greedy, study by study.

The paper explains its Mountain Car result by the kind of problem and sets it against Sutton and Barto's
Cliff Walking (Example 6.6). Both sides are answered with the same two numbers per study, on paired seeds:

- online: the mean return of the ε-greedy behaviour over training, what an agent collects while it learns;
- greedy: the return of the final greedy policy, what it has learned.

On the cliff SARSA collects more online but Q-Learning's greedy path is the better one; where SARSA wins
both, exploring costs Q-Learning more than its bootstrapped targets gain it.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import pandas as pd

from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_run
from rlcompare.stats.compare import compare_paired, comparison_label
from rlcompare.studies.measures import per_seed_metrics
from rlcompare.tabular.results import Results

PAIRS = (("sarsa", "q_learning"), ("sarsa-constant", "q_learning-constant"), ("sarsa-decay", "q_learning-decay"))
"""(SARSA, Q-Learning) run directories compared in a study: the cliff's, then the paper grid's."""
SIBLING_STUDIES = ("paper", "cartpole", "acrobot")
SIDES = ("SARSA", "Q-Learning")


def load_pairs(study_dir: Path) -> dict[str, Results]:
    """The SARSA and Q-Learning runs a study directory holds (complete ones whose files belong together)."""
    runs = {}
    for name in {name for pair in PAIRS for name in pair}:
        run_dir = Path(study_dir) / name
        if rundir.is_complete(run_dir):
            with contextlib.suppress(store.StoreError):
                runs[name] = load_run(run_dir)
    return runs


def contrast_table(studies: dict[str, dict[str, Results]]) -> pd.DataFrame:
    """One row per study and ε schedule: SARSA, Q-Learning and their paired difference, online and greedy."""
    rows = []
    for study, runs in studies.items():
        for sarsa_name, q_name in PAIRS:
            if sarsa_name not in runs or q_name not in runs:
                continue
            sarsa, q = per_seed_metrics(runs[sarsa_name]), per_seed_metrics(runs[q_name])
            config = runs[sarsa_name].config
            exploration = f"ε = {config.epsilon:g}" if config.schedule == "constant" else "ε decaying"
            row = {"study": study, "environment": config.env, "exploration": exploration, "seeds": len(sarsa)}
            for metric, label in (("behaviour_return", "online"), ("greedy_return", "greedy")):
                paired = compare_paired(sarsa[metric].to_numpy(), q[metric].to_numpy(), improvement=False)
                row |= {f"{label}: SARSA": f"{paired.a_mean:.1f}", f"{label}: Q-Learning": f"{paired.b_mean:.1f}",
                        f"{label}: SARSA - Q-Learning": paired.difference.format(1),
                        f"{label}: better": comparison_label(paired.difference, paired.p_value, SIDES)}
            rows.append(row)
    return pd.DataFrame(rows)


def sibling_studies(study_dir: Path) -> dict[str, dict[str, Results]]:
    """The paper's study and its versions on other environments, where they stand beside ``study_dir``."""
    found = {}
    for name in SIBLING_STUDIES:
        sibling = Path(study_dir).parent / name
        with contextlib.suppress(store.StoreError):
            if store.owner_of(sibling) == store.Owner("study", name) and (runs := load_pairs(sibling)):
                found[name] = runs
    return found
