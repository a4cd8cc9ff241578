"""The label-efficiency curves as a PNG (matplotlib stays out of ``labeling``, which computes the curves)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from labeling import CurvePoint, mean_curve
from sessions import new_file


def plot_curves(
    curves: dict[str, Sequence[Sequence[CurvePoint]]], path: Path, *, total_samples: int, rate_hz: float, title: str
) -> Path:
    """Accuracy against labelled time (seconds; % of all time on the top axis), mean ± std over seeds, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=120)
    for k, v in curves.items():
        x, y, sd = mean_curve(v)
        style = {"lw": 2.5} if k == "combined" else {"lw": 1.4}
        seeds = f"{len(v)} seed" + ("" if len(v) == 1 else "s")
        ax.plot(x / rate_hz, 100 * y, marker="o", ms=3, label=f"{k} ({seeds})", **style)
        ax.fill_between(x / rate_hz, 100 * (y - sd), 100 * (y + sd), alpha=0.12)
    ax.set_xlabel("labelled time (s)")
    ax.set_ylabel("held-out accuracy (%)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    top = ax.secondary_xaxis(
        "top", functions=(lambda s: 100 * s * rate_hz / total_samples, lambda p: p * total_samples / (100 * rate_hz))
    )
    top.set_xlabel("labelled time (% of all time)")
    fig.tight_layout()
    try:
        with new_file(path) as tmp:
            fig.savefig(tmp)
    finally:
        plt.close(fig)
    return path
