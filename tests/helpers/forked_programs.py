"""
Programs run as processes of their own, forked from one interpreter that imported the package once.

A console program spends about 1.3 s of CPU importing veragmil_suite (robosuite, MuJoCo) before it reads its command
line; a test that starts 35 programs to see each refuse bad input paid that 35 times. Here a server process imports the
package once, then forks a child per program, which imports the program's own module, runs it as its launcher would
(a console script's ``sys.exit(main())``, ``python -m``'s runpy, a script by path) with its standard output and error
on files of its own, and exits with its status. What the shared import prints is the server's, not the programs'.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

_SERVER = r"""
import importlib, json, os, runpy, sys, traceback
import veragmil_suite  # the imports every program shares, once

def run(job):
    sys.argv = job["argv"]
    kind, target = job["kind"], job["target"]
    if kind == "entry":
        module, function = target.split(":")
        sys.exit(getattr(importlib.import_module(module), function)())
    if kind == "module":
        runpy.run_module(target, run_name="__main__", alter_sys=True)
    else:
        runpy.run_path(target, run_name="__main__")

for line in sys.stdin:
    job = json.loads(line)
    pid = os.fork()
    if pid == 0:
        code = 0
        with open(job["stdout"], "wb") as out, open(job["stderr"], "wb") as err:
            os.dup2(out.fileno(), 1)
            os.dup2(err.fileno(), 2)
        os.dup2(os.open(os.devnull, os.O_RDONLY), 0)  # not the server's job queue
        try:
            run(job)
        except SystemExit as exit_:
            code = exit_.code if isinstance(exit_.code, int) else (0 if exit_.code is None else 1)
            if not isinstance(exit_.code, (int, type(None))):
                print(exit_.code, file=sys.stderr)
        except BaseException:
            traceback.print_exc()
            code = 1
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    print(json.dumps({"returncode": os.waitstatus_to_exitcode(status)}), flush=True)
"""


@dataclass(frozen=True)
class Finished:
    """A forked program's exit status and output, as subprocess.run reports them."""

    returncode: int
    stdout: str
    stderr: str


class ProgramServer:
    """An interpreter that has imported veragmil_suite and forks each program asked of it (``run``)."""

    def __init__(self, env: dict[str, str]):
        self._dir = tempfile.TemporaryDirectory(prefix="forked_programs_")
        self._server = subprocess.Popen(
            [sys.executable, "-c", _SERVER],
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,  # the shared import's warnings: the programs' own output is on files
            text=True,
        )
        self._count = 0

    def run(self, kind: str, target: str, argv: list[str]) -> Finished:
        """Runs a program: ``kind`` "entry" (target "module:function", a console script), "module" (python -m
        target) or "script" (python target), with ``argv`` as its sys.argv."""
        self._count += 1
        out, err = (Path(self._dir.name) / f"{self._count}.{name}" for name in ("out", "err"))
        job = dict(kind=kind, target=target, argv=[str(a) for a in argv], stdout=str(out), stderr=str(err))
        self._server.stdin.write(json.dumps(job) + "\n")
        self._server.stdin.flush()
        answer = self._server.stdout.readline()
        assert answer, f"the program server died running {argv}"
        return Finished(json.loads(answer)["returncode"], out.read_text(), err.read_text())

    def close(self) -> None:
        self._server.stdin.close()
        self._server.wait(timeout=60)
        self._dir.cleanup()

    def __enter__(self) -> ProgramServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
