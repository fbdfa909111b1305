"""File output: the check of an output path, and atomic writes.

:func:`output_problem` says, before any work, why a file or folder cannot be
written (the wrong kind, under a file, permission denied); missing parent
folders are not a problem, they are created. Writes go to a temporary path
beside the target, then rename: nothing half-written is ever left under the
target's name, and files get the permissions of an ordinary
``open(..., "w")`` (0o666 less the umask), not the private 0o600 of
:func:`tempfile.mkstemp`.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

__all__ = [
    "atomic_path",
    "check_output",
    "output_problem",
    "temporary_folder",
    "write_text_atomic",
]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it onto ``path`` on success.

    On an exception the temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(handle)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 text (LF line ends) to ``path`` atomically and durably."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="\n") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())


def temporary_folder(near: str | os.PathLike[str]) -> Path:
    """Create an empty folder beside ``near`` (same file system, so it can be
    renamed onto it), with ordinary permissions (0o777 less the umask)."""
    target = Path(near)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    return tmp


def _refusal(folder: Path) -> str | None:
    """Why no file can be created in the existing ``folder`` (a phrase naming
    it), or None.

    Write and search permission first (``os.access``); then a real probe (an
    empty folder created and removed at once), since root passes every
    permission check and only the file system itself refuses it (read-only,
    or a virtual one such as /proc).
    """
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"permission denied in {os.fspath(folder)}"
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".pneumafit-probe.", dir=folder))
    except OSError as exc:
        return f"{os.fspath(folder)} refuses new files ({exc.strerror or type(exc).__name__})"
    return None


def output_problem(
    path: str | os.PathLike[str], kind: Literal["file", "folder"], option: str = "--out"
) -> str | None:
    """The problem of an output path, or None when it can be written.

    Parameters
    ----------
    path : path
        What the command will write: a file (``kind="file"``, replaced if it
        exists) or a folder (``kind="folder"``, created or written into).
    kind : {"file", "folder"}
        What ``path`` must be.
    option : str
        The option's name, for the message.

    Returns
    -------
    str or None
        ``"cannot write PATH: ..."`` with what was expected, what was found
        and what to do; None when the path is of the right kind (or absent)
        and its nearest existing folder is writable. Missing parent folders
        are not a problem (they are created).
    """
    p = Path(path)
    shown = os.fspath(path)
    if kind == "folder" and p.exists() and not p.is_dir():
        return (
            f"cannot write {shown}: option {option} expected a folder, found a file; "
            "give a new or existing folder, or move the file away"
        )
    if kind == "file" and p.is_dir():
        return (
            f"cannot write {shown}: option {option} expected a file name, found a folder; "
            f"give a file path (for example {os.fspath(p / 'NAME')})"
        )
    # the nearest existing folder: the target itself (an existing folder),
    # else the first ancestor that exists (missing ones will be created)
    existing = p if kind == "folder" and p.is_dir() else None
    if existing is None:
        for ancestor in p.absolute().parents:
            if ancestor.exists():
                existing = ancestor
                break
    if existing is None:  # nothing exists, not even the root: cannot happen on a real system
        return f"cannot write {shown}: no existing folder above it"
    if not existing.is_dir():
        return (
            f"cannot write {shown}: {os.fspath(existing)} is a file, so no folder can be "
            f"created under it; choose another {option}"
        )
    refusal = _refusal(existing)
    if refusal:
        return (
            f"cannot write {shown}: {refusal}; choose another {option} or make that folder writable"
        )
    return None  # an existing file is replaced (written beside it, then renamed)


def check_output(
    path: str | os.PathLike[str], kind: Literal["file", "folder"], option: str = "--out"
) -> None:
    """Raise :class:`~pneumafit.campaign.errors.PneumafitInputError` with
    :func:`output_problem`'s message when ``path`` cannot be written."""
    from pneumafit.campaign.errors import PneumafitInputError

    problem = output_problem(path, kind, option)
    if problem:
        raise PneumafitInputError(problem)
