"""A marker's list of outputs is what rlcompare may delete, so a changed list must not reach outside its
directory (issue 39): a path with ``..``, an absolute path, a symlink leading out, or a pattern's ``*`` across
``/``. Each is refused in one line naming the marker, and nothing is removed."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from helpers import digests, invoke, paper_study

from rlcompare.experiment import store
from rlcompare.experiment.paths import is_inner_path, matches


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = paper_study(tmp_path_factory.mktemp("tampered") / "study", seeds=2, episodes=60)
    assert invoke("report", str(path), "--no-videos").exit_code == 0
    return path


@pytest.fixture
def copy(study: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(study, tmp_path / "shared" / "study", symlinks=True))


def add_to_list(directory: Path, *entries: str) -> None:
    marker = directory / store.MARKER_FILE
    data = json.loads(marker.read_text())
    data["outputs"] += list(entries)
    marker.write_text(json.dumps(data))


@pytest.mark.slow("reports a copied study")
@pytest.mark.parametrize("entry", ["figures/../../victim.png", "../victim.png", "{absolute}", "figures//x.png",
                                   "./figures/x.png", "figures\\..\\..\\victim.png"])
def test_a_listed_path_outside_the_directory_is_refused_and_nothing_removed(copy: Path, entry: str) -> None:
    victim = copy.parent / "victim.png"
    victim.write_bytes(b"a user's figure")
    add_to_list(copy, entry.format(absolute=victim))
    before = digests(copy)
    result = invoke("report", str(copy), "--no-videos")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert store.MARKER_FILE in result.output
    assert "not a path inside its directory" in result.output
    assert victim.read_bytes() == b"a user's figure"
    assert digests(copy) == before


@pytest.mark.slow("reports a copied study")
def test_a_symlink_leading_out_is_neither_written_through_nor_removed_through(copy: Path, tmp_path: Path) -> None:
    outside = tmp_path / "elsewhere"
    shutil.copytree(copy / "figures", outside)
    shutil.rmtree(copy / "figures")
    os.symlink(outside, copy / "figures")
    before = digests(outside)
    shutil.rmtree(copy / "random")  # its figure becomes stale: a report would remove it
    result = invoke("report", str(copy), "--no-videos")
    assert result.exit_code == 2, result.output
    assert "leads out of" in result.output
    assert "Traceback" not in result.output
    assert digests(outside) == before


def test_a_pattern_matches_within_one_directory_level() -> None:
    assert matches("figures/fig3-random.png", "figures/*.png")
    assert not matches("figures/sub/fig.png", "figures/*.png")
    assert not matches("figures/../../victim.png", "figures/*.png")
    assert not matches("figures/x.png/../../victim.png", "figures/*")
    assert [is_inner_path(p) for p in ("a/b.png", "a/../b", "/a", "", "a//b", ".", 3)] == [
        True, False, False, False, False, False, False]


def test_a_studys_record_names_runs_gone_or_replaced_and_a_damaged_record_is_begun_again(tmp_path: Path) -> None:
    """members.json by hand: two runs entered with their meta.json's checksum; one replaced, one removed; the record
    itself damaged (named, never a traceback), then begun again by the next run entered."""
    from rlcompare.experiment import rundir

    study_dir = tmp_path / "study"
    store.claim(study_dir, store.Owner("study", "x"))
    for name in ("a", "b"):
        (study_dir / name).mkdir()
        (study_dir / name / rundir.META_FILE).write_text(f'{{"name": "{name}"}}')
    rundir.enter_members(study_dir, ["a", "b"])
    assert rundir.missing_members(study_dir) == []
    (study_dir / "a" / rundir.META_FILE).write_text('{"name": "a", "trained": "again"}')
    shutil.rmtree(study_dir / "b")
    found = rundir.missing_members(study_dir)
    assert [line.split(":")[0] for line in found] == ["a", "b"]
    assert "not the run the study trained" in found[0]
    assert "is gone" in found[1]
    assert rundir.missing_members(study_dir, reported=["a"]) == found[1:]
    (study_dir / rundir.MEMBERS_FILE).write_text('{"runs": [1]}')
    assert rundir.missing_members(study_dir) == [
        f"{study_dir / rundir.MEMBERS_FILE}: not a study's record rlcompare wrote"]
    rundir.enter_members(study_dir, ["a"])
    assert rundir.missing_members(study_dir) == []
    assert json.loads((study_dir / rundir.MEMBERS_FILE).read_text())["runs"].keys() == {"a"}
