"""The label-efficiency plot (moved out of ``labeling`` with matplotlib)."""

from pathlib import Path

from labeling import CurvePoint
from workbench.evaluation.curves_plot import plot_curves


def test_plot(tmp_path: Path) -> None:
    curves = {
        "random": [[CurvePoint(100, 0.5, 0.0), CurvePoint(200, 0.6, 0.0)]] * 2,
        "combined": [
            [CurvePoint(100, 0.6, 0.0), CurvePoint(200, 0.7, 0.0)],
            [CurvePoint(100, 0.8, 0.0), CurvePoint(200, 0.9, 0.0)],
        ],
    }
    png = plot_curves(curves, tmp_path / "c.png", total_samples=1000, rate_hz=100.0, title="t")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
