"""Readers for robot logs (ROS 2 MCAP, QCAT / BorealTC / generic CSV) and alignment onto one time base."""

from .align import AlignedLog, DiscardRows, align
from .base import ChannelSpec, IngestOptions, Mapping, ParsedLog, Stream, load_mapping
from .csv_reader import sniff_csv
from .mcap_reader import TopicReport, read_mcap
from .poses import PoseTrack, local_metres
from .sources import Source, plan_sources, read_source
from .time_columns import TimeColumn

__all__ = [
    "AlignedLog",
    "ChannelSpec",
    "DiscardRows",
    "IngestOptions",
    "Mapping",
    "ParsedLog",
    "PoseTrack",
    "Source",
    "Stream",
    "TimeColumn",
    "TopicReport",
    "align",
    "load_mapping",
    "local_metres",
    "plan_sources",
    "read_mcap",
    "read_source",
    "sniff_csv",
]
