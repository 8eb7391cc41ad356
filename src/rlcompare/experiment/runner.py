"""``run(config) -> results``: train every seed of a configuration on its engine into its run directory, and the
studies' run-or-load over many configurations."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from rlcompare.experiment import engines, rundir, store
from rlcompare.experiment.interrupts import trainings


def run(config: Any, *, out: Path | None = None, study: str = "", progress: Callable[[int], None] | None = None,
        force: bool = False) -> Any:
    """Train every seed of ``config`` on its engine (:mod:`rlcompare.experiment.engines`); write the run directory
    to ``out`` if given (refused before training, locked while it lasts; ``force``: beside files rlcompare did not
    write, never replacing them). ``progress`` is called with what was finished since its last call (episodes of
    each seed, or seeds: the config's ``progress_total`` says)."""
    train = engines.front(config).train
    if out is None:
        return train(config, study=study, progress=progress)
    with store.output_directory(Path(out), store.RUN, force=force):
        results = train(config, study=study, progress=progress)
        rundir.write_results(Path(out), results)
    return results


def changed_settings(run_dir: Path, config: Any) -> str:
    """How the finished run in ``run_dir`` was made differently from ``config``: ``seeds 0-29 there, 0-9 asked``
    for each setting that differs (the first three); empty where it holds no finished run, or one of ``config``, or
    a damaged one (a ``config.json`` that is not the one its ``meta.json`` recorded: it is trained again)."""
    if not (run_dir / rundir.META_FILE).is_file():
        return ""
    try:
        meta = store.read_json(run_dir / rundir.META_FILE)
        files = meta.get("contents", {}).get("files", {}) if isinstance(meta, dict) else {}
        rundir.check_recorded(run_dir / rundir.CONFIG_FILE, files.get(rundir.CONFIG_FILE), run_dir / rundir.META_FILE)
        stored = store.read_json(run_dir / rundir.CONFIG_FILE)
    except (store.StoreError, AttributeError):
        return ""
    asked = json.loads(json.dumps(config.to_dict()))
    if not isinstance(stored, dict) or stored == asked:
        return ""
    differing = [key for key in sorted(set(stored) | set(asked)) if stored.get(key) != asked.get(key)]
    shown = [f"{key} {_setting(stored.get(key))} there, {_setting(asked.get(key))} asked" for key in differing[:3]]
    return ", ".join(shown) + (f" and {len(differing) - 3} more" if len(differing) > 3 else "")


def damage_of(run_dir: Path, config: Any) -> str:
    """Why the finished run in ``run_dir`` is damaged (a file whose size or checksum is not what its ``meta.json``
    recorded), as :func:`~rlcompare.experiment.rundir.verify_run` says it; empty where it holds no finished run or
    an intact one."""
    if not (run_dir / rundir.META_FILE).is_file():
        return ""
    try:
        rundir.verify_run(run_dir, None, rundir.files_of(engines.front(config).Results))
    except store.StoreError as error:
        return str(error).removesuffix("; run it again")
    return ""


def _setting(value: Any) -> str:
    """A setting as a reader writes it; a run of consecutive seeds as ``0-29``."""
    if isinstance(value, list) and value and all(isinstance(v, int) for v in value):
        if len(value) > 2 and value == list(range(value[0], value[0] + len(value))):
            return f"{value[0]}-{value[-1]}"
        return ", ".join(map(str, value))
    return "none" if value is None else str(value)


def refuse_replacing(out: Path, configs: dict[str, Any]) -> None:
    """A :class:`~rlcompare.experiment.store.StoreError` where ``out`` holds finished runs made with other settings
    than ``configs`` asks for (name -> config; ``""``: ``out`` itself is the run): rlcompare does not replace a
    user's results without a word."""
    changed = {name: text for name, config in configs.items()
               if (text := changed_settings(Path(out) / name if name else Path(out), config))}
    if changed:
        name, text = next(iter(changed.items()))
        where = f"{name}: " if name else ""
        more = f" (and {len(changed) - 1} more runs)" if len(changed) > 1 else ""
        raise store.StoreError(f"{out}: holds finished runs made with other settings ({where}{text}){more}; choose "
                               "another --out, ask for the same settings to resume them, or pass --force to "
                               "replace them")


REPORT_PLACES = ("figures", "tables", "videos", "report.html")
"""Where a study's report writes: folders whose files' names are known only once the runs are trained (a video's
seed is chosen from them), and the page."""


def refuse_clashes(out: Path, configs: dict[str, Any]) -> None:
    """A :class:`~rlcompare.experiment.store.StoreError`, before anything is trained, naming files rlcompare did not
    write where a study writes its own: a run's files (``config.json`` in a run's directory) or anything in the
    report's places. Beside them (``--force``), a user's files are left alone at every level."""
    run_files = (*rundir.RUN_FILES, rundir.PARAMS_FILE)
    candidates = [Path(out) / name / file for name in configs for file in run_files]
    candidates += [path for place in REPORT_PLACES for path in _files(Path(out) / place)]
    listed: dict[Path, set[str]] = {}  # each marker read once
    clashes = [path for path in candidates if _unlisted(path, listed)]
    if clashes:
        shown = ", ".join(str(path.relative_to(out)) for path in clashes[:3])
        more = f" and {len(clashes) - 3} more" if len(clashes) > 3 else ""
        raise store.StoreError(f"{out}: holds files rlcompare did not write where it writes its own ({shown}{more});"
                               " they are left as they are: move them, or choose another --out")


def _files(path: Path) -> list[Path]:
    return [path] if path.is_file() or path.is_symlink() else sorted(p for p in path.rglob("*") if p.is_file())


def _unlisted(path: Path, listed: dict[Path, set[str]]) -> bool:
    """Whether ``path`` is there and not listed by the marker of the directory that holds it (``listed``: the
    markers read so far, by directory)."""
    if not (path.exists() or path.is_symlink()):
        return False
    owner = next((d for d in path.parents if (d / store.MARKER_FILE).is_file()), None)
    if owner is None:
        return True
    if owner not in listed:
        listed[owner] = store.listed_outputs(owner)
    return path.relative_to(owner).as_posix() not in listed[owner]


def run_or_load(
    out: Path, configs: dict[str, Any], *, study: str, progress: Callable[[int], None] | None = None,
    force: bool = False, train: Callable[..., Any] | None = None, load: Callable[..., Any] | None = None,
    workers: int = 1,
) -> Iterator[tuple[str, Any, bool]]:
    """Run each configuration into ``out / name`` on its engine (:mod:`rlcompare.experiment.engines`), or load
    it if that run already finished and its files belong together. A study that keeps a summary of its runs
    instead gives its own ``train`` and ``load`` (``Results.load``'s signature). ``workers`` configurations train
    at once (each run's results depend on its configuration alone).

    ``out`` is claimed as the study's directory (``force``: even beside files rlcompare did not write) and
    locked while this runs. Finished runs made with other settings are refused before anything is trained
    (:func:`refuse_replacing`; ``force``: replaced). Yields ``(name, results, reused)`` as each configuration
    completes, so an interrupted study resumes where it stopped and loses nothing finished.
    """

    def one(name: str, config: Any) -> tuple[str, Any, bool]:
        run_dir = Path(out) / name
        stored = engines.load_if_complete(run_dir, config, load)
        if stored is not None:
            if progress is not None:
                progress(config.progress_total)
            return name, stored, True
        return name, (train or run)(config, out=run_dir, study=study, progress=progress, force=force), False

    with store.output_directory(Path(out), store.Owner("study", study), force=force):
        if not force:
            refuse_replacing(Path(out), configs)
        refuse_clashes(Path(out), configs)
        # trained in threads, even one at a time, so that the main thread answers Ctrl-C while XLA runs
        pending: dict[Future[tuple[str, Any, bool]], str] = {}
        with ThreadPoolExecutor(max(workers, 1)) as pool, trainings(lambda: pending):
            for name, config in configs.items():
                pending[pool.submit(one, name, config)] = name
            for future in as_completed(pending):
                name, results, reused = future.result()
                rundir.enter_members(Path(out), [name])
                yield name, results, reused
