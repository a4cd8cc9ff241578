"""What a stage-2 fit needs from the session, read once: the family, the active predictor and its bundle, the logs
it reads, the labelled segments and their classes, and the classifier active before it. A Retrain's quick phase and
the fit from scratch it falls back to take the same value, so neither asks the session again."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from sessions import LogInfo, ModelVersion, Segment, Session, WorkbenchError
from training import Family, ModelBundle, SpectralConfig

from .train_stages import active_predictor, front_end_of, model_logs, require_stage1


@dataclass(frozen=True, eq=False)
class FitInputs:
    """The session as a stage-2 fit reads it.

    Attributes:
        family: The family fitted.
        predictor: The active predictor's version (the new classifier's ``predictor``).
        bundle: Its bundle (stage 1, the normaliser, the front end); the new version is saved with it.
        logs: The logs whose channels the predictor reads, in the order the segments index them.
        classes: The terrains labelled, in the session's order.
        used: The session's label segments in those logs.
        segments: ``(log index, start, stop, class index)`` of each of ``used``.
        previous: The classifier active before this fit, ``None`` before any.
    """

    family: Family
    predictor: ModelVersion
    bundle: ModelBundle
    logs: list[LogInfo]
    classes: tuple[str, ...]
    used: list[Segment]
    segments: list[tuple[int, int, int, int]]
    previous: ModelVersion | None

    def front_end(self, session: Session) -> SpectralConfig:
        """The spectral front end a frames or windows family reads (``train_stages.front_end_of``)."""
        return front_end_of(session, self.bundle, self.logs)


def fit_inputs(session: Session, fam: Family) -> FitInputs:
    """Read what a stage-2 fit of ``fam`` needs, once.

    Raises:
        WorkbenchError: No predictor yet; a family reading stage 1's outputs over another kind of stage 1; fewer
            than two terrains labelled.
    """
    version, bundle = active_predictor(session)
    require_stage1(session, fam, version, bundle)
    logs = model_logs(session, bundle.channels)
    classes, used, segments = _labelled(session, logs)
    return FitInputs(fam, version, bundle, logs, classes, used, segments, session.active_model("classifier"))


def _labelled(
    session: Session, logs: Sequence[LogInfo]
) -> tuple[tuple[str, ...], list[Segment], list[tuple[int, int, int, int]]]:
    index = {x.id: i for i, x in enumerate(logs)}
    used = [s for s in session.segments() if s.log_id in index]
    # the classes are the terrains labelled: a terrain nobody labelled would be an empty row of the confusion matrix
    # and a column of zeros in every prediction file
    labelled = {s.terrain for s in used}
    classes = tuple(t.name for t in session.terrains() if t.name in labelled)
    segments = [(index[s.log_id], s.start, s.stop, classes.index(s.terrain)) for s in used]
    if len({s[3] for s in segments}) < 2:
        raise WorkbenchError(f"{session.path}: label segments of at least two terrains before training the classifier")
    return classes, used, segments
