"""Resumable stage-1 training: everything a killed run needs to go on where it stopped, in one safetensors file.

Weights, Adam's moments and the best weights so far are tensors; the epoch, batch, loss history, early-stopping
counters and the NumPy generator's state are JSON in the file's metadata. No pickle. The file is replaced whole
(written under a temporary name, synced, renamed), so a kill during a save leaves the previous checkpoint.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file

CHECKPOINT_SCHEMA = 1


@dataclass
class Checkpoint:
    """Where a stage-1 run is, at a batch boundary.

    Attributes:
        fingerprint: What the run trains on and how (see :func:`fingerprint`); a checkpoint of another run is
            ignored.
        epoch: The epoch in progress (1-based).
        batch: Batches of that epoch already done.
        done: Early stopping (or the epoch limit) ended the run; only the model still has to be saved.
        total: Sum of squared errors over this epoch's batches so far, all processes together.
        count: Timesteps behind ``total``.
        history: Finished epochs: epoch, train_loss, val_loss.
        best: Best validation loss so far.
        best_epoch: Its epoch.
        since: Epochs since it.
        rng: The NumPy generator's state (``bit_generator.state``).
        order: The permutation of training pieces of the epoch in progress.
        model: Current weights.
        best_model: Weights at ``best_epoch``.
        optimizer: ``optimizer.state_dict()``.
    """

    fingerprint: str
    epoch: int
    batch: int
    done: bool
    total: float
    count: float
    history: list[dict[str, float]]
    best: float
    best_epoch: int
    since: int
    rng: dict
    order: torch.Tensor
    model: dict[str, torch.Tensor]
    best_model: dict[str, torch.Tensor]
    optimizer: dict = field(repr=False)
    settings: dict = field(default_factory=dict)  # what ``fingerprint`` digests, to say how another run differs


def fingerprint(**what: object) -> str:
    """A short digest of JSON-able settings and data shapes; a checkpoint resumes only a run with the same one."""
    return hashlib.sha256(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()[:16]


def keyed_path(base: str | Path, key: str) -> Path:
    """The checkpoint file of the run ``key`` fingerprints, beside ``base``: runs of other settings never replace
    each other's checkpoints, so each can still be resumed by running it again."""
    base = Path(base)
    return base.with_name(f"{base.stem}-{key}{base.suffix}")


def other_checkpoints(base: str | Path, key: str, settings: dict) -> list[str]:
    """One line per checkpoint beside ``base`` of another run than ``key``: its epoch and how its settings differ."""
    base = Path(base)
    out = []
    for path in sorted(base.parent.glob(f"{base.stem}-*{base.suffix}")):
        if path == keyed_path(base, key):
            continue
        try:
            with safe_open(str(path), framework="pt") as f:
                meta = json.loads(f.metadata()["checkpoint"])
        except (SafetensorError, OSError, KeyError, ValueError):
            continue
        theirs = meta.get("settings") or {}
        diff = [
            f"{k} {_short(theirs.get(k))} (now {_short(settings.get(k))})"
            for k in sorted(set(theirs) | set(settings))
            if theirs.get(k) != settings.get(k)
        ]
        out.append(f"{path.name}: epoch {meta.get('epoch')}, " + ("; ".join(diff) or "settings not recorded"))
    return out


def _short(value: object) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}={v}" for k, v in value.items()) + "}" if len(value) <= 4 else "{...}"
    if isinstance(value, list):
        return f"[{len(value)} items]"
    return str(value)


def save_checkpoint(ckpt: Checkpoint, path: str | Path) -> None:
    """Write ``ckpt`` to ``path``, replacing the file whole."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tensors = {f"model.{k}": v.detach().cpu().contiguous() for k, v in ckpt.model.items()}
    tensors |= {f"best.{k}": v.detach().cpu().contiguous() for k, v in ckpt.best_model.items()}
    tensors["order"] = ckpt.order.cpu().contiguous()
    opt_meta: dict[str, dict[str, object]] = {}
    for idx, state in ckpt.optimizer["state"].items():
        for key, value in state.items():
            if isinstance(value, torch.Tensor):
                tensors[f"optimizer.{idx}.{key}"] = value.detach().cpu().contiguous()
            else:
                opt_meta.setdefault(str(idx), {})[key] = value
    meta = {k: v for k, v in asdict(ckpt).items() if k not in ("model", "best_model", "optimizer", "order")}
    meta |= {"schema": CHECKPOINT_SCHEMA, "param_groups": ckpt.optimizer["param_groups"], "optimizer_scalars": opt_meta}
    tmp = path.with_name(f".{path.name}.tmp")  # one writer (the main process); a kill's leftover is overwritten
    try:
        save_file(tensors, str(tmp), metadata={"checkpoint": json.dumps(meta)})
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def load_checkpoint(path: str | Path, expected: str) -> Checkpoint | None:
    """The checkpoint at ``path`` if there is one for the run ``expected`` fingerprints, else None.

    A file that is not a whole checkpoint (it cannot be: saves are atomic, but a disk can lie) counts as none.
    """
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with safe_open(str(path), framework="pt") as f:
            meta = json.loads(f.metadata()["checkpoint"])
        if meta.get("schema") != CHECKPOINT_SCHEMA or meta.get("fingerprint") != expected:
            return None
        tensors = load_file(str(path))
    except (SafetensorError, OSError, KeyError, ValueError):
        return None
    state: dict[int, dict[str, object]] = {}
    for name, value in tensors.items():
        if name.startswith("optimizer."):
            _, idx, key = name.split(".", 2)
            state.setdefault(int(idx), {})[key] = value
    for idx, scalars in meta.pop("optimizer_scalars").items():
        state.setdefault(int(idx), {}).update(scalars)
    optimizer = {"state": state, "param_groups": meta.pop("param_groups")}
    meta.pop("schema")
    return Checkpoint(
        **meta,
        order=tensors["order"],
        model={k[6:]: v for k, v in tensors.items() if k.startswith("model.")},
        best_model={k[5:]: v for k, v in tensors.items() if k.startswith("best.")},
        optimizer=optimizer,
    )
