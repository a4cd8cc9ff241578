"""Research runs over datasets, all the protocols in one place: the folds and fits on arrays (``evaluate_windows`` and
``evaluate_spectral``: BorealTC's partitions and runs, per family; ``evaluate_sequences``: QCAT and held-out logs),
the datasets they read (``protocols``), a user's own session (``session_eval``), and the label-efficiency simulation
with its report and plot."""

from .evaluate_sequences import held_out_logs_protocol, qcat_protocol
from .evaluate_spectral import borealtc_window_protocol, window_inputs
from .evaluate_windows import (
    FoldResult,
    Split,
    WindowProtocol,
    borealtc_protocol,
    labelled_subset,
    outer_folds,
    partitions,
    windows,
)
from .far_runs import FarRuns, FarScore, read_far_runs, score_far
from .label_efficiency import SimSettings, report, simulate_logs, simulate_partitions
from .protocol_members import FoldData, Member, RocketMember, cut_windows
from .protocols import (
    BOREALTC_PUBLISHED,
    evaluate_borealtc,
    evaluate_demo,
    evaluate_qcat,
    load_recordings,
    load_runs,
    simulate,
    truth_arrays,
)
from .session_eval import evaluate_session
from .session_loop import LoopRound, LoopSettings, evaluate_loop

__all__ = [
    "BOREALTC_PUBLISHED",
    "FarRuns",
    "FarScore",
    "FoldData",
    "FoldResult",
    "LoopRound",
    "LoopSettings",
    "Member",
    "RocketMember",
    "SimSettings",
    "Split",
    "WindowProtocol",
    "borealtc_protocol",
    "borealtc_window_protocol",
    "cut_windows",
    "evaluate_borealtc",
    "evaluate_demo",
    "evaluate_loop",
    "evaluate_qcat",
    "evaluate_session",
    "held_out_logs_protocol",
    "labelled_subset",
    "load_recordings",
    "load_runs",
    "outer_folds",
    "partitions",
    "qcat_protocol",
    "read_far_runs",
    "report",
    "score_far",
    "simulate",
    "simulate_logs",
    "simulate_partitions",
    "truth_arrays",
    "window_inputs",
    "windows",
]
