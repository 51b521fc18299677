"""The ``spcopyro`` command ends its process without the interpreter's teardown
(:mod:`spcopyro._util.process_exit`), and does everything of an exit before it: the non-daemon
threads finish, the atexit handlers run, the streams are flushed, the status is main's. A program
calling ``console_main`` itself, or one profiled, exits as before. Nothing here times anything."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# A __main__ file ending in console_main, as the console script does; the object held by a
# module writes MARK (in __del__) when the interpreter tears the modules down.
_SCRIPT = """
import atexit, sys, threading, time, types
sys.argv = ["spcopyro", *ARGS]

class Teardown:
    def __del__(self, open=open):
        with open(MARK, "w") as f:
            f.write("torn down")

probe = types.ModuleType("spcopyro_teardown_probe")  # cleared when the modules are torn down
probe.held = Teardown()
sys.modules[probe.__name__] = probe
del probe
atexit.register(lambda: print("atexit ran"))
def late():
    time.sleep(0.3)
    print("thread done")
threading.Thread(target=late).start()  # non-daemon: the exit waits for it
print("unflushed", end=" ")
from spcopyro.cli.main import console_main
console_main()
"""


def _env() -> dict[str, str]:
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, "CI": "1"}


def _mark(tmp_path: Path) -> Path:
    return tmp_path / "torn-down"


def _run(tmp_path: Path, args: list[str], *before: str) -> subprocess.CompletedProcess[str]:
    script = tmp_path / "spcopyro_main.py"
    mark = repr(str(_mark(tmp_path)))
    script.write_text(_SCRIPT.replace("ARGS", repr(args)).replace("MARK", mark))
    return subprocess.run([sys.executable, *before, str(script)], capture_output=True,
                          text=True, env=_env(), timeout=300)  # fmt: skip


def test_the_command_skips_the_teardown_after_a_whole_exit(tmp_path):
    done = _run(tmp_path, ["where", str(tmp_path / "no-fit"), "kitchen"])
    assert done.returncode == 2, done.stderr  # main's status
    assert done.stderr.startswith("error:"), done.stderr
    lines = done.stdout.split("\n")
    assert lines[0].startswith("unflushed "), done.stdout
    assert "thread done" in done.stdout and "atexit ran" in lines, done.stdout
    assert done.stdout.index("thread done") < done.stdout.index("atexit ran"), done.stdout
    assert not _mark(tmp_path).exists()  # the modules were not torn down


def test_a_profiled_command_exits_as_before(tmp_path):
    """``python -m cProfile`` writes its statistics once the program returned."""
    stats = tmp_path / "stats.prof"
    done = _run(tmp_path, ["where", str(tmp_path / "no-fit"), "kitchen"], "-m", "cProfile", "-o",
                str(stats))  # fmt: skip
    assert done.stderr.startswith("error:"), done.stderr
    assert stats.is_file() and stats.stat().st_size > 0
    assert "atexit ran" in done.stdout and "thread done" in done.stdout, done.stdout
    assert _mark(tmp_path).read_text() == "torn down"  # the interpreter's own exit


def test_a_program_calling_console_main_gets_system_exit():
    code = (
        "import sys; sys.argv = ['spcopyro', '--version']\n"
        "from spcopyro.cli.main import console_main\n"
        "try:\n    console_main()\nexcept SystemExit as e:\n    print('caught', e.code)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=_env(), timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.rstrip().endswith("caught 0"), done.stdout
