"""What a deep run produces: every seed's episodes, evaluations and parameters, and the files its run directory holds
(written and read by :mod:`rlcompare.experiment.rundir`, with ``params.npz`` where a tabular run keeps its
Q-tables)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

import jax
import numpy as np
import pandas as pd

from rlcompare.deep.config import DeepConfig, json_round_trip, with_settings_added_since

EPISODE_COLUMNS = ["seed", "episode", "env_step", "return", "length", "terminated"]
EVALUATION_COLUMNS = ["seed", "round", "after_step", "return", "length", "terminated"]


@dataclass
class DeepResults:
    """Every seed of one deep configuration: its episodes, evaluations, final parameters and how the run went."""

    arrays_file: ClassVar[str] = "params.npz"
    """The run directory's file of arrays: the network's parameters at each stage, and the seeds."""

    config: DeepConfig
    episodes: pd.DataFrame
    """One row per seed x training episode, in the order they ended: ``env_step`` (environment steps of the
    seed's training when it ended, over all parallel environments), ``return``, ``length``, ``terminated``."""
    evaluations: pd.DataFrame
    """One row per seed x round x greedy episode; ``after_step``: the training steps before the round."""
    params: dict[str, np.ndarray]
    """Each parameter's path in the method's parameter tree (``jax.tree_util.keystr``) -> its array, with a
    leading seed axis."""
    meta: dict[str, Any]
    snapshots: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    """Each earlier stage of learning (:data:`~rlcompare.deep.rollout.STAGES`) -> its parameters, as ``params``
    (empty for a run written before deep runs kept them)."""

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.config.seeds

    @property
    def diverged(self) -> dict[int, int]:
        """Each seed whose training diverged -> the first update after which its parameters were not all finite
        (``meta.json``'s ``diverged``; none for a run written before it was recorded)."""
        return {int(seed): int(update) for seed, update in self.meta.get("diverged", {}).items()}

    def divergence(self) -> str:
        """Where the training diverged, in words for a report (empty where it did not): which seeds, from which
        update, and what that makes of their returns."""
        if not self.diverged:
            return ""
        seeds = ", ".join(f"{seed} (from update {update:,})" for seed, update in sorted(self.diverged.items()))
        return (f"{self.config.name}: the training diverged in {len(self.diverged)} of {len(self.seeds)} seeds: "
                f"{seeds}, its parameters no longer all finite; those seeds' returns are a network of NaNs', not a "
                "learned policy's")

    @property
    def stages(self) -> list[str]:
        """The stages of learning whose networks this run keeps, in order, ``final`` last."""
        return [*self.snapshots, "final"]

    def stacked_params(self, template: Any, stage: str = "final") -> Any:
        """Every seed's parameters at ``stage`` in the tree shape of ``template`` (the method's own,
        :func:`~rlcompare.deep.train.params_template`), with a leading seed axis; a name the stored file lacks is a
        :class:`ValueError`, a stage the run lacks a :class:`KeyError`."""
        if stage not in self.stages:
            raise KeyError(f"stage {stage!r} is not in this run; stages: {self.stages}")
        stored = self.params if stage == "final" else self.snapshots[stage]
        paths, tree = jax.tree_util.tree_flatten_with_path(template)
        names = [jax.tree_util.keystr(path) for path, _ in paths]
        missing = [name for name in names if name not in stored]
        if missing or len(names) != len(stored):
            raise ValueError(f"{self.arrays_file}: its parameters are not those of {self.config.algorithm}'s network "
                             f"(missing {missing[:3]}, {len(stored)} stored, {len(names)} expected)")
        return jax.tree_util.tree_unflatten(tree, [stored[name] for name in names])

    def seed_params(self, seed: int, template: Any, stage: str = "final") -> Any:
        """One seed's parameters (see :meth:`stacked_params`)."""
        if seed not in self.seeds:
            raise KeyError(f"seed {seed} is not in this run; seeds: {list(self.seeds)}")
        index = self.seeds.index(seed)
        return jax.tree.map(lambda leaf: leaf[index], self.stacked_params(template, stage))

    def labels(self) -> dict[str, str]:
        """The columns every row of its tables carries: study, environment, algorithm and preset."""
        return {"study": self.meta.get("study", ""), "env": self.config.env, "algorithm": self.config.algorithm,
                "schedule": self.config.preset}

    def columns(self) -> dict[str, dict[str, np.ndarray]]:
        """The columns of its tables beside the labels: ``episodes`` and ``evaluations``."""
        return {name: {column: frame[column].to_numpy() for column in frame.columns}
                for name, frame in (("episodes", self.episodes), ("evaluations", self.evaluations))}

    def arrays(self) -> dict[str, np.ndarray]:
        """What :attr:`arrays_file` holds: the final parameters, each earlier stage's, and the seeds."""
        return {**self.params, **_stage_arrays(self.snapshots), "seeds": np.asarray(self.seeds)}

    def record(self) -> dict[str, Any]:
        """What the run holds, for ``meta.json``: its seeds."""
        return {"seeds": list(self.seeds)}

    @classmethod
    def read_config(cls, stored: dict[str, Any], expected: DeepConfig | None) -> DeepConfig:
        """The configuration ``config.json`` holds, with the settings added since it was written; a
        :class:`ValueError` where it is not ``expected``, or its preset gives other hyperparameters now."""
        config = DeepConfig.from_dict(stored)
        stored = with_settings_added_since(stored, config)
        if expected is not None and json_round_trip(expected.to_dict()) != stored:
            raise ValueError("another configuration than the one asked for")
        if json_round_trip(config.to_dict()) != stored:
            raise ValueError("its hyperparameters are not what its preset gives now (written by another version of "
                             "rlcompare); run it again")
        return config

    @classmethod
    def from_files(cls, config: DeepConfig, episodes: pd.DataFrame, evaluations: pd.DataFrame,
                   arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> DeepResults:
        """The results a run directory's files hold; a :class:`ValueError` where they do not belong to ``config``."""
        seeds = arrays.pop("seeds", np.array([])).tolist()
        params, snapshots = _split_stages(arrays)
        if seeds != list(config.seeds) or set(episodes["seed"]) - set(seeds):
            raise ValueError(f"the seeds of {cls.arrays_file} or episodes.parquet differ from those of config.json")
        return cls(config, episodes[EPISODE_COLUMNS].reset_index(drop=True),
                   evaluations[EVALUATION_COLUMNS].reset_index(drop=True), params, meta, snapshots)


def merge_seeds(parts: list[DeepResults]) -> DeepResults:
    """One :class:`DeepResults` from runs of one configuration on other seeds (a sweep's one-seed trials), the
    seeds in the order of ``parts``; wall-clock and compile seconds are summed."""
    first = parts[0]
    seeds = tuple(seed for part in parts for seed in part.seeds)
    timings = dict(first.meta["timings"])
    for key in ("wall_seconds", "compile_seconds"):
        timings[key] = sum(part.meta["timings"][key] for part in parts)
    wall = timings["wall_seconds"]
    timings["steps_per_second"] = timings["training_steps"] * len(seeds) / wall if wall > 0 else None
    return DeepResults(dataclasses.replace(first.config, seeds=seeds),
                       pd.concat([part.episodes for part in parts], ignore_index=True),
                       pd.concat([part.evaluations for part in parts], ignore_index=True),
                       _concatenated([part.params for part in parts]),
                       {**first.meta, "seeds": list(seeds), "timings": timings,
                        "diverged": {str(seed): update for part in parts for seed, update in part.diverged.items()}},
                       {stage: _concatenated([part.snapshots[stage] for part in parts]) for stage in first.snapshots
                        if all(stage in part.snapshots for part in parts)})


def _concatenated(arrays: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {name: np.concatenate([part[name] for part in arrays]) for name in arrays[0]}


STAGE_SEPARATOR = ":"
"""``params.npz`` names an earlier stage's array ``<stage>:<path>`` (a path starts with ``[``)."""


def _stage_arrays(snapshots: dict[str, dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {f"{stage}{STAGE_SEPARATOR}{name}": array for stage, arrays in snapshots.items()
            for name, array in arrays.items()}


def _split_stages(stored: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, dict[str, np.ndarray]]]:
    """``params.npz``'s arrays as ``(final parameters, {stage: parameters})``, in the order they were written."""
    final: dict[str, np.ndarray] = {}
    snapshots: dict[str, dict[str, np.ndarray]] = {}
    for name, array in stored.items():
        stage, separator, path = name.partition(STAGE_SEPARATOR)
        if separator and not stage.startswith("["):
            snapshots.setdefault(stage, {})[path] = array
        else:
            final[name] = array
    return final, snapshots
