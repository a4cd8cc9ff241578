"""What a Label Studio project's labelling config says the backend must answer with: the ``TimeSeriesLabels``
control (its name, the object it labels, its labels) and whether that ``TimeSeries`` keeps time on a date axis."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

from sessions import LABEL_STUDIO_CONTROL, LABEL_STUDIO_OBJECT


@dataclass(frozen=True)
class LabelConfig:
    """The parts of a project's config a prediction names.

    Attributes:
        from_name: The ``TimeSeriesLabels`` control's name.
        to_name: The ``TimeSeries`` object it labels.
        labels: The labels it offers, in order (the terrains, as the project spells them).
        dates: Whether the object's time column is parsed as a date (``timeFormat``): regions are then
            milliseconds on the log's clock, as Label Studio keeps them there; else seconds.
    """

    from_name: str = LABEL_STUDIO_CONTROL
    to_name: str = LABEL_STUDIO_OBJECT
    labels: tuple[str, ...] = ()
    dates: bool = False

    def label_for(self, terrain: str) -> str | None:
        """The project's label for a terrain (case and spaces aside: ``Wet floor`` is ``wet-floor``), if any."""
        if not self.labels:
            return terrain
        key = name_key(terrain)
        return next((x for x in self.labels if name_key(x) == key), None)


def name_key(name: str) -> str:
    """A terrain's name as Label Studio and the session are matched by: case, spaces and punctuation aside."""
    return "".join(c for c in name.lower() if c.isalnum())


def parse_label_config(text: object) -> LabelConfig:
    """The time-series labelling part of ``text`` (a project's ``label_config``); our own export's names where the
    text is missing or holds no ``TimeSeriesLabels``.

    Raises:
        ValueError: ``text`` is not XML.
    """
    if not isinstance(text, str) or not text.strip():
        return LabelConfig()
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ValueError(f"the project's labelling config is not XML ({exc})") from None
    control = next(iter(root.iter("TimeSeriesLabels")), None)
    if control is None:
        return LabelConfig()
    to_name = control.get("toName", LABEL_STUDIO_OBJECT).split(",")[0]
    series = next((e for e in root.iter("TimeSeries") if e.get("name") == to_name), None)
    labels = tuple(e.get("value", "") for e in control.iter("Label") if e.get("value"))
    dates = series is not None and bool(series.get("timeFormat"))
    return LabelConfig(control.get("name", LABEL_STUDIO_CONTROL), to_name, labels, dates)
