"""The tests' side of ``fork_server.py``: code and ``workbench`` commands run in child processes of their own, forked
from a server that imported the heavy modules once; every server ends with the test module that started it
(``tests/conftest.py``), so its CPU and its children's count in that module's (``tests/suite_cpu.py``)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import pytest

REPO = Path(__file__).resolve().parents[1]
TIME_LIMIT_S = 20.0
CLI_MODULES = ("numpy", "pandas", "workbench.cli")
CLI_CODE = "import sys\nfrom workbench.cli import main\nsys.exit(main(sys.argv[1:]))\n"


@dataclass(frozen=True)
class Ran:
    """What a forked child did: its exit code (``-9``: SIGKILL), its output, seconds, peak RSS (MB), and whether the
    time limit killed it."""

    code: int
    out: str
    err: str
    seconds: float
    peak_mb: float
    killed: bool


class ForkServer:
    """One ``fork_server.py`` per set of modules, started on first use and again if it died."""

    servers: ClassVar[dict[tuple[str, ...], subprocess.Popen]] = {}

    @classmethod
    def run(cls, modules: tuple[str, ...], code: str, argv: list[str], *, timeout: float) -> Ran:
        proc = cls.servers.get(modules)
        if proc is None or proc.poll() is not None:
            proc = cls.servers[modules] = subprocess.Popen(
                [sys.executable, str(REPO / "tests" / "fork_server.py"), *modules],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                cwd=REPO,
                env={**os.environ, "WORKBENCH_DEBUG": ""},
                text=True,
            )
            assert json.loads(proc.stdout.readline()).get("ready")
        folder = Path(tempfile.mkdtemp())
        job = {"code": code, "argv": [str(a) for a in argv], "timeout": timeout}
        job |= {k: str(folder / k) for k in ("out", "err", "peak")}
        proc.stdin.write(json.dumps(job) + "\n")
        proc.stdin.flush()
        answer = json.loads(proc.stdout.readline())
        text = {k: (folder / k).read_bytes().decode("utf-8", "replace") for k in ("out", "err")}
        peak = int((folder / "peak").read_text() or 0) / 1024 if (folder / "peak").exists() else 0.0
        shutil.rmtree(folder)
        return Ran(int(answer["code"]), text["out"], text["err"], float(answer["seconds"]), peak, answer["killed"])

    @classmethod
    def stop(cls) -> None:
        """End every server and wait for it."""
        for proc in cls.servers.values():
            proc.stdin.close()
            proc.wait(30)
        cls.servers.clear()


def run_cli(args: list[str], *, timeout: float = TIME_LIMIT_S) -> tuple[int, str, str, float, float]:
    """``workbench ARGS`` in a child process of its own: exit code, stdout, stderr, seconds and peak RSS (MB) of that
    child alone."""
    ran = ForkServer.run(CLI_MODULES, CLI_CODE, list(args), timeout=timeout)
    if ran.killed:
        pytest.fail(f"workbench {' '.join(map(str, args))[:200]}: no answer within {timeout:.0f} s (killed)")
    return ran.code, ran.out, ran.err, ran.seconds, ran.peak_mb
