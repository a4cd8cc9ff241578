"""What the session knows, taught to the model that ships: the session's own terrain over unlabelled stretches.

Inside a session a run's terrain is known from more than the model: the person's labels there vote over the run's
frames that resemble them (``propagate``), and the blend of those votes with the ensemble is what the page shows.
The exported bundle carries none of it: after four rounds of suggestions on a legged robot's runs the session was
99 % right on its new runs while the bundle scored 66 % on the robot's next runs. A stretch (a span with no label and
no change point) where the blend is sure of one terrain lends that terrain to stage 2's next fit, as self-training's
pseudo-labels do with the fit's own agreement.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

# the share of a stretch's steps the blend calls its most common terrain, at least, for the stretch to teach it: the
# rule self-training applies to the fold model's own rows. A mean probability of 0.9 taught nothing on BorealTC with
# one run per terrain (five calibrated classes: no step of a new run reached 0.9)
TEACHER_SURE = 0.9


def taught_terrains(
    probs: Sequence[np.ndarray | None],
    stretches: Sequence[tuple[int, int, int]],
    *,
    columns: Sequence[int] | None = None,
    sure: float = TEACHER_SURE,
) -> np.ndarray:
    """Per stretch ``(log, start, stop)``, the class the blend teaches there, ``-1`` where it teaches none.

    Args:
        probs: Per log, ``(T, K)`` the session's blended probabilities (``None``: the log was not scored); a
            memory-mapped array is read a stretch at a time.
        stretches: Unlabelled spans with no change point inside.
        columns: Per class taught, its column in ``probs`` (``-1``: the blend has none for it, it is never taught);
            default: the columns as they are.
        sure: The share of the stretch's steps whose most probable class is the stretch's most common one.

    Returns:
        ``(S,)`` int64 class indices (into ``columns`` when given, else into ``probs``' last axis).
    """
    out = np.full(len(stretches), -1, np.int64)
    for j, (i, a, b) in enumerate(stretches):
        p = probs[i]
        if p is None or b <= a:
            continue
        said = np.asarray(p[a:b]).argmax(axis=1)  # (L,) the blend's terrain per step, in its own columns
        if columns is not None:  # the blend's class -> the fit's (-1: a terrain the fit does not have)
            to_fit = np.full(np.asarray(p[:1]).shape[1], -1, np.int64)
            for k, c in enumerate(columns):
                if c >= 0:
                    to_fit[c] = k
            said = to_fit[said]
        votes = np.bincount(said[said >= 0], minlength=1)  # (K,)
        if votes.max() >= sure * len(said):
            out[j] = int(votes.argmax())
    return out
