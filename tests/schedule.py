"""The order `make test` hands test files to its two pytest-xdist workers: the longest first.

`--dist loadfile` gives each worker one file at a time, in collection order (`--no-loadscope-reorder`; xdist's own
reorder puts the files with the most tests first, which left the 40 s browser and torchrun files for the end, where
one worker ran them alone while the other sat idle). Handing out the longest files first lets the short ones fill
the gaps, so both workers finish within a few seconds of each other.
"""

from __future__ import annotations

# Files that took 7 s or more in `make test` (summed setup, call and teardown, `pytest --durations=0`), longest
# first. A file missing here only runs later; a stale entry only costs balance, never a test.
LONGEST_FIRST = (
    "tests/workbench/cycle/test_default_family.py",
    "tests/browser/test_workbench_ui.py",
    "tests/safety/test_security.py",
    "tests/workbench/test_torchrun.py",
    "tests/safety/test_kill_training.py",
    "tests/safety/test_kill_labels.py",
    "tests/browser/test_serve_page.py",
    "tests/browser/test_first_screen.py",
    "tests/safety/test_hostile_cli.py",
    "tests/safety/test_upload_totals.py",
    "tests/workbench/evaluation/test_session_loop.py",
    "tests/workbench/cycle/test_cycle.py",
    "tests/workbench/cycle/test_frame_stage1.py",
    "tests/workbench/cli/test_own_logs.py",
    "tests/safety/test_bombs.py",
    "tests/workbench/evaluation/test_label_efficiency.py",
    "tests/workbench/cycle/test_drift_session.py",
    "tests/safety/test_disk_full.py",
    "tests/workbench/cycle/test_session_estimates.py",
    "tests/workbench/evaluation/test_session_eval.py",
    "tests/training/test_window_family.py",
    "tests/workbench/ui/test_ui_state.py",
)


def pytest_collection_modifyitems(session, config, items) -> None:
    """Move the files of ``LONGEST_FIRST`` to the front in its order; every other file keeps its place after them."""
    rank = {path: i for i, path in enumerate(LONGEST_FIRST)}
    position = {id(item): i for i, item in enumerate(items)}
    items.sort(key=lambda item: (rank.get(item.nodeid.split("::")[0], len(rank)), position[id(item)]))
