"""The names a bundle's ``model.json`` gives the default family's modules (each config's ``kind``), apart from the
modules themselves so that a bundle is read without loading PyTorch (:mod:`training.runtime.scoring_bundle`)."""

WINDOW_KIND = "frames"  # the stage-2 window classifier's
OLD_WINDOW_KINDS = ("window",)  # the linear model on summaries that preceded it: refused with a hint to retrain
FRAME_PREDICTOR_KIND = "next-frame"  # stage 1's next-frame predictor's
