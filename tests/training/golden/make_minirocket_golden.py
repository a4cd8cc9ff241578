"""Numbers aeon's MiniRocket computes, kept as the reference ``tests/training/test_rocket_transform.py`` checks our
PyTorch transform against (``make aeon-golden``: it runs in an environment of its own, ``.venv-aeon``, because aeon 1.6
pins NumPy below the version the workbench runs).

Writes ``minirocket_aeon.npz`` beside this file: seeded windows, aeon's fitted parameters and its features, for a
multichannel case with few features and a single-channel case of a real window length (1.7 s at 100 Hz).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from aeon import __version__ as aeon_version
from aeon.transformations.collection.convolution_based import MiniRocket

OUT = Path(__file__).resolve().parent / "minirocket_aeon.npz"
CASES = {"multi": (6, 4, 64, 840), "single": (3, 1, 170, 9996)}  # windows, channels, length, n_kernels


def main() -> None:
    rng = np.random.default_rng(0)
    arrays: dict[str, np.ndarray] = {}
    for name, (n, c, length, kernels) in CASES.items():
        # smooth signals with steps and noise: the sums then cross the biases at many positions
        x = np.cumsum(rng.normal(size=(n, c, length)), axis=2).astype(np.float32)
        x += rng.normal(scale=0.3, size=x.shape).astype(np.float32)
        rocket = MiniRocket(n_kernels=kernels, random_state=0).fit(x)
        per_combination, indices, dilations, per_dilation, biases = rocket.parameters
        arrays |= {
            f"{name}_x": x,
            f"{name}_per_combination": per_combination,
            f"{name}_indices": indices,
            f"{name}_dilations": dilations,
            f"{name}_per_dilation": per_dilation,
            f"{name}_biases": biases,
            f"{name}_features": rocket.transform(x).astype(np.float32),
            f"{name}_kernels": np.asarray(kernels),
        }
    arrays["aeon_version"] = np.asarray(aeon_version)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT, **arrays)
    print(f"wrote {OUT} (aeon {aeon_version})")


if __name__ == "__main__":
    main()
