"""The one rule for what a command writes (``fly``, ``dataset``, ``bench``, ``sweep``, ``map make``,
``map fetch``, ``export``): a folder (or a file) that holds something already is never
changed silently.

- Absent or empty: written.
- Not empty (a file: exists), without an option: refused in one line (exit 2), nothing changed.
  The line names ``--resume`` only when the command can continue what is there (the same
  inputs), and ``--overwrite`` always.
- ``--overwrite``: the old contents are removed first, then the command writes afresh (never a
  mix of two runs).
- ``--resume`` (commands that continue a run): continues the same inputs; a folder of other
  inputs is refused naming what differs.

A command gives :func:`claim_folder` a ``resume_problem`` callable: None when the folder holds
a run this command can continue, else a short phrase saying why not ("seed differs").
"""

from __future__ import annotations

import argparse
import shutil
from collections.abc import Callable
from pathlib import Path

from air_sitl.errors import DatasetError, OptionError

ResumeProblem = Callable[[], "str | None"]


def add_out_arguments(parser: argparse.ArgumentParser, *, resume: str | None = None) -> None:
    """``--overwrite`` and (with the help text ``resume``) ``--resume``, mutually exclusive."""
    group = parser.add_mutually_exclusive_group()
    if resume is not None:
        group.add_argument("--resume", action="store_true", help=resume)
    group.add_argument(
        "--overwrite",
        action="store_true",
        help="replace what the output holds already (its old contents are removed first)",
    )


def _refuse_to_empty(path: Path) -> None:
    """OptionError when emptying ``path`` would remove more than a command's output: the
    working folder or one of its parents, the home folder, the root."""
    real = path.resolve()
    cwd = Path.cwd().resolve()
    if real == cwd or real in cwd.parents or real == Path.home().resolve() or real.parent == real:
        msg = (
            f"{path}: --overwrite would empty the working, home or root folder; choose a subfolder"
        )
        raise OptionError(msg)


def empty_folder(path: Path) -> None:
    """Remove everything inside ``path`` (the folder itself stays)."""
    _refuse_to_empty(path)
    try:
        for child in path.iterdir():
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child)
            else:
                child.unlink()
    except OSError as err:
        msg = f"{path}: --overwrite: cannot remove the old contents: {err.strerror or err}"
        raise DatasetError(msg) from None


def is_nonempty_folder(path: Path) -> bool:
    """``path`` is a folder holding something."""
    return path.is_dir() and any(path.iterdir())


def refusal(path: Path, problem: str | None, *, resumable: bool) -> str:
    """The one line refusing a non-empty ``path``: ``--resume`` named only when ``problem`` is
    None on a command that resumes; ``problem`` says what else the folder holds."""
    if resumable and problem is None:
        what = "folder exists and is not empty: --resume continues it, "
    elif problem:
        what = f"folder holds another run: {problem}; "
    else:
        what = "folder exists and is not empty: "
    return f"{path}: {what}--overwrite replaces it, or choose another --out"


def claim_folder(
    path: Path,
    *,
    overwrite: bool,
    resume: bool = False,
    resume_problem: ResumeProblem | None = None,
) -> bool:
    """Apply the rule to the output folder ``path`` (see the module docstring); create it.

    ``resume_problem`` is None for a command that never resumes. Returns True when a
    non-empty folder is continued (``resume``), False when the command writes afresh.
    """
    if path.exists() and not path.is_dir():
        msg = f"{path}: exists and is not a folder (remove it, or choose another --out)"
        raise DatasetError(msg)
    if is_nonempty_folder(path):
        if overwrite:
            empty_folder(path)
        elif resume and resume_problem is not None:
            problem = resume_problem()
            if problem is not None:
                msg = f"{path}: --resume: {problem}; --overwrite replaces it, or another --out"
                raise DatasetError(msg)
            return True
        else:
            problem = resume_problem() if resume_problem is not None else None
            raise DatasetError(refusal(path, problem, resumable=resume_problem is not None))
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"{path}: cannot create the output folder: {err.strerror or err}"
        raise DatasetError(msg) from None
    return False


def claim_path(path: Path, *, overwrite: bool, folder: bool = False) -> None:
    """Apply the rule to an output the writer creates itself (a file, or with ``folder`` a
    folder such as a rosbag2): refused when it exists, removed first with ``overwrite``; what
    is of the other kind (a folder where a file goes) is never removed."""
    if not path.exists() and not path.is_symlink():
        return
    if path.is_dir() != folder:
        msg = f"{path}: is a {'file' if folder else 'folder'} (choose another output)"
        raise DatasetError(msg)
    if not overwrite:
        msg = f"{path}: exists already (--overwrite replaces it, or choose another name)"
        raise DatasetError(msg)
    if folder:
        empty_folder(path)
    try:
        path.rmdir() if folder else path.unlink()
    except OSError as err:
        msg = f"{path}: --overwrite: cannot remove it: {err.strerror or err}"
        raise DatasetError(msg) from None
