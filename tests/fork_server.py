"""Python code run in forked children of one process that imported the heavy modules once:
``python tests/fork_server.py MODULE...``.

Each line on stdin is a job (JSON: ``code``, its ``argv``, files for its ``out``, ``err`` and ``peak``, a
``timeout``). The server forks; the child points its stdin at /dev/null and its stdout and stderr at the two files,
runs the code as ``__main__`` with ``sys.argv`` set, and exits with its code: a real process (its own exit status,
signals and memory; killed alone past the time limit). The server answers one JSON line: the exit code as
``subprocess`` gives it (``-9``: killed by SIGKILL), whether the limit killed it, the seconds, and the child's own
peak RSS is in its ``peak`` file (``VmHWM``, kB; the pages it shares with the server count, as they would in a fresh
interpreter that imported the same modules). Starting Python and importing the CLI, pandas and NumPy cost 0.6-0.9 s
of CPU per command, PyTorch 2-3 s; the hostile table runs fifty commands and the kill tests six trainings.
"""

from __future__ import annotations

import importlib
import json
import os
import signal
import sys
import time
from pathlib import Path


def _peak_kb() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    return 0


def _child(job: dict) -> None:
    """In the forked child: the job's code with its output in two files; never returns."""
    code = 70
    try:
        null = os.open(os.devnull, os.O_RDONLY)  # the server's stdin is its queue of jobs
        os.dup2(null, 0)
        os.close(null)
        for fd, key in ((1, "out"), (2, "err")):
            f = os.open(job[key], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            os.dup2(f, fd)
            os.close(f)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        sys.argv = ["-c", *job["argv"]]
        try:
            exec(compile(job["code"], "<job>", "exec"), {"__name__": "__main__"})
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:
            import traceback

            traceback.print_exc()
            code = 1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        Path(job["peak"]).write_text(str(_peak_kb()))
        os._exit(int(code))


def serve() -> None:
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # the repository, not tests/ (whose workbench/ is tests')
    for name in sys.argv[1:]:
        importlib.import_module(name)
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        job = json.loads(line)
        t0 = time.perf_counter()
        pid = os.fork()
        if pid == 0:
            _child(job)
        deadline, killed = t0 + float(job["timeout"]), False
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                break
            if time.perf_counter() > deadline:
                os.kill(pid, signal.SIGKILL)
                _, status = os.waitpid(pid, 0)
                killed = True
                break
            time.sleep(0.005)
        answer = {"code": os.waitstatus_to_exitcode(status), "killed": killed, "seconds": time.perf_counter() - t0}
        print(json.dumps(answer), flush=True)


if __name__ == "__main__":
    serve()
