"""Staged files moved over their targets as one: all of them, or none.

:func:`~spcopyro._util.folder_commit.commit_folder` moves a house's map (``NAME.pgm``,
``NAME.yaml``, staged beside them) in with the house folder: one file that cannot be put in place
(a folder where ``NAME.yaml`` goes, a permission refused) must not leave the other one new.
Imports nothing of the package.
"""

from __future__ import annotations

import contextlib
import logging
import os
import stat
from collections.abc import Sequence
from pathlib import Path

logger = logging.getLogger(__name__)


class FilesNotMoved(OSError):
    """A file of :func:`move_files_in` could not be put in place: none was (the message says
    which, and why). ``stranded``: the old targets that could not be put back either, each
    still in its ``STAGED.old`` (the message names it): the caller must not remove its folder."""

    stranded: tuple[Path, ...] = ()


def move_files_in(files: Sequence[tuple[Path, Path]], folder: Path | None = None) -> None:
    """Move each ``(staged, target)`` of ``files`` over its target (``os.replace``: readers see
    the old file or the new one), all or none. Each new file takes its old target's mode (a
    map made group-readable stays so). The old targets are kept (hard-linked, else renamed, to
    ``STAGED.old``) until all are moved, then removed; when a move fails, the old targets are put
    back, each tried, and :class:`FilesNotMoved` raised for that move (saying that the targets and
    ``folder``, the one moved in with them, are left as they were: the caller puts the folder
    back; an old target that could not be put back stays in ``STAGED.old``, which it names)."""
    done: list[tuple[Path, Path, Path | None]] = []  # (staged, target, the old target kept)
    targets = [target for _, target in files]
    try:
        for staged, target in files:
            done.append((staged, target, _keep_old(staged, target)))
            os.replace(staged, target)  # a folder at target: IsADirectoryError
    except OSError as error:
        stranded: list[tuple[Path, Path, OSError]] = []  # (old target kept, its place, why)
        for new, place, old in reversed(done):  # each put back, even after one that is not
            try:
                if old is not None:
                    os.replace(old, place)
                elif not os.path.lexists(new):  # moved in where nothing was: back again
                    os.rename(place, new)
            except OSError as why:
                if old is not None:  # the only copy of the old file: named, and left there
                    stranded.append((old, place, why))
        left = ", ".join(
            str(path)
            for path in ([] if folder is None else [folder]) + targets
            if all(path != place for _, place, _ in stranded)
        )
        lost = "".join(
            f"; the old {place} could not be put back ({why.strerror or why}): it is kept as {old} "
            f"(move it back to {place}, then remove {old.parent})"
            for old, place, why in stranded
        )
        failure = FilesNotMoved(
            f"cannot put {target} in place ({error.strerror or error}); {left} left as they "
            f"were{lost}"
        )
        failure.stranded = tuple(old for old, _, _ in stranded)
        raise failure from error
    for _, _, old in done:
        if old is not None:
            with contextlib.suppress(OSError):
                os.unlink(old)


def kept_old_files(folder: Path) -> list[Path]:
    """The ``*.old`` files in ``folder``, a staging folder a refused :func:`move_files_in` left:
    old targets it could not put back (:class:`FilesNotMoved` named each and where it goes).
    Each is warned of again, since the folder must stay until the user moves them back."""
    kept = sorted(folder.glob("*.old"))
    for old in kept:
        logger.warning("%s is a file an earlier run replaced and could not put back (its error "
                       "said where): move it back, then remove %s", old, folder)  # fmt: skip
    return kept


def take_mode(new: Path, old: Path) -> os.stat_result | None:
    """``old``'s status (not following a link; None where nothing is there), a regular file's
    mode given to ``new``: a file replaced keeps its mode, as one rewritten by ``open`` does."""
    try:
        status = os.lstat(old)
    except FileNotFoundError:
        return None
    if stat.S_ISREG(status.st_mode):
        os.chmod(new, stat.S_IMODE(status.st_mode))
    return status


def _keep_old(staged: Path, target: Path) -> Path | None:
    """``target`` kept as ``STAGED.old`` (its mode given to ``staged``); None where there is no
    file (nothing, or a folder, which ``os.replace`` refuses)."""
    status = take_mode(staged, target)
    if status is None or stat.S_ISDIR(status.st_mode):
        return None
    old = staged.with_name(f"{staged.name}.old")
    try:
        os.link(target, old, follow_symlinks=False)  # target stays in place until replaced
    except OSError:  # no hard links on this file system (or not ours to link): set aside
        os.rename(target, old)
    return old
