"""``--force`` means the same at every level of a study (issue 39): a user's files beside rlcompare's, in the
study's directory or in a run's, are left alone and do not stop it; a user's file where rlcompare writes its own is
named before anything is trained."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import finished_runs, invoke

pytestmark = pytest.mark.slow("reproduces a small study into a directory a user shares")

PAPER = ["reproduce", "--allow-undecidable", "--seeds", "2", "--episodes", "60"]


def test_force_writes_beside_a_users_file_in_a_run_directory(tmp_path: Path) -> None:
    out = tmp_path / "study"
    (out / "random").mkdir(parents=True)
    (out / "random" / "notes.txt").write_text("mine")
    result = invoke(*PAPER, "--no-videos", "--force", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert (out / "random" / "notes.txt").read_text() == "mine"
    assert "random" in finished_runs(out)
    assert (out / "report.html").is_file()


@pytest.mark.parametrize("users_file", ["videos/random-seed0.mp4", "random/config.json", "tables/mine.csv"])
def test_a_users_file_where_rlcompare_writes_is_named_before_training(users_file: str, tmp_path: Path) -> None:
    out = tmp_path / "study"
    (out / users_file).parent.mkdir(parents=True)
    (out / users_file).write_text("mine")
    result = invoke(*PAPER, "--force", "--out", str(out))
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert f"where it writes its own ({users_file})" in result.output
    assert finished_runs(out) == []
    assert (out / users_file).read_text() == "mine"
