"""MiniRocket's classifier: the fixed transform, a per-feature scale and a linear head (config dataclass + module).

A step's input is the last ``length`` normalised samples, flattened time-major ``(L·C,)``: what ``RawSteps``
hands the passes, the streaming step keeps in its ring and the ONNX graph takes. The head is a ridge classifier
fitted in closed form (:mod:`.rocket_fit`), as aeon's ``MiniRocketClassifier``, and its scores are turned into
probabilities by a temperature fitted on held-out windows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch
from torch import nn

from ..passes import per_distinct_row
from .rocket_kernels import CLIP, GRID, RocketConfig
from .rocket_transform import RocketTransform

ROCKET_KIND = "minirocket"  # the ``kind`` in a bundle's classifier config that names this module


@dataclass(frozen=True)
class RocketClassifierConfig:
    """Sizes of a MiniRocket classifier.

    Attributes:
        length: Samples per window.
        channels: Channels per sample.
        dilations: The transform's dilations.
        per_dilation: Features per kernel at each dilation.
        n_classes: Terrains.
        hop: Samples between windows: a stream's classifier runs every ``hop`` samples and holds its answer.
        kind: Always ``"minirocket"``: tells a bundle's config which module to rebuild.
    """

    length: int
    channels: int
    dilations: tuple[int, ...]
    per_dilation: tuple[int, ...]
    n_classes: int
    hop: int = 1
    kind: str = ROCKET_KIND

    def __post_init__(self) -> None:  # JSON gives lists back: keep the config hashable and equal to the saved one
        object.__setattr__(self, "dilations", tuple(int(d) for d in self.dilations))
        object.__setattr__(self, "per_dilation", tuple(int(n) for n in self.per_dilation))

    @property
    def rocket(self) -> RocketConfig:
        """The transform's config."""
        return RocketConfig(self.length, self.channels, self.dilations, self.per_dilation)

    @property
    def n_features(self) -> int:
        """Inputs per step: the window, flattened."""
        return self.length * self.channels


class RocketClassifier(nn.Module):
    """``(N, L·C)`` windows -> MiniRocket features -> scaled -> linear -> logits ``(N, K)``."""

    def __init__(self, config: RocketClassifierConfig) -> None:
        super().__init__()
        self.config = config
        self.transform = RocketTransform(config.rocket)
        f = config.rocket.features
        self.register_buffer("scale", torch.ones(f))  # 1 / each feature's spread on the labelled windows
        self.head = nn.Linear(f, config.n_classes)
        self.register_buffer("temperature", torch.ones(()))

    def transformed(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, L·C)`` -> MiniRocket features ``(N, F)`` of the windows on the grid
        (``rocket_kernels.on_grid``: exact sums, so every runtime gives the same features)."""
        x = windows.unflatten(1, (self.config.length, self.config.channels)).transpose(1, 2)  # (N, C, L)
        return self.transform(torch.round(x.clamp(-CLIP, CLIP) * GRID) / GRID)

    def features(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, L·C)`` -> the scaled features the head reads, ``(N, F)``."""
        return self.transformed(windows) * self.scale

    def logits(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, L·C)`` -> calibrated logits ``(N, K)``: the ridge scores over the temperature."""
        return self.head_logits(self.transformed(windows))

    def head_logits(self, transformed: torch.Tensor) -> torch.Tensor:
        """Calibrated logits ``(N, K)`` of features ``(N, F)`` already transformed (:meth:`transformed`): what
        members sharing one transform each compute from it."""
        return self.head(transformed * self.scale) / self.temperature

    def forward(self, features: torch.Tensor, state: None = None) -> tuple[torch.Tensor, None]:
        """``features (B, T, L·C)`` -> ``logits (B, T, K)``; no state is carried (the window is the input).

        A step's input changes once per hop (``RawSteps``), so the transform runs once per distinct consecutive
        row and the result is repeated.
        """
        return per_distinct_row(self.logits, features), None

    @staticmethod
    def ensemble_forward(members: Sequence[nn.Module]) -> Callable[[torch.Tensor], torch.Tensor] | None:
        """Every member's logits at once where they share one transform (one fit's folds differ in heads only):
        ``features (B, T, L·C)`` -> ``(M, B, T, K)``, the transform run once, not once per member. ``None`` where the
        members are not MiniRocket classifiers sharing a transform (the offline pass then runs each)."""
        if len(members) < 2 or not all(isinstance(m, RocketClassifier) for m in members):
            return None
        rockets = [m for m in members if isinstance(m, RocketClassifier)]
        if not shares_transform(rockets):
            return None

        def heads(windows: torch.Tensor) -> torch.Tensor:  # (N, L·C) -> (N, M·K)
            feats = rockets[0].transformed(windows)  # (N, F) once
            return torch.cat([m.head_logits(feats) for m in rockets], 1)

        def forward(features: torch.Tensor) -> torch.Tensor:
            b, t, _ = features.shape
            logits = per_distinct_row(heads, features)  # (B, T, M·K)
            return logits.view(b, t, len(rockets), -1).permute(2, 0, 1, 3)  # (M, B, T, K)

        return forward


def shares_transform(members: Sequence[RocketClassifier]) -> bool:
    """Every member's transform is the first's (masks and biases): one fit's ensemble, whose folds differ in heads."""
    first = members[0].transform
    return all(torch.equal(m.transform.masks, first.masks) and torch.equal(m.transform.biases, first.biases)
               for m in members[1:])  # fmt: skip
