"""Figures and videos drawn again only when what they are drawn from changes, and kept only when provably
rlcompare's and unchanged (:mod:`rlcompare.report.drawn`)."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest
from helpers import invoke

from rlcompare.experiment import store
from rlcompare.report import drawn
from rlcompare.studies.paper.report import build_report
from rlcompare.studies.paper.study import paper_configs, reproduce

SETTINGS = {"episodes": 60, "max_steps": 40, "eval_every": 20, "eval_episodes": 2}
"""Short episodes: each video is an episode of the run's limit, drawn and encoded again in most tests here."""


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small paper study (3 seeds x 60 episodes of at most 40 steps), with one report and its videos."""
    path = tmp_path_factory.mktemp("study")
    list(reproduce(path, paper_configs((0, 1, 2), **SETTINGS)))
    build_report(path, video_workers=1)
    return path


@pytest.fixture
def study_copy(study: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(study, tmp_path / "study"))


def stamps(directory: Path) -> dict[str, tuple[int, int]]:
    """Each figure's and video's inode and modification time: a file written again gets a new inode."""
    return {p.relative_to(directory).as_posix(): (p.stat().st_ino, p.stat().st_mtime_ns)
            for folder in ("figures", "videos") for p in sorted((directory / folder).iterdir())}


@pytest.mark.slow("trains a study and draws its report, twice")
def test_a_second_report_keeps_every_figure_and_video_and_rewrites_the_tables(
        study_copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from rlcompare.report import aggregate_plots
    from rlcompare.studies.paper import report as paper_report

    before, page = stamps(study_copy), (study_copy / "report.html").read_bytes()
    ledger = json.loads((study_copy / drawn.LEDGER).read_text())
    assert set(ledger["files"]) == set(before)  # every figure and video is in the ledger
    assert drawn.LEDGER in store.read_json(study_copy / store.MARKER_FILE)["outputs"]

    def drawn_again(figure, path):
        raise AssertionError(f"{path} drawn again")

    for module in (paper_report, aggregate_plots):  # no figure is even drawn
        monkeypatch.setattr(module, "save_figure", drawn_again)
    build_report(study_copy, video_workers=1)
    assert stamps(study_copy) == before  # nothing written again
    assert (study_copy / "report.html").read_bytes() == page


@pytest.mark.slow("trains a study and draws its report, twice")
def test_a_file_edited_or_replaced_is_drawn_again_and_the_others_kept(study_copy: Path) -> None:
    figure, movie = study_copy / "figures" / "fig6-constant.png", study_copy / "videos" / "random-seed0.mp4"
    original_figure, original_movie = figure.read_bytes(), movie.read_bytes()
    figure.write_bytes(original_figure + b"\0")
    movie.unlink()
    before = stamps(study_copy)
    build_report(study_copy, video_workers=1)
    after = stamps(study_copy)
    assert figure.read_bytes() == original_figure  # drawn again, the same
    assert movie.read_bytes() == original_movie
    changed = {name for name in after if after[name] != before.get(name)}
    assert changed == {"figures/fig6-constant.png", "videos/random-seed0.mp4", "videos/random-seed0.gif"}  # one job


@pytest.mark.slow("trains a study and draws its report, twice")
def test_another_key_draws_everything_again(study_copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    before = stamps(study_copy)
    monkeypatch.setattr(drawn, "code_fingerprint", lambda: "other code")
    build_report(study_copy, video_workers=1)
    after = stamps(study_copy)
    assert all(after[name] != before[name] for name in before)


@pytest.mark.slow("trains a study and draws its report, twice")
def test_a_file_rlcompare_did_not_list_is_never_kept_nor_touched(study_copy: Path) -> None:
    mine = study_copy / "figures" / "mine.png"
    mine.write_bytes(b"a user's own file")
    ledger_path = study_copy / drawn.LEDGER
    ledger = json.loads(ledger_path.read_text())
    ledger["files"]["figures/mine.png"] = {"key": ledger["files"]["figures/fig3-random.png"]["key"],
                                           "sha256": drawn.file_digest(mine)}
    ledger_path.write_text(json.dumps(ledger))
    key = ledger["files"]["figures/fig3-random.png"]["key"]
    ledger_drawn = drawn.Drawn(study_copy)
    assert not ledger_drawn.kept(mine, key)
    assert ledger_drawn.kept(study_copy / "figures" / "fig3-random.png", key)
    build_report(study_copy, videos=False)
    assert mine.read_bytes() == b"a user's own file"
    assert "figures/mine.png" not in json.loads(ledger_path.read_text())["files"]


@pytest.mark.slow("trains a study and draws its report, twice")
def test_no_ledger_or_a_damaged_one_keeps_nothing(study_copy: Path) -> None:
    ledger = json.loads((study_copy / drawn.LEDGER).read_text())
    figure = study_copy / "figures" / "fig3-random.png"
    key = ledger["files"]["figures/fig3-random.png"]["key"]
    assert drawn.Drawn(study_copy).kept(figure, key)
    assert not drawn.Drawn(study_copy).kept(figure, None)  # runs without recorded checksums: always drawn
    assert not drawn.Drawn(study_copy).kept(figure, "another key")
    (study_copy / drawn.LEDGER).write_text("{not json")
    assert not drawn.Drawn(study_copy).kept(figure, key)
    before = stamps(study_copy)
    build_report(study_copy, video_workers=1)
    after = stamps(study_copy)
    assert all(after[name] != before[name] for name in before)
    assert json.loads((study_copy / drawn.LEDGER).read_text()) == ledger  # written again, whole


@pytest.mark.slow("trains a study and draws its report, twice")
def test_a_retrained_configuration_draws_again_only_what_shows_it(study_copy: Path) -> None:
    """Another run in one configuration's directory (another step size here) changes the key of the figures and
    videos drawn from it, and of no other."""
    before = stamps(study_copy)
    shutil.rmtree(study_copy / "sarsa-decay")
    config = next(c for c in paper_configs((0, 1, 2), **SETTINGS) if c.name == "sarsa-decay")
    list(reproduce(study_copy, [dataclasses.replace(config, alpha=0.1)]))
    build_report(study_copy, video_workers=1)
    after = stamps(study_copy)
    changed = {name for name in after if after[name] != before.get(name)}
    assert {"figures/fig3-random.png", "figures/fig4-q_learning-constant.png", "figures/fig6-constant.png",
            "figures/stages-sarsa-constant.png", "videos/random-seed0.mp4"}.isdisjoint(changed)
    assert {"figures/fig8-sarsa-decay.png", "figures/fig9-decay.png", "figures/stages-sarsa-decay.png",
            "figures/visits.png", "figures/aggregate-intervals.png"} <= changed
    assert {name for name in changed if name.startswith("videos/")} == {
        name for name in after if name.startswith("videos/sarsa-decay-")}


@pytest.mark.slow("trains a study and draws its report, twice")
def test_a_users_own_ledger_file_is_left_alone_and_nothing_kept(tmp_path: Path) -> None:
    """A directory shared with ``--force`` whose ``.drawn.json`` is the user's: the report draws everything and
    neither reads nor replaces that file."""


    target = tmp_path / "shared"
    target.mkdir()
    (target / drawn.LEDGER).write_text("mine")
    result = invoke("reproduce", "--allow-undecidable", "--episodes", "20", "--seeds", "1", "--no-videos", "--out",
                                          str(target), "--force", columns=None)
    assert result.exit_code == 0, result.output
    assert (target / drawn.LEDGER).read_text() == "mine"
    assert (target / "report.html").is_file()


def test_the_code_that_trains_or_parses_options_does_not_enter_the_key() -> None:
    """What training made is in the runs' checksums; the code that draws, loads and plays the agents is in the key."""
    assert not drawn._draws("cli/commands.py")
    assert not drawn._draws("engine/run.py")
    for relative in ("engine/state.py", "analysis/plots.py", "experiment/results.py", "envs/mountain_car.py",
                     "algorithms/policies.py", "studies/paper/figures.py"):
        assert drawn._draws(relative), relative
