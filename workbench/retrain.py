"""The Retrain's training settings, in one place: the UI's job, ``workbench serve``, the demo's quick start and the
label-efficiency simulation all read them from here, so what the simulation measures is what the button does."""

from __future__ import annotations

from dataclasses import dataclass, field

from training import TrainConfig, WindowFitConfig


@dataclass(frozen=True)
class RetrainSettings:
    """How the UI's Retrain trains.

    Attributes:
        hidden: LSTM width of a predictor trained from the UI (a classifier takes its predictor's width).
        predictor: Stage 1, when logs were added since it trained.
        classifier: Stage 2 from scratch (the refine phase, a new terrain, a new predictor). Stopping at 100 epochs
            with patience 20 keeps one label set's accuracy within 2 points over training seeds; 40 with patience 8
            moved it by 11.
        warm_epochs: The quick phase fine-tunes the active classifier for this many epochs on the labels added or
            changed since (``None``: every retrain trains as long as a fresh one). The old models fit all the older
            labels already, and a person waits for this one (``benchmarks/speed/bench_retrain.py``).
        warm_lr_scale: The fine-tune's learning rate, as a share of ``classifier.lr``: at the full rate two epochs of
            new labels and replayed old ones pulled the warm models off what they knew (QCAT-scale bench: 75.9 % on
            unlabelled trials at 0.005, 81.2 % at 0.001).
        refine: After the quick fine-tune, train stage 2 from scratch in the background and replace it.
        window: The default family's stage 2 from scratch (the refine phase, a new terrain, a new predictor).
        window_steps: The default family's quick phase: AdamW steps per fold model on the labels added or changed
            since, with as many older rows replayed (``training.fine_tune_window_classifier``). Its from-scratch fit
            is minutes on a big session (QCAT scale: 269 s), the quick phase seconds
            (``benchmarks/speed/bench_retrain.py``).
        window_lr_scale: The quick phase's learning rate as a share of ``window.lr``. Neither it nor
            ``window_steps`` was tuned on a benchmark: a fine-tune is a smaller step than a fit.
        teach: The fit from scratch is taught by the session: over an unlabelled stretch the session's scores (the
            ensemble blended with the run's label votes) are sure of, their terrain instead of the fit's own
            agreement (``cycle.train_classifier``'s ``teacher``). Off: on the far runs kept out of the session it
            moved the shipped model by +0.6 and +4.9 points on BorealTC (1 labelled run per terrain, seeds 1-2)
            and by -16.0 on the demo walks (92.4 -> 76.4 %, the session's new runs 94.0 -> 85.4 %): it teaches the
            early rounds' errors back (benchmarks/results/loop.md; `evaluate loop --strategies combined-teacher`).
    """

    hidden: int = 200
    predictor: TrainConfig = field(default_factory=lambda: TrainConfig(max_epochs=30, patience=5))
    classifier: TrainConfig = field(default_factory=lambda: TrainConfig(max_epochs=100, patience=20))
    warm_epochs: int | None = 2
    warm_lr_scale: float = 0.2
    refine: bool = True
    window: WindowFitConfig = field(default_factory=WindowFitConfig)
    window_steps: int = 150
    window_lr_scale: float = 0.3
    teach: bool = False


RETRAIN = RetrainSettings()
