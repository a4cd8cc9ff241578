"""The ``workbench`` command line: typed functions parsed by tyro, one per subcommand.

User errors (bad files, bad sessions, refused labels) print one line and exit 2; nothing prints a traceback unless
``WORKBENCH_DEBUG=1`` is set.
"""

from __future__ import annotations

import inspect
import os
import sys
from pathlib import Path
from typing import Annotated, Literal

import tyro

from sessions import MAX_RATE_HZ, IngestError, IngestOptions, Session, WorkbenchError, load_mapping, name_refusal

from ..retrain import RETRAIN
from ..user_errors import USER_ERRORS, one_line
from . import evaluate_command, label_commands, label_studio_command, model_commands
from .ingest_report import dry_run_report
from .stopping import Terminated, sigterm_unwinds
from .terminal import EscapingStream, shown

Pos = tyro.conf.Positional


def _err(message: str) -> None:
    print(f"error: {shown(message)}", file=sys.stderr)


def new(session: Pos[Path], terrains: tuple[str, ...] = ()) -> None:
    """Create an empty session folder. It has no terrains until you name them (here, with `workbench terrains`, or
    from a label file with --create-terrains).

    Args:
        session: Folder to create (may exist if empty).
        terrains: Terrain classes to start with, e.g. --terrains grass gravel ice.
    """
    for name in terrains:  # before the folder is made: a refused name leaves no half-made session
        if (why := name_refusal(name.strip(), "terrain")) is not None:
            raise WorkbenchError(why)
    with Session.create(session) as s:
        for name in terrains:
            s.add_terrain(name)
        named = f"; terrains: {', '.join(shown(t.name) for t in s.terrains())}" if terrains else "; no terrains yet"
        print(f"created session {shown(s.path)} (schema {s.schema_version}){named}")


def ingest(
    session: Pos[Path],
    files: Pos[list[Path]],
    mapping: Path | None = None,
    dry_run: bool = False,
    allow_gaps: bool = False,
    rate: float | None = None,
    camera_fps: float = IngestOptions.camera_fps,
) -> int:
    """Ingest robot logs (ROS 2 MCAP, QCAT / BorealTC / generic CSV; folders are searched) into a session.

    Each file is all-or-nothing: a bad one prints one line naming it and the reason, and the session stays as it
    was for that file. Exit code 2 when any file was refused.

    Args:
        session: The session folder.
        files: Log files or folders of them.
        mapping: TOML or JSON file naming topics/columns to read (see README "Bring your own logs").
        dry_run: Show what would be read (channels, rates, gaps) as an editable mapping file; write nothing.
        allow_gaps: Accept NaN/inf samples and dropouts, recording them as gaps instead of refusing the file.
        rate: Rate (Hz) of the aligned time base; default: the fastest stream's median rate.
        camera_fps: Most camera frames kept a second per image topic (sensor_msgs/Image, CompressedImage), stored
            as JPEG beside the log for the UI; 0 keeps none.
    """
    if not camera_fps >= 0:
        raise WorkbenchError(f"--camera-fps must be 0 or more, not {camera_fps}")
    if rate is not None and not 0 < rate <= MAX_RATE_HZ:
        raise WorkbenchError(f"--rate {rate:g}: a rate is above 0 and at most {MAX_RATE_HZ:g} Hz")
    options = IngestOptions(
        mapping=load_mapping(mapping) if mapping else IngestOptions().mapping,
        rate_hz=rate,
        allow_gaps=allow_gaps,
        camera_fps=camera_fps,
    )
    if dry_run:
        ok, text = dry_run_report(files, options)
        print(text)
        return 0 if ok else 2
    from tqdm import tqdm

    failures: list[IngestError] = []
    for note in _same_files(files):
        print(f"note: {shown(note)}")
    with Session.open(session) as s:
        before = {log.id for log in s.logs()}
        with tqdm(total=0, unit="B", unit_scale=True, desc="ingest", disable=None) as bar:

            def progress(done: int, total: int) -> None:
                bar.total = total
                bar.n = done
                bar.refresh()

            def on_error(err: IngestError) -> None:
                failures.append(err)
                bar.write(f"error: {shown(one_line(err))}", file=sys.stderr)

            logs = s.ingest(files, options=options, on_error=on_error, progress=progress)
        added = [log for log in logs if log.id not in before]
        for log in added:
            gaps = f", {len(log.gaps)} gaps" if log.gaps else ""
            print(f"+ {shown(log.name)}: {log.duration_s:.1f} s at {log.rate_hz:g} Hz, {log.n_channels} channels{gaps}")
            for note in log.info.get("notes", ()):  # type: ignore[union-attr]
                print(f"  note: {shown(note)}")
            for cam in log.info.get("cameras", ()):  # type: ignore[union-attr]
                if cam.get("skipped"):
                    n = cam["skipped"]
                    print(
                        f"  warning: camera {shown(cam['topic'])}: skipped {n} camera frame{'s' * (n > 1)} "
                        f"({shown(cam['skipped_why'])}); {cam['frames']} kept"
                    )
        already = len(logs) - len(added)
        print(
            f"ingested {len(added)} log(s)"
            + (f", {already} already in the session" if already else "")
            + (f", refused {len(failures)} file(s)" if failures else "")
        )
    return 2 if failures else 0


def _same_files(files: list[Path]) -> list[str]:
    """A line per file given again under another path (a link, ``./``): it is read once, and says so."""
    seen: dict[Path, Path] = {}
    out = []
    for f in files:
        try:
            key = f.resolve()
        except OSError:
            continue
        if f.is_file() and key in seen and seen[key] != f:
            out.append(f"{f} is {seen[key]} (one file): read once")
        seen.setdefault(key, f)
    return out


def info(session: Pos[Path]) -> None:
    """Show a session's logs, terrains and labels.

    Args:
        session: The session folder.
    """
    with Session.open(session) as s:
        logs = s.logs()
        segments = s.segments()
        print(f"session {shown(s.path)} (schema {s.schema_version})")
        print(f"{len(logs)} log(s), {sum(log.duration_s for log in logs) / 60:.1f} min in all")
        width = max((len(shown(log.name)) for log in logs), default=4)
        for log in logs:
            lab = sum(seg.length for seg in segments if seg.log_id == log.id)
            ref = f"  reference={shown(log.reference_terrain)}" if log.reference_terrain else ""
            ref += "".join(f"  camera {shown(c.topic)} ({c.frames} frames)" for c in s.cameras(log.id))
            print(
                f"  {log.id:>4}  {shown(log.name):<{width}}  {log.format:<8} {log.duration_s:>9.1f} s  "
                f"{log.rate_hz:>7g} Hz  {log.n_channels:>3} ch  {len(log.gaps):>3} gaps  "
                f"{lab / max(log.n_samples, 1):>6.1%} labelled{ref}"
            )
        print(
            "terrains: "
            + (", ".join(shown(t.name) for t in s.terrains()) or "none yet (workbench terrains SESSION add NAME)")
        )
        print(f"{len(segments)} label segment(s)")


def terrains(
    session: Pos[Path],
    action: Pos[Literal["list", "add", "rename", "remove"]] = "list",
    names: Pos[tuple[str, ...]] = (),
    color: str | None = None,
) -> None:
    """List, add, rename or remove terrain classes.

    `workbench terrains S` lists them with their labelled time; `add NAME...` adds; `rename OLD NEW` renames (labels
    follow); `remove NAME...` removes terrains no label uses (a used one is refused, nothing removed).

    Args:
        session: The session folder.
        action: list, add, rename or remove.
        names: The terrain names the action takes.
        color: Colour of an added terrain, #rrggbb (default: the next of a palette).
    """
    with Session.open(session) as s:
        if action == "add":
            if not names:
                raise WorkbenchError("terrains add: name at least one terrain")
            for name in names:
                t = s.add_terrain(name, color=color)
                print(f"added terrain {shown(t.name)} ({t.color})")
        elif action == "rename":
            if len(names) != 2:
                raise WorkbenchError("terrains rename: give the old name and the new one")
            s.rename_terrain(*names)
            print(f"renamed terrain {shown(names[0])} to {shown(names[1])}")
        elif action == "remove":
            if not names:
                raise WorkbenchError("terrains remove: name at least one terrain")
            s.remove_terrains(names)
            print(f"removed terrain(s): {', '.join(shown(n) for n in names)}")
        else:
            seconds: dict[str, float] = {}
            rates = {x.id: x.rate_hz for x in s.logs()}
            for seg in s.segments():
                seconds[seg.terrain] = seconds.get(seg.terrain, 0.0) + seg.length / rates[seg.log_id]
            for t in s.terrains():
                print(f"  {shown(t.name):<20} {t.color}  {seconds.get(t.name, 0.0):>9.1f} s labelled")
            if not s.terrains():
                hint = "or import labels with --create-terrains"
                print(f"no terrains yet: `workbench terrains {session} add NAME...`, {hint}")


def serve(
    session: Pos[Path],
    host: str = "127.0.0.1",
    port: int = 8080,
    token: str | None = None,
    no_token: bool = False,
    hidden: int = RETRAIN.hidden,
    stage1_epochs: int = RETRAIN.predictor.max_epochs,
    stage2_epochs: int = RETRAIN.classifier.max_epochs,
    open_map: Annotated[bool, tyro.conf.arg(name="map")] = False,
) -> None:
    """Serve the workbench UI for a session in the browser.

    Only pages this server serves may use it (requests naming another Host or Origin get 403). Beyond loopback
    every request also needs the token, printed in the URL at start.

    Args:
        session: The session folder.
        host: Address to bind. The default serves this machine only.
        port: Port to listen on; a taken port is an error. 0 picks any free one.
        token: The token requests must carry, at least 16 characters (default: none on loopback, a new random one
            beyond it).
        no_token: Serve without a token; allowed on loopback only.
        hidden: LSTM width of a predictor trained from the UI (a classifier takes its predictor's width).
        stage1_epochs: Most epochs of a predictor retrain from the UI (early stopping may end it sooner).
        stage2_epochs: Most epochs of a classifier retrain from the UI.
        open_map: Open every page on the map of the log on screen (its path coloured by terrain) instead of the robot,
            where the log has positions; **M** switches on the page either way.
    """
    from training import hide_gpus

    from ..ui.app import WorkbenchApp
    from ..ui.gate import check_token, is_loopback, new_token

    if no_token and token is not None:
        raise WorkbenchError("--token and --no-token contradict each other: choose one")
    if no_token and not is_loopback(host):
        raise WorkbenchError(f"--no-token serves {host} to anyone who reaches the port: allowed on loopback only")
    if token is None and not no_token and not is_loopback(host):
        token = new_token()
    check_token(token, host=host)  # before the session opens: an empty --token is refused, never served
    hide_gpus()  # the UI trains and scores on the CPU: a GPU seen by torch would keep its fits from forking
    s = Session.open(session)
    if not is_loopback(host):
        print(
            f"warning: serving on {host}: anyone who can reach this port and has the token in the URL can read and "
            "change the session, over plain HTTP; prefer an SSH tunnel to a loopback server, see README",
            file=sys.stderr,
        )
    from ..ui import LANE

    LANE.expect()  # serve_forever gives this thread to the torch work: the scoring worker must not start its own
    try:
        app = WorkbenchApp(
            s,
            host=host,
            port=port,
            token=token,
            hidden=hidden,
            max_epochs=(stage1_epochs, stage2_epochs),
            open_map=open_map,
        )
    except BaseException:
        LANE.expect_no_more()
        raise
    print(f"workbench serving {shown(s.path)} at {app.url}", flush=True)
    app.serve_forever()


def demo(
    session: Path = Path("demo-session"),
    host: str = "127.0.0.1",
    port: int = 8080,
    logs: int = 6,
    minutes: float = 5.0,
    seed: int = 0,
    seed_labels: float = 0.02,
    epochs: int = 15,
    hidden: int = 64,
    serve_ui: Annotated[bool, tyro.conf.arg(name="serve")] = True,
) -> None:
    """Generate demo robot logs, ingest them, label a few segments, train both stages, serve the UI.

    Reuses the session when it exists already, so running it again just serves.

    Args:
        session: Session folder to create (or reuse).
        host: Address to bind.
        port: Port to listen on.
        logs: Number of demo walks to generate.
        minutes: Typical length of each walk.
        seed: Seed of the generator.
        seed_labels: Fraction of the time labelled from the demo's ground truth (0: a blank start, no training).
        epochs: Most epochs of the paper family's LSTM stage 1, when the session uses it: a quick start;
            `workbench train` does the full run. The default family's stage 1 trains a fixed number of steps.
        hidden: Width of the paper family's LSTMs, when the session uses them: smaller than the paper's 200 so that
            training, scoring and a retrain from the page take minutes on a laptop's CPU (`workbench train --model
            paper --hidden 200` gives the paper's width). The default family's sizes are its own.
        serve_ui: Serve the UI when ready (--no-serve: prepare the session and exit); the page opens on the map
            of the field the walks cross (**M**: the robot).
    """
    from training import hide_gpus

    from ..demo import TERRAINS, generate_demo_logs
    from ..demo import seed_labels as add_seed_labels

    hide_gpus()  # the demo trains and serves on the CPU (see serve)

    if (session / "session.sqlite").exists():
        with Session.open(session) as s:
            print(f"using existing demo session {shown(s.path)} ({len(s.logs())} logs)")
    else:
        log_dir = session.with_name(session.name + "-logs")
        paths = generate_demo_logs(log_dir, n_logs=logs, minutes=minutes, seed=seed, progress=True)
        print(f"wrote {len(paths)} demo logs to {shown(log_dir)}/ (ground truth beside each in .truth.json)")
        Session.create(session).close()
        if ingest(session, [log_dir]):
            raise WorkbenchError("demo logs failed to ingest")
        with Session.open(session) as s:
            for name in TERRAINS:  # the demo's own: a new session has none
                s.add_terrain(name)
            added = add_seed_labels(s, seed_labels, seed=seed)
            print(f"labelled {len(added)} segment(s) from the demo's ground truth ({seed_labels:.0%} of the time)")
        if added:
            model_commands.train(
                session, stage="predictor", max_epochs=epochs, patience=max(3, epochs // 4), hidden=hidden
            )
            if len({seg.terrain for seg in added}) >= 2:
                # stage 2 on a few seconds of labels is cheap: let early stopping end it, not the quick-start cap
                stage2 = RETRAIN.classifier  # as the page's Retrain trains it
                model_commands.train(
                    session, stage="classifier", max_epochs=stage2.max_epochs, patience=stage2.patience, hidden=hidden
                )
            else:
                print("classifier: skipped (the seed labels cover fewer than two terrains)")
            from ..ui import score_and_keep

            with Session.open(session) as s:
                print("scoring the logs for the page's first screen", flush=True)
                score_and_keep(s)
    if serve_ui:
        serve(session, host=host, port=port, hidden=hidden, open_map=True)  # the demo walks cross a field: open on it


def labels() -> None:
    """Label files: `workbench labels export SESSION --out F`, `workbench labels import SESSION F`."""


def evaluate() -> None:
    """Measure the method: `workbench evaluate borealtc|qcat|demo FOLDER` (a dataset's protocol, or --simulate the
    label efficiency), `evaluate session|loop SESSION` (your own logs, leave-logs-out or as a person works them)."""


COMMANDS = {
    "new": new,
    "ingest": ingest,
    "info": info,
    "train": model_commands.train,
    "export": model_commands.export,
    "classify": model_commands.classify,
    "evaluate": evaluate,
    "labels": labels,
    "suggest": label_commands.suggest,
    "terrains": terrains,
    "serve": serve,
    "demo": demo,
    "label-studio": label_studio_command.label_studio,
}
LABEL_COMMANDS = {"export": label_commands.labels_export, "import": label_commands.labels_import}


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``workbench`` console script. Returns the exit code."""
    argv = sys.argv[1:] if argv is None else argv
    stdout = sys.stdout
    if not {"-h", "--help"} & set(argv) and not isinstance(stdout, EscapingStream):
        sys.stdout = EscapingStream(stdout)  # type: ignore[assignment]  # help keeps tyro's colours
    try:
        return _run(argv)
    finally:
        sys.stdout = stdout


def _run(argv: list[str]) -> int:
    try:
        with sigterm_unwinds():
            return _parse_and_run(argv)
    except USER_ERRORS as exc:
        _err(one_line(exc))
        return 2
    except Terminated:
        return 143  # 128 + SIGTERM, what a shell reports for a command it terminated
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # the reader went away (`... | head`): stop quietly, as a shell pipeline expects
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python's own flush at exit would raise again
        return 141  # 128 + SIGPIPE, what a shell reports for a command its pipe closed
    except Exception as exc:
        if os.environ.get("WORKBENCH_DEBUG"):
            raise
        _err(f"internal error: {type(exc).__name__}: {exc} (set WORKBENCH_DEBUG=1 for the traceback)")
        return 1


def _parse_and_run(argv: list[str]) -> int:
    if argv[:1] == ["labels"]:  # tyro has no nested subcommands over functions: route them here
        result = tyro.extras.subcommand_cli_from_dict(
            LABEL_COMMANDS, prog="workbench labels", description="Export or import label files.", args=argv[1:]
        )
    elif argv[:1] == ["evaluate"]:
        protocols = evaluate_command.PROTOCOLS
        if len(argv) > 1 and argv[1] in protocols and (wrong := evaluate_command.misplaced_option(argv[1], argv[2:])):
            raise WorkbenchError(wrong)
        result = tyro.extras.subcommand_cli_from_dict(
            protocols, prog="workbench evaluate", description=inspect.cleandoc(evaluate.__doc__ or ""), args=argv[1:]
        )
    else:
        result = tyro.extras.subcommand_cli_from_dict(
            COMMANDS, prog="workbench", description="Terrain workbench: label robot logs, train, export.", args=argv
        )
    return int(result or 0)


if __name__ == "__main__":
    sys.exit(main())
