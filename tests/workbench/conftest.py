"""What the workbench's test modules share."""

from __future__ import annotations

from dataclasses import replace

import pytest

from workbench.retrain import RETRAIN


@pytest.fixture(scope="module")
def fast_window_fits():
    """For tests that check what the default family's fits do (families, folds, fine-tunes, reports), not how well:
    8 of the 60 passes and 4 of the 10 refit passes, in a session's training and in ``evaluate session``'s folds.
    Modules ask for it with ``pytestmark = pytest.mark.usefixtures("fast_window_fits")``."""
    with pytest.MonkeyPatch.context() as mp:
        fast = replace(RETRAIN, window=replace(RETRAIN.window, epochs=8, refit_epochs=4))
        mp.setattr("workbench.cycle.stage2_fit.RETRAIN", fast)
        mp.setattr("workbench.evaluation.session_eval.RETRAIN", fast)
        yield
