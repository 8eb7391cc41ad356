"""Output paths as users type them: a leading ``~`` is the home directory, names with spaces and non-ASCII
letters work, a path through a symlink writes into its target, ``.`` is written when empty, and ``/``, ``.`` or
``~`` holding other files are refused in one message with nothing written."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from helpers import invoke


def _run(out: str):
    return invoke("run", "--seeds", "1", "--episodes", "5", "--out", out, columns=300)


def test_a_leading_tilde_is_the_home_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    result = _run("~/runs/r")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "home" / "runs" / "r" / "meta.json").is_file()
    assert not (tmp_path / "~").exists()


@pytest.mark.parametrize("name", ["with space", "ñandú", "日本"])
def test_names_with_spaces_and_other_letters_work(name: str, tmp_path: Path) -> None:
    result = _run(str(tmp_path / name))
    assert result.exit_code == 0, result.output
    assert (tmp_path / name / "meta.json").is_file()


def test_a_path_through_a_symlink_writes_into_its_target(tmp_path: Path) -> None:
    (tmp_path / "target").mkdir()
    os.symlink(tmp_path / "target", tmp_path / "link")
    result = _run(str(tmp_path / "link" / "r"))
    assert result.exit_code == 0, result.output
    assert (tmp_path / "target" / "r" / "meta.json").is_file()


def test_the_root_is_refused_in_one_message_and_nothing_written() -> None:
    before = sorted(os.listdir("/"))
    result = _run("/")
    assert result.exit_code == 2
    assert "holds files rlcompare did not write" in result.output
    assert sorted(os.listdir("/")) == before


def test_the_current_directory_is_written_when_empty_and_refused_when_it_holds_a_users_files(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    empty, used = tmp_path / "empty", tmp_path / "used"
    empty.mkdir()
    used.mkdir()
    (used / "notes.txt").write_text("mine")
    monkeypatch.chdir(empty)
    result = _run(".")
    assert result.exit_code == 0, result.output
    assert (empty / "meta.json").is_file()
    monkeypatch.chdir(used)
    refused = _run(".")
    assert refused.exit_code == 2
    assert "holds files rlcompare did not write ('notes.txt')" in " ".join(refused.output.split())
    assert sorted(p.name for p in used.iterdir()) == ["notes.txt"]


def test_the_home_directory_itself_is_refused_when_it_holds_a_users_files(tmp_path: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    home = tmp_path / "home"
    (home / ".bashrc").parent.mkdir()
    (home / ".bashrc").write_text("mine")
    monkeypatch.setenv("HOME", str(home))
    result = _run("~")
    assert result.exit_code == 2
    assert f"{home} holds files rlcompare did not write" in " ".join(result.output.split())
    assert sorted(p.name for p in home.iterdir()) == [".bashrc"]
