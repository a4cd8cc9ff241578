"""What the card says against what new runs score, on a demo session labelled one run per terrain (issue 42).

Three demo walks; in each, the longest reference patch of a terrain no other walk has is labelled whole. The
default family is trained as ``workbench train --stage classifier`` would; its estimate (a same-run figure: each
terrain is in one log) is printed beside its accuracy on three new walks of another seed, on their time of the
labelled terrains. ``--nominal`` draws the walks without run conditions (speed, gait, gains, IMU mounting).

    python benchmarks/one_run_per_terrain.py [--nominal]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np

from sessions import Session
from training import TrainConfig
from workbench import cycle
from workbench.cli import main
from workbench.demo import TERRAINS, RunConditions, generate_demo_logs
from workbench.demo import run_conditions as run_module

STAGE1 = TrainConfig(max_epochs=2, patience=1, chunk=32, piece=256, batch_size=16, label_piece=64, context=32)


def one_run_per_terrain(root: Path) -> Path:
    """A session whose three walks each have one whole patch labelled, of three different terrains."""
    with Session.create(root / "s") as s:
        for name in TERRAINS:  # a new session has none
            s.add_terrain(name)
        s.ingest(generate_demo_logs(root / "logs", n_logs=3, minutes=1.5, seed=11))
        taken: set[str] = set()
        for log in s.logs():
            a, b, terrain = max((r for r in s.reference(log.id) if r[2] not in taken), key=lambda r: r[1] - r[0])
            s.add_segment(log.id, a, b, terrain, author="benchmark")
            taken.add(terrain)
        cycle.train_predictor(s, config=STAGE1, hidden=8)
    return root / "s"


def main_() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nominal", action="store_true", help="walks without run conditions")
    args = parser.parse_args()
    if args.nominal:
        run_module.RunConditions.draw = classmethod(lambda cls, seed: RunConditions())  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        path = one_run_per_terrain(root)
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            main(["train", str(path), "--stage", "classifier"])
        print(next(line for line in out.getvalue().splitlines() if line.startswith("classifier v")))
        with Session.open(path) as s:
            new = s.ingest(generate_demo_logs(root / "new", n_logs=3, minutes=1.5, seed=12))
            _, bundle = cycle.active_bundle(s)
            scored = cycle.score_session(s, [x.id for x in new])
            right = total = 0
            for x in new:
                predicted = np.asarray(bundle.classes)[scored[x.id].probs.argmax(1)]
                for a, b, terrain in s.reference(x.id):
                    if terrain in bundle.classes:
                        right += int((predicted[a:b] == terrain).sum())
                        total += b - a
        walks = "nominal walks" if args.nominal else "walks that differ by run"
        print(
            f"{walks}: accuracy on 3 new walks, their {total / 100:.0f} s of the labelled terrains: "
            f"{100 * right / total:.1f} %"
        )


if __name__ == "__main__":
    main_()
