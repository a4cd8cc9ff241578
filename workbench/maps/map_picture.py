"""``terrain-map.png``: every log's path coloured by terrain, for the report and the model card.

Tracks of one frame share a panel (GNSS runs in local metres from one fix, so a patch seen twice lines up); tracks
of other frames get panels of their own beside it. Labels in full colour, the model's sure answers lighter,
the rest grey; metres on both axes at one scale, a scale bar, and north on a GNSS panel.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .terrain_paths import GREY, GREY_ALPHA, LABEL, MODEL, LogPath, colour_of, panel_of, stretches

WIDTH = {LABEL: 3.2, MODEL: 2.4}  # source -> line width; unsure: GREY_WIDTH
GREY_WIDTH = 1.4
MOST_PANELS = 12  # panels drawn (the rest counted in the title)
COLUMNS = 4


def write_map_picture(paths: list[LogPath], terrains: list[tuple[str, str]], out: Path) -> Path | None:
    """Draw ``paths`` (``terrains``: each terrain's name and colour, in the session's order) to ``out`` as PNG;
    ``None`` (nothing written) when no log has a path."""
    if not paths:
        return None
    import matplotlib

    matplotlib.use("Agg")  # no display on a robot's build machine
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    frames = list(dict.fromkeys(panel_of(p) for p in paths))
    shown = frames[:MOST_PANELS]
    cols = min(COLUMNS, len(shown))
    rows = -(-len(shown) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(max(8.0, 5.5 * cols), 5.5 * rows + 1.0), squeeze=False)
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    for ax, frame in zip(axes.flat, shown, strict=False):
        mine = [p for p in paths if panel_of(p) == frame]
        for path in mine:
            segments, colours, widths = [], [], []
            for a, b, terrain, source in stretches(path):
                if b - a < 2:
                    continue
                _, colour, alpha = colour_of(terrain, source, terrains)
                width = WIDTH.get(source, GREY_WIDTH) if terrain >= 0 else GREY_WIDTH
                rgba = matplotlib.colors.to_rgba(colour, alpha)
                segments.append(path.xy[a:b])
                colours.append(rgba)
                widths.append(width)
            ax.add_collection(LineCollection(segments, colors=colours, linewidths=widths, capstyle="round"))
            ax.annotate(path.log, path.xy[0], fontsize=7, color="#424242", xytext=(3, 3), textcoords="offset points")
        everything = np.concatenate([p.xy for p in mine])  # (N, 2)
        lo, hi = everything.min(axis=0), everything.max(axis=0)
        widest = float((hi - lo).max())
        centre = (lo + hi) / 2
        lo, hi = np.minimum(lo, centre - 0.3 * widest), np.maximum(hi, centre + 0.3 * widest)  # no sliver panels
        pad = max(1.0, 0.05 * widest)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        geographic = mine[0].frame == "wgs84"
        ax.set_xlabel("east (m)" if geographic else "x (m)")
        ax.set_ylabel("north (m)" if geographic else "y (m)")
        kinds = ", ".join(sorted({p.kind for p in mine}))
        where = "GNSS, metres from the first fix" if geographic else frame if len(mine) == 1 else f"frame {frame}"
        ax.set_title(f"{where} ({kinds}; {len(mine)} log(s))", fontsize=10)
        ax.grid(True, color="#eeeeee")
        bar = _bar_metres(float((hi - lo).max() + 2 * pad))
        ax.add_artist(AnchoredSizeBar(ax.transData, bar, f"{bar:g} m", "upper right", frameon=False, size_vertical=0))
        if geographic:
            ax.annotate(
                "N",
                xy=(0.04, 0.95),
                xytext=(0.04, 0.83),
                xycoords="axes fraction",
                ha="center",
                arrowprops={"arrowstyle": "-|>", "color": "#424242"},
                fontsize=10,
            )
    handles = [Line2D([], [], color=c, lw=3.2, label=n) for n, c in terrains]
    handles += [
        Line2D([], [], color="#424242", lw=3.2, label="labelled"),
        Line2D([], [], color="#424242", lw=2.4, alpha=0.45, label="the model's answer"),
        Line2D([], [], color=GREY, lw=GREY_WIDTH, alpha=GREY_ALPHA, label="unsure or unscored"),
    ]
    fig.legend(
        handles=handles, loc="lower center", ncol=min(len(handles), 4 if cols == 1 else 7), frameon=False, fontsize=9
    )
    more = f" ({len(frames) - len(shown)} more panel(s) not drawn)" if len(frames) > len(shown) else ""
    fig.suptitle(f"Where each terrain was{more}")
    fig.tight_layout(rect=(0, 0.1 if cols == 1 else 0.07, 1, 0.96))
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _bar_metres(span: float) -> float:
    """A round length about a fifth of ``span`` metres: 1, 2 or 5 times a power of ten."""
    target = max(span / 5.0, 1e-3)
    power = 10.0 ** np.floor(np.log10(target))
    return float(max(m * power for m in (1.0, 2.0, 5.0) if m * power <= target))
