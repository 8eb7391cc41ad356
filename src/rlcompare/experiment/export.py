"""The other way: rlcompare's runs written where other tools read them (``rlcompare export``): the tidy table
(:func:`~rlcompare.experiment.outside.episodes_table`) as a CSV, or TensorBoard event files under CleanRL's tag, one
directory a seed, each run's files named after it and entered in the directory's :data:`EXPORTS` ledger so that a
second run never replaces the first's."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from rlcompare.experiment import store

EXPORT_TAG = "charts/episodic_return"
"""The tag an exported run's episode returns carry in TensorBoard: CleanRL's, which ``compare`` reads first
(:data:`~rlcompare.experiment.formats.TAGS`)."""


EXPORTS = "exports.json"
"""The file of an export directory that says which run each label's files came from."""


def claim_label(out: Path, label: str, run_dir: Path) -> None:
    """Enter ``run_dir`` as the run whose files are exported under ``label`` in ``out`` (in :data:`EXPORTS`); an
    :class:`~rlcompare.experiment.store.StoreError` where another run holds the label there: exporting this one
    would replace its files."""
    ledger = out / EXPORTS
    claimed = store.read_json(ledger) if ledger.exists() else {}
    source = str(Path(run_dir).resolve())
    if claimed.get(label, source) != source:
        raise store.StoreError(f"{out}: its {label} files were exported from {claimed[label]}, another run of the same "
                               f"name; export {run_dir} into another --out")
    store.enter_outputs(ledger)
    store.write_json_atomic(ledger, {**claimed, label: source})


def tensorboard_directory(method: str, env: str, seed: object) -> str:
    """``{method}/{env}/{seed}``, the layout :func:`grouping`'s default rule reads (a ``/`` in a name as ``_``)."""
    return "/".join(str(part).replace("/", "_") for part in (method, env, seed))


SCRATCH = ".export-"
"""The prefix of the directory an export writes each event file in before moving it into place."""
SCRATCH_MARK = ".rlcompare-scratch"
"""The file an export writes first into its scratch directory: what proves the directory its own."""


def new_scratch(out: Path) -> Path:
    """A scratch directory in ``out``, marked as an export's (:data:`SCRATCH_MARK`) before anything is written in it."""
    import tempfile

    scratch = Path(tempfile.mkdtemp(dir=out, prefix=SCRATCH))
    (scratch / SCRATCH_MARK).write_text("an export's scratch: removed by the next export into this directory\n")
    return scratch


def remove_stale_scratch(out: Path) -> list[Path]:
    """Remove what interrupted exports left in ``out``: each scratch directory that holds :data:`SCRATCH_MARK`, and
    an empty one (killed before its mark); a directory of the same prefix that is neither stays. The removed."""
    import shutil

    removed = []
    for stale in sorted(out.glob(f"{SCRATCH}*")):
        if stale.is_dir() and not stale.is_symlink() and ((stale / SCRATCH_MARK).is_file() or not any(stale.iterdir())):
            shutil.rmtree(stale)
            removed.append(stale)
    return removed


def write_tensorboard(frame: pd.DataFrame, out: Path) -> list[Path]:
    """Each run of a tidy table as a TensorBoard event file written by TensorBoard's own writer, under
    :data:`EXPORT_TAG`, in ``out / {method}/{env}/{seed}``; each written in a scratch directory of its own
    (:func:`new_scratch`) and moved into place once whole, and entered in ``out``'s list of outputs first
    (:func:`rlcompare.experiment.store.enter_outputs`)."""
    import shutil

    from tensorboard.summary import Writer

    remove_stale_scratch(out)
    written = []
    for (method, env, seed), run in frame.groupby(["method", "env", "seed"], sort=True):
        target = out / tensorboard_directory(str(method), str(env), seed)
        scratch = new_scratch(out)
        try:
            writer = Writer(str(scratch))
            for step, value in zip(run["step"], run["value"], strict=True):
                writer.add_scalar(EXPORT_TAG, float(value), step=int(step))
            writer.close()
            (made,) = scratch.glob("events.out.tfevents.*")
            final = target / made.name
            store.enter_outputs(final)
            target.mkdir(parents=True, exist_ok=True)
            os.replace(made, final)
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        written.append(final)
    return written
