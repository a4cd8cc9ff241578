"""The export's scoring of every log, a group of logs at a time: a fleet's per-step scores are never held together.

`export --predictions` scored every log in one call and built one table of every step before writing it; at a
fleet's hours that is every log's probabilities, then a table of tens of millions of rows with a string per step.
Here each group is scored, handed over log by log (a Parquet row group each, an MCAP file each, the card's per-log
figures), and dropped before the next.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

import labeling
from sessions import LogInfo

from .. import cycle

GROUP_STEPS = cycle.GROUP_STEPS  # samples of logs scored at a time (11.7 h at 100 Hz), as the UI's first start


def scored_logs(
    logs: Sequence[LogInfo],
    score: Callable[[list[int]], dict[int, labeling.LogScores]],
    *,
    group_steps: int | None = None,
) -> Iterator[tuple[LogInfo, labeling.LogScores]]:
    """Each log with its scores, in the order of ``logs``, scored a group at a time by ``score(log_ids)`` (groups of
    ``group_steps`` samples, default :data:`GROUP_STEPS`)."""
    for group in cycle.log_groups(logs, group_steps=GROUP_STEPS if group_steps is None else group_steps):
        scored = score([x.id for x in group])
        for x in group:
            yield x, scored.pop(x.id)
        del scored


class PredictionsWriter:
    """One Parquet file written a log at a time (a row group each) with the schema of the first log's table."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._writer = None

    def write(self, frame: pd.DataFrame) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(frame, preserve_index=False)
        if self._writer is None:
            self._writer = pq.ParquetWriter(self.path, table.schema)
        self._writer.write_table(table.cast(self._writer.schema))

    def close(self, empty: pd.DataFrame) -> Path:
        """Finish the file; with no log written, write ``empty`` (the columns and no row)."""
        if self._writer is None:
            empty.to_parquet(self.path, index=False)
        else:
            self._writer.close()
        return self.path


def with_drift_column(frame: pd.DataFrame, drift: bool) -> pd.DataFrame:
    """``frame`` with a ``drift`` column when the model gives one (NaN for a log it did not score), else without."""
    if drift and "drift" not in frame:
        frame["drift"] = np.full(len(frame), np.nan, np.float32)
    return frame
