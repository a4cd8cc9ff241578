"""MiniRocket: fixed dilated convolutions pooled into proportions of positives, and a ridge head.

The field's standard baseline for time-series classification (Dempster et al., 2021; aeon's ``MiniRocket`` and
``MiniRocketClassifier``), written in PyTorch so that it streams and exports to ONNX: :mod:`.rocket_kernels` (the
fixed kernels and the fit of dilations, channel subsets and biases, in NumPy), :mod:`.rocket_transform` (the
transform), :mod:`.rocket_classifier` (transform, scale, linear head), :mod:`.rocket_fit` (the ridge head and its
temperature, on windows), :mod:`.raw_steps` (a log's per-step windows), :mod:`.rocket_steps_fit` (stage 2 in a
session: blocked folds, held-out logs), :mod:`.rocket_step` (one sample at a time; the ONNX step),
:mod:`.rocket_family` (what the registry reads).
"""

from ..lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "rocket_kernels": ("RocketConfig", "RocketParameters", "aeon_parameters", "fit_rocket"),
        "rocket_transform": ("RocketTransform",),
        "rocket_classifier": ("ROCKET_KIND", "RocketClassifier", "RocketClassifierConfig"),
        "rocket_fit": ("fit_rocket_classifier", "rocket_features"),
        "raw_steps": ("RawSteps",),
        "rocket_steps_fit": ("fit_rocket_steps",),
        "rocket_step": ("RocketStep", "RocketStepModel"),
        "rocket_family": ("FAMILY",),
    },
    globals(),
)
