"""How the kept scores are laid out: one ``.npy`` per array of each log, written whole or not at all and read back
memory-mapped, and the groups of logs a scoring writes before the next."""

from __future__ import annotations

import os
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeVar

import numpy as np

import labeling

GROUP_STEPS = 1 << 22  # samples of logs scored together and written before the next (11.7 h at 100 Hz)


class _Sized(Protocol):
    @property
    def n_samples(self) -> int: ...


S = TypeVar("S", bound=_Sized)


def log_groups(logs: Sequence[S], *, group_steps: int = GROUP_STEPS) -> list[list[S]]:
    """``logs`` in order, cut into groups of at most ``group_steps`` samples (a longer log is a group alone): what
    a pass over a fleet's logs scores and hands on before the next, so their scores are never held together."""
    groups: list[list[S]] = []
    size = 0
    for x in logs:
        if not groups or (groups[-1] and size + x.n_samples > group_steps):
            groups.append([])
            size = 0
        groups[-1].append(x)
        size += x.n_samples
    return groups


MAPPED_BYTES = 8 << 20  # a kept array this big or bigger is memory-mapped; smaller ones are read into memory


def kept_array(path: Path) -> np.ndarray:
    """A kept score array, read-only: memory-mapped when it is big (an hour's probabilities), read whole when small.

    Every memory map holds an open file: mapping each of a log's eleven arrays made a session of 300 short logs hold
    3,300 files, past the 1,024 a Linux desktop allows (and a 2,880-log session past 20,000), and its scores could no
    longer be kept or read. Small arrays cost their bytes in memory instead, which for such logs is little.
    """
    if path.stat().st_size >= MAPPED_BYTES:
        return np.load(path, mmap_mode="r")
    array = np.load(path)
    array.flags.writeable = False  # as a read-only map: nobody changes a kept score in place
    return array


def write_array(folder: Path, log_id: int, name: str, array: np.ndarray) -> np.ndarray:
    """Write one array whole or not at all; it comes back read-only (:func:`kept_array`)."""
    tmp = folder / f".{log_id:06d}.{name}.{uuid.uuid4().hex[:8]}.npy"
    with open(tmp, "wb") as f:
        np.save(f, np.asarray(array))
    path = folder / f"{log_id:06d}.{name}.npy"
    os.replace(tmp, path)
    return kept_array(path)


def score_arrays(s: labeling.LogScores) -> dict[str, np.ndarray]:
    """A log's scores as the named arrays kept for it (``surprise``, and what the model gives of the rest)."""
    arrays = {"surprise": np.asarray(s.surprise)}
    if s.probs is not None and s.disagreement is not None:
        arrays["probs"] = np.asarray(s.probs)
        arrays["disagreement"] = np.asarray(s.disagreement)
    if s.drift is not None:
        arrays["drift"] = np.asarray(s.drift)
    if s.probs is not None and s.agreement is not None:
        arrays["agreement"] = np.asarray(s.agreement)
    return arrays


def kept_scores(kept: dict[str, np.ndarray]) -> labeling.LogScores:
    """A log's scores from its kept arrays by name (:func:`score_arrays`' inverse)."""
    return labeling.LogScores(
        kept["surprise"], kept.get("probs"), kept.get("disagreement"), kept.get("drift"), kept.get("agreement")
    )


# what a scoring of groups hands back: what the groups agree on (None: no log), scores, embeddings, arrays' names
Scored = tuple["GroupFirst | None", dict[int, labeling.LogScores], dict, dict[str, list[str]]]


@dataclass(frozen=True)
class GroupFirst:
    """What every group's scoring agrees on: the versions, the classes, the span."""

    predictor: int | None
    classifier: int | None
    classes: tuple[str, ...]
    span: int
