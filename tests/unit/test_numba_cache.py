"""The numba cache directory: keyed by the compiled sources, old versions pruned."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import rlcompare
from rlcompare.compiled import COMPILED_SOURCES, prune_unused, source_digest

PACKAGE = Path(rlcompare.__file__).parent


def copy_of_compiled_sources(tmp_path: Path) -> Path:
    copy = tmp_path / "package"
    for name in COMPILED_SOURCES:
        if (PACKAGE / name).is_dir():
            shutil.copytree(PACKAGE / name, copy / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(PACKAGE / name, copy / name)
    return copy


def test_digest_changes_with_any_compiled_source_and_only_with_them(tmp_path: Path) -> None:
    copy = copy_of_compiled_sources(tmp_path)
    before = source_digest(copy)
    assert before == source_digest(PACKAGE)
    (copy / "cli.py").write_text("# not compiled code\n")
    (copy / "tabular" / "config.py").write_text("# validated settings, not compiled code\n")
    assert source_digest(copy) == before
    port = copy / "envs" / "cartpole.py"
    port.write_text(port.read_text() + "\n# one more line\n")
    assert source_digest(copy) != before


def test_prune_deletes_other_versions_unused_for_a_month_and_keeps_the_rest(tmp_path: Path) -> None:
    current, recent, stale, other = (tmp_path / name for name in ("numba-a", "numba-b", "numba-c", "notes"))
    for directory in (current, recent, stale, other):
        directory.mkdir()
    month_ago = time.time() - 31 * 86400
    for directory in (current, stale, other):
        os.utime(directory, (month_ago, month_ago))
    prune_unused(tmp_path, keep=current)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes", "numba-a", "numba-b"]


def test_an_empty_cache_says_the_next_run_compiles(tmp_path, monkeypatch):
    import numba

    from rlcompare.compiled import holds_nothing_yet

    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    assert holds_nothing_yet()
    (tmp_path / "tabular").mkdir()
    (tmp_path / "tabular" / "run.train_block-1.py310.nbi").write_bytes(b"")
    assert not holds_nothing_yet()


def test_a_run_records_how_long_its_kernels_took_to_load_or_compile():
    from rlcompare import ExperimentConfig, run

    timings = run(ExperimentConfig(seeds=(0,), episodes=2, eval_every=0)).meta["timings"]
    assert 0 < timings["compile_seconds"] < 600
    assert timings["wall_seconds"] >= 0
