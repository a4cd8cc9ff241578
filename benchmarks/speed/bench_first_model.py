"""Time to a first model, as a new user meets it: `workbench train SESSION` (both stages, the default family) on a
new session of 1 hour and of 10 hours of 22-channel 100 Hz logs (demo walks as ROS 2 MCAP) with 5 % of the time
labelled; `workbench train` then `workbench export --predictions` on a session shaped as a quadruped's logs (11 IMU
CSVs of 6 to 10 minutes, 6 channels at 50 Hz, 10 % labelled in 5 s pieces: :mod:`imu_logs`), by the default family
and by MiniRocket (`--model minirocket`) on copies of the same session; and `workbench demo`'s
first start to a served page.

Each step runs in a fresh interpreter, as a person runs the command, and reports its wall time and peak resident set
(``ru_maxrss``). Writing, ingesting and labelling the logs are set-up, timed but not part of the figure.

References, measured in the same run on the same session:

- for `workbench train`: reading the logs and computing the default family's spectral frames from them (fitting the
  input normalisation over every log, choosing the front end, the frames of every log), in a fresh interpreter
  too. No stage 1 over the frames can take less; the figure says what training adds to it.
- for MiniRocket's train + export: the default family's on the same session.
- for the demo: writing its six walks and ingesting them (`generate_demo_logs` and `workbench ingest`), the part
  of its first start that has no model in it.
"""

from __future__ import annotations

import json
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from speed_common import Row, free_port, parse_args, record, wait_answering

LABELLED = 0.05
IMU_LABELLED = 0.10  # the quadruped-shaped session's labels: 10 % of the time, in 5 s pieces


def child(step: str, *args: str) -> dict:
    """Run one step of this file in a fresh interpreter; what it printed last (JSON: its peak RSS and seconds)."""
    out = subprocess.run([sys.executable, __file__, "--child", step, *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{step} failed:\n{out.stdout[-2000:]}\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_child(step: str, args: list[str]) -> None:
    t = time.perf_counter()
    extra: dict = {}
    if step == "setup":  # write the walks, ingest them, label 5 % of the time
        from sessions import Session
        from workbench.demo import generate_demo_logs, seed_labels

        folder, n_logs, minutes = Path(args[0]), int(args[1]), float(args[2])
        files = generate_demo_logs(folder / "logs", n_logs=n_logs, minutes=minutes, seed=0)
        with Session.create(folder / "session") as s:
            logs = s.ingest(files)
            for name in {t for x in logs for _, _, t in s.reference(x.id)} - {t.name for t in s.terrains()}:
                s.add_terrain(name)
            added = seed_labels(s, LABELLED, seed=0)
            steps = sum(x.n_samples for x in logs)
            extra = {
                "logs": len(logs),
                "hours": steps / logs[0].rate_hz / 3600,
                "channels": len(logs[0].channel_names),
                "labelled": sum(g.stop - g.start for g in added) / steps,
            }
    elif step == "setup-imu":  # 11 IMU CSVs at 50 Hz, ingested, the reference imported, 10 % labelled in 5 s pieces
        from speed_common import write_imu_logs

        from sessions import Session
        from workbench.demo import seed_labels

        folder = Path(args[0])
        files, reference = write_imu_logs(
            folder / "logs", n_logs=int(args[1]), minutes=(float(args[2]), float(args[3]))
        )
        with Session.create(folder / "session") as s:
            logs = s.ingest(files)
            s.import_reference(reference, create_terrains=True)
            added = seed_labels(s, IMU_LABELLED, seed=0, segment_s=5.0)
            steps = sum(x.n_samples for x in logs)
            extra = {
                "logs": len(logs),
                "hours": steps / logs[0].rate_hz / 3600,
                "steps": steps,
                "channels": len(logs[0].channel_names),
                "rate": logs[0].rate_hz,
                "labelled": sum(g.stop - g.start for g in added) / steps,
            }
    elif step in ("export", "export-untaught"):  # `workbench export SESSION --out OUT --predictions [--untaught]`
        from workbench.cli import main as workbench

        untaught = ["--untaught"] if step == "export-untaught" else []
        if workbench(["export", args[0], "--out", args[1], "--predictions", *untaught]) != 0:
            raise SystemExit("workbench export failed")
        extra = {"predictions": Path(args[1], "predictions.parquet").stat().st_size}
    elif step == "frames":  # the reference: read the logs, fit the normalisation, compute every log's frames
        from sessions import Session
        from training import Normalizer, log_frames
        from workbench.cycle import choose_front_end

        with Session.open(Path(args[0])) as s:
            logs = s.logs()
            normalizer = Normalizer.fit([s.rows(x.id) for x in logs])
            front = choose_front_end(s, logs)
            extra = {"frames": sum(len(log_frames(s.rows(x.id), front, transform=normalizer)) for x in logs)}
    elif step == "train":  # `workbench train SESSION --model FAMILY`, in this interpreter: its peak is this one's
        from workbench.cli import main as workbench

        if workbench(["train", args[0], "--model", args[1]]) != 0:
            raise SystemExit("workbench train failed")
        from sessions import Session

        with Session.open(Path(args[0])) as s:
            v = s.active_model("classifier")
            extra = {"classifier": v.id if v else None, "stage1": s.active_model("predictor").config.get("kind")}
    else:
        raise SystemExit(f"unknown step {step}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # kB on Linux
    print(json.dumps({"peak": peak, "seconds": time.perf_counter() - t, **extra}))


def demo_first_start(folder: Path, *, quick: bool) -> tuple[float, float]:
    """Seconds from `workbench demo` to its page answering, and the reference: writing and ingesting its logs."""
    size = ["--logs", "2", "--minutes", "1"] if quick else []
    workbench = str(Path(sys.executable).with_name("workbench"))
    port = free_port()
    t = time.perf_counter()
    proc = subprocess.Popen(
        [workbench, "demo", "--session", str(folder / "demo"), "--port", str(port), *size],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        wait_answering(proc, f"http://127.0.0.1:{port}/", name="workbench demo")
        served = time.perf_counter() - t
    finally:
        proc.terminate()
        proc.wait(30)
    t = time.perf_counter()
    n_logs, minutes = ("2", "1") if quick else ("6", "5")
    code = (
        "import sys; from pathlib import Path; from workbench.demo import generate_demo_logs; "
        f"generate_demo_logs(Path(sys.argv[1]), n_logs={n_logs}, minutes={minutes}, seed=0)"
    )
    subprocess.run([sys.executable, "-c", code, str(folder / "ref-logs")], check=True)
    subprocess.run([workbench, "new", str(folder / "ref")], check=True, capture_output=True)
    subprocess.run(
        [workbench, "ingest", str(folder / "ref"), str(folder / "ref-logs")], check=True, capture_output=True
    )
    return served, time.perf_counter() - t


def session_steps(
    setup_step: str, args: list[str], *, export: bool, models: tuple[str, ...] = ("default",)
) -> tuple[dict, dict, dict[str, tuple[dict, dict | None]]]:
    """In a temporary folder, each in a fresh interpreter: the set-up, the reference (the frames), then per family in
    ``models`` on its own copy of the session: `workbench train --model FAMILY` and, with ``export``, `workbench
    export --predictions`; what each reported."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        setup = child(setup_step, str(folder), *args)
        print(f"set-up {setup}", flush=True)
        ref = child("frames", str(folder / "session"))
        print(f"reference {ref}", flush=True)
        runs = {}
        for model in models:
            session = str(folder / f"session-{model}")
            shutil.copytree(folder / "session", session)
            train = child("train", session, model)
            print(f"train {model} {train}", flush=True)
            exported = child("export", session, str(folder / f"export-{model}")) if export else None
            if exported:
                print(f"export {model} {exported}", flush=True)
            runs[model] = (train, exported)
            if export and model == "default":  # the export's reference: the active version shipped as it is
                runs["untaught"] = (train, child("export-untaught", session, str(folder / "export-untaught")))
                print(f"export --untaught {runs['untaught'][1]}", flush=True)
    return setup, ref, runs


def imu_first_model(*, quick: bool) -> list[Row]:
    """`workbench train` then `workbench export --predictions` on a session shaped as a quadruped's IMU logs, by the
    default family and by MiniRocket on copies of the same session."""
    n_logs, low, high = ("3", "1", "2") if quick else ("11", "6", "10")
    setup, ref, runs = session_steps("setup-imu", [n_logs, low, high], export=True, models=("default", "minirocket"))
    shape = (
        f"{setup['logs']} logs of {low}-{high} min, {setup['steps']:,} steps of {setup['channels']}-channel "
        f"{setup['rate']:.0f} Hz IMU CSV, {setup['labelled']:.1%} labelled in 5 s pieces"
    )

    def figure(model: str) -> tuple[float, str]:
        train, export = runs[model]
        total = train["seconds"] + export["seconds"]
        peak = max(train["peak"], export["peak"]) / 2**30
        parts = f"train {train['seconds']:.0f} s, export {export['seconds']:.0f} s"
        return total, f"{total:.0f} s ({parts}), peak {peak:.2f} GiB RSS"

    default, default_text = figure("default")
    rocket, rocket_text = figure("minirocket")
    taught, untaught = runs["default"][1]["seconds"], runs["untaught"][1]["seconds"]
    return [
        Row(
            f"`workbench export --predictions` after a first `train`, the bundle taught by the session, {shape}",
            f"{taught:.0f} s",
            f"`export --predictions --untaught` (the active version as it is), same session: {untaught:.0f} s",
            f"{taught / untaught:.1f}× the untaught export",
            "measured: the taught fit's cost at the first export",
            None,
            "–",
        ),
        Row(
            f"`workbench train` + `export --predictions` (default family), {shape}",
            default_text,
            f"reading the logs + computing the frames: {ref['seconds']:.0f} s",
            f"{default / ref['seconds']:.1f}× the reference",
            "≤ 60 s",
            bool(default <= 60),
            f"stage 1: {runs['default'][0]['stage1']}; classifier v{runs['default'][0]['classifier']}",
        ),
        Row(
            "`workbench train --model minirocket` + `export --predictions`, the same session",
            rocket_text,
            f"the default family's train + export, same session: {default:.0f} s",
            f"{rocket / default:.2f}× the default",
            "≤ 2× the default",
            bool(rocket <= 2 * default),
            f"classifier v{runs['minirocket'][0]['classifier']}",
        ),
    ]


def main() -> None:
    if "--child" in sys.argv:
        i = sys.argv.index("--child")
        run_child(sys.argv[i + 1], sys.argv[i + 2 :])
        return
    args = parse_args(__doc__)
    sizes = ((2, 3.0, 60.0), (4, 6.0, 600.0)) if args.quick else ((6, 10.0, 60.0), (20, 30.0, 600.0))
    rows = []
    for n_logs, minutes, target in sizes:
        setup, ref, runs = session_steps("setup", [str(n_logs), str(minutes)], export=False)
        train = runs["default"][0]
        hours, gb = setup["hours"], train["peak"] / 2**30
        rows.append(
            Row(
                f"`workbench train` (both stages, default family), new session of {setup['logs']} logs, "
                f"{hours:.1f} h of {setup['channels']}-channel 100 Hz logs, {setup['labelled']:.1%} labelled",
                f"{train['seconds']:.0f} s, peak {gb:.2f} GiB RSS ({train['peak'] / 1e9:.2f} GB)",
                f"reading the logs + computing the frames: {ref['seconds']:.0f} s, peak {ref['peak'] / 2**30:.2f} GiB",
                f"{train['seconds'] / ref['seconds']:.1f}× the reference",
                f"≤ {target:.0f} s" + (", ≤ 2 GiB" if target > 60 else ""),
                bool(train["seconds"] <= target and (target <= 60 or gb <= 2.0)),
                f"stage 1: {train['stage1']}; classifier v{train['classifier']}",
            )
        )
    rows.extend(imu_first_model(quick=args.quick))
    with tempfile.TemporaryDirectory() as tmp:
        served, reference = demo_first_start(Path(tmp), quick=args.quick)
    rows.append(
        Row(
            "`workbench demo` first start to a served page (writes, ingests, labels 2 %, trains both stages, scores)",
            f"{served:.0f} s",
            f"writing and ingesting its logs: {reference:.0f} s",
            f"{served / reference:.1f}× the reference",
            "≤ 60 s",
            bool(served <= 60),
        )
    )
    record("first_model", rows, device=args.device)


if __name__ == "__main__":
    main()
