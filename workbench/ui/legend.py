"""The line above the charts: the log and window, the cursor and range, what the server is busy with, the terrain
keys and what the track colours mean. Every text from the session is escaped: log and terrain names are data."""

from __future__ import annotations

import html
from collections.abc import Sequence

from sessions import LogInfo, Terrain

from .charts import DRIFT, SURPRISE, UNSURE


def legend_html(
    log: LogInfo,
    window: tuple[int, int],
    *,
    terrains: Sequence[Terrain],
    cursor_s: float,
    selection: tuple[int, int] | None = None,
    busy: str = "",
    problem: str = "",
) -> str:
    """HTML of the legend for ``log`` with samples ``window`` = ``[a, b)`` on screen."""
    chips = "".join(
        f"<span style='display:inline-block;padding:0 6px;margin:1px 2px;border-radius:8px;"
        f"background:{_attr(t.color)}33;border:1px solid {_attr(t.color)}'>{i + 1} {html.escape(t.name)}</span>"
        for i, t in enumerate(terrains[:9])
    )
    sel = ""
    if selection is not None:
        s0, s1 = (x / log.rate_hz for x in selection)
        sel = f" · range <b>{s0:.2f}–{s1:.2f} s</b>"
    doing = f" · <i>{html.escape(busy)}…</i>" if busy else ""
    if problem:
        doing += f"<br><span style='color:#c62828'>{html.escape(problem)}</span>"
    a, b = window
    return (
        "<div style='font-size:0.8em;line-height:1.6'>"
        f"<b>{html.escape(log.name)}</b> · {a / log.rate_hz:.1f}–{b / log.rate_hz:.1f} s of {log.duration_s:.0f} s · "
        f"cursor {cursor_s:.2f} s{sel}{doing}<br>{chips}"
        f"<span style='color:{SURPRISE}'> ━ surprise</span>"
        f"<span style='color:{UNSURE}'> ━ uncertainty</span>"
        "<span style='background:#ffb30040'> highlighted </span>"
        f"<span style='background:{DRIFT}99;color:#fff'> drift: unlike anything labelled </span></div>"
    )


def _attr(text: str) -> str:
    return html.escape(text, quote=True)
