"""The paper's question as other studies answered it: their verdict tables, read beside a study's own.

"On-policy against off-policy target" is judged by the paper's tabular study on Mountain Car (``rlcompare
reproduce``, its ``tables/verdicts.csv``) and by the deep study on classic control, with a network and in a table
(``rlcompare reproduce deep``, its ``tables/deep_verdicts.csv``). A study that asks the question again (MinAtar)
sets their rows beside its own: read from the files those studies wrote, nothing recomputed. A directory is read
only where its marker names that study and lists the verdict file among what rlcompare wrote there; anything else
is named and left out, and a verdict file that cannot be read as that study writes it is one line, never an error.
Each study Holm-corrects its own claims: the labels come from separate families.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from rlcompare.experiment import store
from rlcompare.formatting import cut
from rlcompare.studies.paper.study import MOUNTAIN_CAR

COLUMNS = ["study", "environment", "engine: on- vs off-policy", "metric", "claim", "estimate", "estimate of",
           "p (Holm)", "verdict"]
"""The columns of :func:`beside`'s table, the study's own rows first."""
MAX_TABLE_BYTES = 2**20
"""The largest verdict file read (rlcompare's are a few kilobytes); a larger one is not of that study."""
TWO_SIDED = "which target is better (two-sided, margin of no difference)"
CAPTION = ("The same question in each study, labelled within its own family: each study Holm-corrects its own "
           "claims separately, so these labels are not one family")


@dataclass(frozen=True)
class Source:
    """A study whose verdicts are read: its name (its marker's and its default directory's), the file, the
    columns the rows need, and the command that makes it."""

    name: str
    table: str
    needed: tuple[str, ...]
    command: str


PAPER = Source("paper", "tables/verdicts.csv", ("claim", "metric", "test", "estimate", "p (Holm)", "verdict"),
               "rlcompare reproduce")
DEEP = Source("deep", "tables/deep_verdicts.csv",
              ("env", "engine", "metric", "on - off (mean, 95% CI)", "p (Holm)", "verdict"), "rlcompare reproduce deep")
SOURCES = {source.name: source for source in (PAPER, DEEP)}
PAPER_METRICS = {"convergence_episode": "episodes to converge", "behaviour_return": "mean return while learning",
                 "greedy_return": "final greedy return", "first_action_left": "share of start states pushed left"}
ENGINES = {"network": "network (MLP): SARSA(λ) vs Q(λ), PQN-style", "table": "table: SARSA vs Q-Learning"}


@dataclass
class Beside:
    """What :func:`beside` found: the table (:data:`COLUMNS`), one sentence on what was read and what was not,
    and a line for each verdict file that could not be read."""

    table: pd.DataFrame
    sentence: str
    malformed: list[str] = field(default_factory=list)

    @property
    def paragraphs(self) -> list[str]:
        return [self.sentence, *self.malformed]


def sibling_dirs(study_dir: Path, given: Mapping[str, Path | str] | None = None) -> dict[str, Path]:
    """Where each source is looked for: ``given`` (by study name), else beside ``study_dir`` under the study's
    own name, as ``rlcompare reproduce`` defaults to ``runs/<study>``. An unknown name is a :class:`ValueError`."""
    given = dict(given or {})
    unknown = sorted(set(given) - set(SOURCES))
    if unknown:
        raise ValueError(f"beside: got {unknown[0]!r}; allowed: {', '.join(SOURCES)}")
    return {name: Path(given[name]) if name in given else Path(study_dir).parent / name for name in SOURCES}


class _NotRead(Exception):
    """Why a source's directory or file is not read: the phrase for the sentence."""


class _Malformed(Exception):
    """A verdict file of the right study that cannot be read as that study writes it."""


def _verified(source: Source, directory: Path) -> Path:
    """The verdict file of ``source`` in ``directory``, where the directory's marker names that study and lists
    the file as one rlcompare wrote; else :class:`_NotRead` saying why."""
    if not directory.exists():
        raise _NotRead(f"the {source.name} study is absent ('{source.command} --out {directory}' makes it)")
    if not directory.is_dir():
        raise _NotRead(f"{directory} is a file, not the {source.name} study's directory: not read")
    try:
        owner = store.owner_of(directory)
        listed = store.read_json(directory / store.MARKER_FILE)["outputs"] if owner is not None else []
    except (store.StoreError, OSError, KeyError, TypeError) as error:
        raise _NotRead(f"{directory} is not the {source.name} study's ({cut(str(error), 120)}): not read"
                       ) from None
    if owner != store.Owner("study", source.name):
        what = f"it holds {owner}" if owner is not None else "rlcompare wrote no marker there"
        raise _NotRead(f"{directory} is not the {source.name} study's ({what}): not read")
    path = directory / source.table
    if source.table not in listed or not path.is_file():
        raise _NotRead(f"the {source.name} study at {directory} has no verdict table rlcompare wrote "
                       f"('rlcompare report {directory}' writes it from its runs)")
    return path


def _read(source: Source, path: Path) -> pd.DataFrame:
    """The verdict file's rows as written (every cell a string); :class:`_Malformed` saying what is wrong. A
    blank file is a table without rows, as the study writes one where it had nothing to compare."""
    try:
        size = path.stat().st_size
        if size > MAX_TABLE_BYTES:
            raise _Malformed(f"{size:,} bytes, more than the study writes there")
        data = path.read_bytes()
        if not data.strip():
            return pd.DataFrame(columns=list(source.needed))
        frame = pd.read_csv(io.BytesIO(data), dtype=str, keep_default_na=False)
    except _Malformed:
        raise
    except (OSError, ValueError) as error:  # pandas' ParserError and EmptyDataError, UnicodeDecodeError: ValueErrors
        raise _Malformed(cut(str(error).strip() or type(error).__name__, 120)) from None
    missing = [column for column in source.needed if column not in frame.columns]
    if missing:
        raise _Malformed(f"no column {', '.join(repr(m) for m in missing)}")
    if (frame["verdict"].str.strip() == "").any():
        raise _Malformed("a row without a verdict")
    return frame


def _rows(source: Source, frame: pd.DataFrame) -> list[dict[str, object]]:
    p_values = pd.to_numeric(frame["p (Holm)"], errors="coerce")
    if source is PAPER:
        return [{"study": "paper (tabular)", "environment": MOUNTAIN_CAR.env, "engine: on- vs off-policy":
                 ENGINES["table"], "metric": PAPER_METRICS.get(row["metric"], row["metric"].replace("_", " ")),
                 "claim": row["claim"], "estimate": row["estimate"] or None, "estimate of": row["test"],
                 "p (Holm)": p, "verdict": row["verdict"]}
                for row, p in zip(frame.to_dict("records"), p_values, strict=True)]
    return [{"study": "deep (classic control)", "environment": row["env"],
             "engine: on- vs off-policy": ENGINES.get(row["engine"], row["engine"]), "metric": row["metric"],
             "claim": TWO_SIDED, "estimate": row["on - off (mean, 95% CI)"] or None,
             "estimate of": "on - off, mean [95% CI]", "p (Holm)": p, "verdict": row["verdict"]}
            for row, p in zip(frame.to_dict("records"), p_values, strict=True)]


def beside(study_dir: Path, own: pd.DataFrame, given: Mapping[str, Path | str] | None = None) -> Beside:
    """``own`` (rows in :data:`COLUMNS`) with the verdict rows of every source found (:func:`sibling_dirs`), and
    what was read, what was absent or not that study's, and which file was malformed."""
    rows, phrases, malformed = [own], [], []
    for name, directory in sibling_dirs(study_dir, given).items():
        source = SOURCES[name]
        try:
            path = _verified(source, directory)
            frame = _read(source, path)
        except _NotRead as why:
            phrases.append(str(why))
            continue
        except _Malformed as error:
            phrases.append(f"the {name} study's verdict file could not be read")
            malformed.append(f"{directory / source.table}: malformed ({error}); its rows are left out.")
            continue
        rows.append(pd.DataFrame(_rows(source, frame), columns=COLUMNS))
        phrases.append(f"the {name} study's {len(frame)} verdict{'s' if len(frame) != 1 else ''} "
                       f"({directory / source.table})")
    table = pd.concat([frame for frame in rows if not frame.empty] or [own], ignore_index=True)
    return Beside(table[COLUMNS] if not table.empty else pd.DataFrame(columns=COLUMNS),
                  "Beside this study: " + "; ".join(phrases) + ".", malformed)
