"""Research runs over datasets: the BorealTC, QCAT and demo protocols, and the label-efficiency simulation with its
report and plot."""

from .label_efficiency import SimSettings, report, simulate_logs, simulate_partitions
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

__all__ = [
    "BOREALTC_PUBLISHED",
    "SimSettings",
    "evaluate_borealtc",
    "evaluate_demo",
    "evaluate_qcat",
    "evaluate_session",
    "load_recordings",
    "load_runs",
    "report",
    "simulate",
    "simulate_logs",
    "simulate_partitions",
    "truth_arrays",
]
