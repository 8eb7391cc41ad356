"""The smaller messages of issue 39, each made plain: standard output that cannot be written, a cache that cannot
be kept, ``load_agent`` on a study or with a boolean seed, and an Atari game asked of the tabular engine."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import ENV, command_line, invoke, paper_study

from rlcompare import load_agent
from rlcompare.experiment import store
from rlcompare.experiment.rundir import META_FILE
from rlcompare.validation import ConfigError

RUN = ["run", "--seeds", "1", "--episodes", "20"]


@pytest.mark.slow("starts rlcompare in a process of its own")
def test_a_full_standard_output_says_so_and_keeps_the_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert command_line(*RUN, "--out", str(tmp_path / "warm")).returncode == 0  # compiled: nothing printed before
    with open("/dev/full", "w") as full:
        result = subprocess.run([sys.executable, "-m", "rlcompare.cli", *RUN, "--out", str(out)], stdout=full,
                                stderr=subprocess.PIPE, text=True, env=ENV, check=False)
    assert result.returncode == 2
    assert "standard output: cannot write (No space left on device)" in result.stderr
    assert "Exception ignored" not in result.stderr
    assert json.loads((out / META_FILE).read_text())["seeds"] == [0]


@pytest.mark.slow("starts rlcompare in a process of its own")
def test_a_cache_that_cannot_be_kept_is_named_not_promised(tmp_path: Path) -> None:
    blocked = tmp_path / "a-file"
    blocked.write_text("not a directory")
    result = command_line(*RUN, "--out", str(tmp_path / "run"), env={"XDG_CACHE_HOME": str(blocked)})
    assert result.returncode == 0, result.stderr
    said = " ".join(result.stdout.split())
    assert "is not writable, so each run compiles its training loops again" in said
    assert "later runs load it" not in said


@pytest.mark.slow("trains a small study")
def test_load_agent_on_a_study_names_its_runs_and_refuses_a_boolean_seed(tmp_path: Path) -> None:
    study = paper_study(tmp_path / "study", seeds=1, episodes=20)
    with pytest.raises(store.StoreError, match=r"holds the paper study, not one run; allowed: one of its run "
                                               r"directories \(q_learning-constant, "):
        load_agent(study)
    with pytest.raises(ConfigError, match=r"^seed: got True"):
        load_agent(study / "random", seed=True)


def test_an_atari_game_asked_of_the_tabular_engine_names_the_deep_one(tmp_path: Path) -> None:
    result = invoke("run", "--env", "ALE/Pong-v5", "--seeds", "1", "--episodes", "5", "--out", str(tmp_path / "r"))
    assert result.exit_code == 2
    assert "Atari 2600 game" in result.output
    assert "Pong-Atari" in result.output
    assert "Namespace ALE not found" not in result.output
