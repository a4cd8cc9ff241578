"""Small matplotlib figures for the page (confusion matrix, learning curve), rendered to RGB arrays."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def _render(fig) -> np.ndarray:
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    import matplotlib.pyplot as plt

    plt.close(fig)
    return img


def confusion_image(confusion: Sequence[Sequence[int]], classes: Sequence[str], *, title: str) -> np.ndarray:
    """``(H, W, 3)`` uint8 picture of a confusion matrix (rows: truth, columns: prediction), row-normalised."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = np.asarray(confusion, np.float64)
    norm = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(3.9, 3.4), dpi=100)
    ax.imshow(norm, cmap="Greens", vmin=0, vmax=1)
    k = len(classes)
    ax.set_xticks(range(k), classes, rotation=45, ha="right", fontsize=7)
    ax.set_yticks(range(k), classes, fontsize=7)
    for i in range(k):
        for j in range(k):
            if m[i, j]:
                ax.text(
                    j,
                    i,
                    f"{norm[i, j]:.0%}",
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="white" if norm[i, j] > 0.6 else "black",
                )
    ax.set_xlabel("predicted", fontsize=8)
    ax.set_ylabel("labelled", fontsize=8)
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    return _render(fig)


def learning_curve_image(points: Sequence[tuple[float, float, float, int]]) -> np.ndarray:
    """``(H, W, 3)`` accuracy and macro-F1 (out of fold) against labelled seconds, one point per version
    ``(seconds, accuracy, macro_f1, version)``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(3.9, 2.4), dpi=100)
    if points:
        pts = sorted(points)
        x = [p[0] for p in pts]
        ax.plot(x, [100 * p[1] for p in pts], "o-", color="#2e7d32", ms=3, label="accuracy")
        ax.plot(x, [100 * p[2] for p in pts], "s--", color="#6a1b9a", ms=3, label="macro-F1")
        for p in pts:
            ax.annotate(f"v{p[3]}", (p[0], 100 * p[1]), fontsize=6, xytext=(2, 3), textcoords="offset points")
        ax.legend(fontsize=7, loc="lower right")
    ax.set_xlabel("labelled time (s)", fontsize=8)
    ax.set_ylabel("out-of-fold %", fontsize=8)
    ax.set_ylim(0, 100)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _render(fig)
