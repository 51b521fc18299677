"""A finished folder moved into place whole: the old one set aside, what its writer did not
write carried into the new one, then removed; a Ctrl-C (or SIGTERM) meanwhile held until all is in
place (:func:`commit_folder`).

:mod:`spcopyro._util.outputs` stages the folders (``OUT.partial-PID-XXXXXXXX`` beside OUT) and
commits a fit's with :func:`commit_folder`; the commands that write a house folder (a dataset's
rooms, ``import-bag``) call it with the house's map. :func:`completed` and :func:`set_aside` tell
the Ctrl-C line of a command (:mod:`spcopyro.cli.interrupted`) whether OUT is the new folder and
where an old one was kept.

Imports of the package: only :mod:`~spcopyro._util.interrupts`, :mod:`~spcopyro._util.file_moves`.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Container, Iterator, Sequence
from pathlib import Path

from spcopyro._util.file_moves import FilesNotMoved, move_files_in
from spcopyro._util.interrupts import remove_tree, signals_deferred

__all__ = [
    "absolute_path", "carry_over", "commit_folder", "completed", "is_empty_folder", "set_aside",
    "swapped_in", "write_started",
]  # fmt: skip


def absolute_path(path: str | os.PathLike[str]) -> Path:
    """``path`` made absolute, as ``os.path.abspath`` does (no link resolved)."""
    return Path(os.path.abspath(os.fspath(path)))


def is_empty_folder(path: Path) -> bool:
    """Whether the folder ``path`` holds no entry."""
    with os.scandir(path) as entries:
        return next(entries, None) is None


_SET_ASIDE: list[tuple[Path, Path]] = []
"""(OUT, the folder :func:`swapped_in` set it aside in), absolute, for each swap of this process
not yet finished: one stopped by an error (Ctrl-C included) stays, its folder kept."""


@contextlib.contextmanager
def swapped_in(out: Path, staging: Path, hidden: bool = False) -> Iterator[Path]:
    """The folder ``out`` set aside (yielded: ``OUT.replaced-XXXXXXXX`` beside it, with a
    leading dot if ``hidden``) and ``staging`` renamed into its place (the old one put back if
    that fails, or the block's OSError leaves ``out`` empty: it put the new one back);
    the old one removed once the block ends, or kept after another error (:func:`set_aside`)."""
    old = out.parent / f"{'.' if hidden else ''}{out.name}.replaced-{secrets.token_hex(4)}"
    swap = (absolute_path(out), absolute_path(old))
    # recorded before the rename, so that a Ctrl-C just after it finds it; one just before
    # leaves it recorded but not there, and set_aside names only a folder that is there
    _SET_ASIDE.append(swap)
    try:
        os.rename(out, old)
    except OSError:  # nothing set aside
        _SET_ASIDE.remove(swap)
        raise
    try:
        os.rename(staging, out)
        yield old
    except OSError:
        if not os.path.lexists(out):  # the new one not (or no longer) there: the old one back
            os.rename(old, out)
            _SET_ASIDE.remove(swap)
        raise
    remove_tree(old)  # a Ctrl-C meanwhile leaves it (set_aside names it)
    _SET_ASIDE.remove(swap)


def set_aside(out: str | os.PathLike[str]) -> list[Path]:
    """The folders :func:`swapped_in` set ``out`` aside in, in this process, and kept (a swap
    stopped, by Ctrl-C or an error, before it removed the folder), those still there; absolute.
    A leftover ``OUT.replaced-*`` of an earlier process is not one of them."""
    out = absolute_path(out)
    return [old for where, old in _SET_ASIDE if where == out and os.path.lexists(old)]


def carry_over(old: Path, out: Path, written: Container[str]) -> tuple[str, ...]:
    """Move the entries of the replaced folder ``old`` that its writer did not write (not in
    ``written``: ``Ft.csv`` of ``spcopyro features``, a user's notes) into the new ``out``,
    unless ``out`` holds one of that name; their names, sorted."""
    kept = []
    for entry in sorted(old.iterdir()):
        if entry.name not in written and not (out / entry.name).exists():
            os.rename(entry, out / entry.name)
            kept.append(entry.name)
    return tuple(kept)


_COMPLETED: set[Path] = set()
"""The OUTs :func:`commit_folder` moved a new folder (and its files) into, in this process,
absolute; a new staging folder for one (:func:`~spcopyro._util.outputs.staging_folder`, which
:func:`~spcopyro._util.outputs.stage_output` and :func:`~spcopyro._util.outputs.stage_marked_folder`
make) takes it out again (:func:`write_started`): its latest write is not done."""


def completed(out: str | os.PathLike[str]) -> bool:
    """Whether this process's latest write into ``out`` is in place, whole (:func:`commit_folder`
    finished its renames), though a Ctrl-C may have stopped the command after."""
    return absolute_path(out) in _COMPLETED


def write_started(out: str | os.PathLike[str]) -> None:
    """A new write into ``out`` has begun (a staging folder was made for it): :func:`completed`
    is False for ``out`` until :func:`commit_folder` has moved the new folder in."""
    _COMPLETED.discard(absolute_path(out))


def commit_folder(
    staging: Path,
    out: Path,
    written: Container[str],
    files: Sequence[tuple[Path, Path]] = (),
    *,
    hidden: bool = False,
    replace: bool = True,
) -> tuple[str, ...]:
    """Move the staged folder ``staging`` to ``out``, then each ``(staged, target)`` of
    ``files`` (staged beside its target in a :func:`~spcopyro._util.outputs.staging_folder`: a
    house's map) over its target, all or none (:func:`~spcopyro._util.file_moves.move_files_in`:
    one refused, the folder is put back too, and :class:`FilesNotMoved` names it); the new
    ``out`` and files keep the old ones' modes. A non-empty ``out`` is set aside
    (:func:`swapped_in`, ``hidden``; with ``replace`` False the rename fails on one instead,
    OSError), what its writer did not write (not in ``written``) carried into the new one
    (:func:`carry_over`), then removed. A Ctrl-C (or SIGTERM) meanwhile is held until all are in
    place and the old folder removed (:func:`~spcopyro._util.interrupts.signals_deferred`): it
    finds all old or all new, and :func:`completed` says which; an OSError raised says in
    ``signalled`` whether one was held (``[SIGNUM]``, else ``[]``). Returns the names
    carried."""
    signalled: list[int] = []
    mode = stat.S_IMODE(out.stat().st_mode) if out.is_dir() else None  # the old OUT's
    held = signals_deferred(lambda signum, frame: signalled.append(signum))  # renames
    try:
        with contextlib.ExitStack() as swap, held:  # on leaving: the old folder removed
            old = None
            if replace and out.is_dir() and not is_empty_folder(out):
                old = swap.enter_context(swapped_in(out, staging, hidden))
            else:
                os.rename(staging, out)  # replaces an empty folder atomically
            try:
                move_files_in(files, out)  # all or none
            except FilesNotMoved:  # the new folder put back too (swapped_in puts back an old one)
                os.rename(out, staging)
                if old is None and mode is not None:  # an empty OUT was there
                    out.mkdir(mode=mode)
                    os.chmod(out, mode)  # not the umask's
                raise
            kept = () if old is None else carry_over(old, out, written)
            if mode is not None:  # not before: carry_over writes into OUT
                os.chmod(out, mode)
            _COMPLETED.add(absolute_path(out))
    except OSError as error:  # said with the Ctrl-C held meanwhile (cli.main: then 130)
        error.signalled = signalled[:1]  # type: ignore[attr-defined]
        raise
    if signalled:  # all in place: stopped now
        raise KeyboardInterrupt(f"signal {signalled[0]}")
    return kept
