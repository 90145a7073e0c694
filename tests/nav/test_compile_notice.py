"""The first flight after an install compiles the filter's kernels (about half a minute): a
terminal is told so in one line, once; a pipe (scripts, tests, workers) is not."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
NOTICE = "air-sitl: compiling the test kernel for this machine, once"

SCRIPT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, sys.argv[1])
    import tiny
    from air_sitl.compiled import never_compiled, say_when_compiling
    print("cold" if never_compiled(tiny.twice) else "cached", flush=True)
    say_when_compiling("the test kernel", tiny.twice)
    assert tiny.twice(2.0) == 4.0
    """
)


def _run(folder: Path, *, terminal: bool) -> tuple[str, str]:
    """Run SCRIPT; its stdout and what reached its stderr (a pty's, or a pipe's)."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    argv = [sys.executable, "-c", SCRIPT, str(folder)]
    if not terminal:
        run = subprocess.run(
            argv, capture_output=True, text=True, env=env, timeout=120, check=False
        )
        assert run.returncode == 0, run.stderr
        return run.stdout, run.stderr
    main, sub = pty.openpty()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=sub, text=True, env=env)
    os.close(sub)
    said = b""
    while True:  # read the pty until the child closes it
        try:
            chunk = os.read(main, 4096)
        except OSError:
            break
        if not chunk:
            break
        said += chunk
    out = proc.communicate(timeout=120)[0]
    os.close(main)
    assert proc.returncode == 0, said
    return out, said.decode()


def test_a_terminal_is_told_once_when_kernels_compile(tmp_path: Path) -> None:
    (tmp_path / "tiny.py").write_text(
        "from air_sitl.compiled import compiled\n\n\n"
        "@compiled\ndef twice(x: float) -> float:\n    return 2.0 * x\n"
    )
    out, err = _run(tmp_path, terminal=True)
    assert out.strip() == "cold" and NOTICE in err
    out, err = _run(tmp_path, terminal=True)  # compiled and kept by the first run
    assert out.strip() == "cached" and NOTICE not in err


def test_a_pipe_is_not_told(tmp_path: Path) -> None:
    (tmp_path / "tiny.py").write_text(
        "from air_sitl.compiled import compiled\n\n\n"
        "@compiled\ndef twice(x: float) -> float:\n    return 2.0 * x\n"
    )
    out, err = _run(tmp_path, terminal=False)
    assert out.strip() == "cold" and err == ""
