"""Output folders that appear whole or not at all, and files replaced atomically.

``spcopyro fit --out OUT`` writes every file of a run (result files, figures, scores, chains,
convergence record) into a *staging* folder beside OUT -- ``OUT.partial-PID-XXXXXXXX``, in OUT's
parent, so that moving it into place is a ``rename`` on one file system, which is atomic -- and
moves it to OUT only when everything is written (:meth:`StagedOutput.commit`). So a crash, a
Ctrl-C, or a second fit into the same folder never leaves a mixture of two runs' files:

* :func:`stage_output` refuses an OUT that exists and is not empty unless ``overwrite`` is given
  (and refuses to overwrite a folder that no fit wrote, or one that holds the current
  directory); it creates the staging folder at once, so an unwritable OUT or parent is reported
  before any work is done.
* With ``overwrite``, the old run's files are replaced; others (a user's notes) are kept.
* Two fits into one OUT: the commits are serialised by a lock on the parent folder, and a fit
  commits only if OUT is still the folder it saw when it started; otherwise it fails with
  :class:`OutputError`, leaving OUT as the other fit wrote it and its own files in its staging
  folder (named in the message: nothing is deleted).
* An interrupted fit's checkpoint lives beside OUT as ``OUT.checkpoint.npz``
  (:func:`checkpoint_path`), never inside it, so it cannot be mistaken for a result.
* Staging folders and new files get the permissions a plain ``mkdir`` or ``open`` gives under
  the user's umask (not ``tempfile``'s 0700 / 0600); a folder or file replaced keeps the old
  one's mode (:func:`~spcopyro._util.folder_commit.commit_folder`, :func:`replace_file`), as
  ``open`` keeps a file's.

The move into place itself, the old folder set aside and what its writer did not write carried
over, is :mod:`~spcopyro._util.folder_commit`'s.

Imports of the package: only :mod:`~spcopyro._util.interrupts`, :mod:`~spcopyro._util.file_moves`,
:mod:`~spcopyro._util.folder_commit`.
"""

from __future__ import annotations

import contextlib
import glob
import io
import json
import os
import re
import secrets
import zipfile
import zlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, TypeVar

import numpy as np

from spcopyro._util.file_moves import kept_old_files, take_mode
from spcopyro._util.folder_commit import (
    absolute_path,
    commit_folder,
    completed,
    is_empty_folder,
    write_started,
)
from spcopyro._util.interrupts import remove_tree

try:  # POSIX: serialise commits into one parent folder
    import fcntl
except ImportError:  # pragma: no cover - Windows: commits are not serialised
    fcntl = None  # type: ignore[assignment]

T = TypeVar("T")

CHECKPOINT_SUFFIX = ".checkpoint.npz"
STAGING_INFIX = ".partial-"
RESULT_MARKERS = ("result.npz", "config.json")
"""A folder holding both was written by ``spcopyro fit``: the only kind ``overwrite`` replaces."""


def missing_fit_markers(path: Path) -> list[str]:
    """The :data:`RESULT_MARKERS` that folder ``path`` lacks (none: ``spcopyro fit`` wrote it)."""
    return [name for name in RESULT_MARKERS if not (path / name).is_file()]


DAMAGED_FILE_ERRORS = (
    OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError,
)  # fmt: skip
"""What reading a damaged or truncated ``.npz`` raises (numpy, zipfile and zlib each their own)."""


def read_npz(path: Path) -> np.lib.npyio.NpzFile:
    """``np.load`` of ``path`` from memory: a damaged zip then leaves no file handle open behind
    numpy (which warns later, as an unclosed file). Raises one of :data:`DAMAGED_FILE_ERRORS`."""
    return np.load(io.BytesIO(Path(path).read_bytes()), allow_pickle=False)


ROBOT_MAP_FILE = "robot_map.yaml"
"""The map a coarse fit's grid was coarsened from (``--cell-size``), written beside the fit's own
``map.yaml`` by ``spcopyro fit``: ``navigate`` plans on it, since coarsening thickens walls and can
close a doorway the robot drives through."""


def robot_map_of(result: object, folder: str | os.PathLike[str]) -> Path | None:
    """The map_server yaml a coarse fit's grid was coarsened from, for ``navigate`` (which plans
    on it) and ``export --nav2`` (Nav2's main map): the fit's own copy (:data:`ROBOT_MAP_FILE`
    in ``folder``, which only a coarse fit writes), else, for a coarse fit written before that
    copy, the data folder's map when it still sits in the dataset layout
    (``DATA/../map/HOUSE.yaml``, from the result's provenance). None for a fit on the map's own
    cells or when neither file is there. ``result``: a
    :class:`~spcopyro.results.result.SpCoResult` (its ``preparation`` and ``provenance``)."""
    own = Path(folder) / ROBOT_MAP_FILE
    if own.is_file():
        return own
    if getattr(result.preparation, "cell_size", None) is None:  # type: ignore[attr-defined]
        return None
    source = (result.provenance or {}).get("source") or {}  # type: ignore[attr-defined]
    if not source.get("data") or not source.get("house"):
        return None
    path = Path(source["data"]).parent / "map" / f"{source['house']}.yaml"
    return path if path.is_file() else None


MANIFEST = "outputs.json"
"""The list of the files a fit wrote into its folder (``{"files": [...]}``): ``--overwrite``
replaces those and keeps everything else (issue 22 item 3)."""
FIT_FILES = frozenset(
    "agreement.npy agreement.png chains.json concepts.json config.json convergence.json "
    "house.png labels.npy map.yaml map.pgm result.npz robot_map.yaml robot_map.pgm scores.json "
    "semantic_map.png trace.csv trace.png truth.npy uncertainty.npy uncertainty.png".split()
)
"""The files ``spcopyro fit`` writes: what a folder without a manifest (a fit of an older
version) is taken to hold of the fit's own; ``where --out`` never replaces one."""


def write_manifest(folder: Path) -> Path:
    """Write :data:`MANIFEST` into ``folder``, listing every entry in it (and itself)."""
    names = sorted({entry.name for entry in folder.iterdir()} | {MANIFEST})
    path = folder / MANIFEST
    path.write_text(json.dumps({"files": names}, indent=1) + "\n")
    return path


def fit_written(folder: Path) -> frozenset[str]:
    """The names of the entries a fit wrote into ``folder``: its manifest's, or :data:`FIT_FILES`
    (and the manifest) when it has none or a damaged one."""
    try:
        names = json.loads((folder / MANIFEST).read_text())["files"]
        if isinstance(names, list) and all(isinstance(n, str) for n in names):
            return frozenset(names) | {MANIFEST}
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return FIT_FILES | {MANIFEST}


class OutputError(ValueError):
    """An output folder that cannot be written as asked (the message says why and what to do)."""


def checkpoint_path(out: str | os.PathLike[str]) -> Path:
    """``OUT.checkpoint.npz``: where an interrupted fit into ``out`` keeps its state (beside
    OUT, not inside it)."""
    out = absolute_path(out)
    return out.parent / f"{out.name}{CHECKPOINT_SUFFIX}"


def file_identity(path: Path) -> tuple[int, int] | None:
    """(device, inode) of ``path`` (not following a link), None where nothing is there: tells a
    file replaced whole (a new inode) from the one seen before (``study.commands`` names a
    stopped run's reports that are still an earlier run's so)."""
    try:
        status = path.lstat()
    except (FileNotFoundError, NotADirectoryError):
        return None
    return status.st_dev, status.st_ino


@contextlib.contextmanager
def _parent_lock(parent: Path) -> Iterator[None]:
    """An exclusive ``flock`` on the parent folder while a commit looks and renames."""
    if fcntl is None:  # pragma: no cover
        yield
        return
    descriptor = os.open(parent, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)  # releases the lock


@dataclass
class StagedOutput:
    """A run's output folder in the making: write into :attr:`path`, then :meth:`commit`.

    Used as a context manager, an exception (Ctrl-C included) before the commit removes the
    staging folder, so nothing of the run is left behind.
    """

    out: Path
    """The folder the outputs go to (absolute)."""
    path: Path
    """The staging folder the outputs are written into (beside :attr:`out`)."""
    overwrite: bool
    seen: tuple[int, int] | None
    """(device, inode) of :attr:`out` when staged (None: absent): another fit's commit changes
    it."""
    committed: bool = False
    kept: bool = False
    """The staged files were kept after a failed commit (:meth:`discard` leaves them)."""

    def commit(self) -> Path:
        """Move the staged folder to :attr:`out`
        (:func:`~spcopyro._util.folder_commit.commit_folder`); with ``overwrite`` a non-empty
        old one is replaced: set aside, what the old fit did not write (not in its manifest: a
        user's notes, ``where`` figures) carried into the new OUT, the rest removed.
        A Ctrl-C meanwhile is raised once OUT is the new one (:attr:`committed` then True).

        Raises:
            OutputError: another process wrote :attr:`out` since :func:`stage_output` (the staged
                files stay in :attr:`path`, named in the message).
        """
        if self.committed:
            raise OutputError(f"{self.out}: already committed")
        write_manifest(self.path)
        with _parent_lock(self.out.parent):
            if file_identity(self.out) != self.seen:
                self.kept = True
                raise OutputError(
                    f"{self.out} was written by another process while this fit ran; it is left "
                    f"as that one wrote it, and this fit's outputs are in {self.path}"
                )
            replace = self.seen is not None and self.overwrite and not is_empty_folder(self.out)
            try:
                commit_folder(self.path, self.out, fit_written(self.out) if replace else (),
                              replace=replace)  # fmt: skip
            except OSError as error:
                if replace:
                    raise
                self.kept = True  # the rename refused: OUT not empty any more
                refused = OutputError(f"{self.out} could not be written ({error.strerror}); this "
                                      f"fit's outputs are in {self.path}")  # fmt: skip
                refused.signalled = getattr(error, "signalled", None)  # type: ignore[attr-defined]
                raise refused from None  # with the Ctrl-C held meanwhile (cli.main: then 130)
            finally:
                self.committed = completed(self.out)
        return self.out

    def discard(self) -> None:
        """Remove the staging folder (nothing of this run is kept), unless committed or kept."""
        if not (self.committed or self.kept):
            remove_tree(self.path)

    def __enter__(self) -> StagedOutput:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is not None:
            self.discard()


def nearest_existing(path: Path) -> Path:
    """``path`` or the nearest of its parents that exists (where an output would be made)."""
    while not path.exists() and path.parent != path:
        path = path.parent
    return path


class NotAFolderError(OutputError, NotADirectoryError):
    """An output folder (or the folder of an output file) that is, or lies under, a file: an
    :class:`OutputError` and a :class:`NotADirectoryError`."""


def check_not_holding_cwd(path: str | os.PathLike[str], label: str) -> None:
    """:class:`OutputError` when the folder ``path`` is or holds the current directory: an
    output moved into place there (a rename onto it, even empty) deletes the folder the shell
    stands in, which then lists nothing (``cd .`` finds it again)."""
    folder = absolute_path(path)
    if folder.is_dir() and Path.cwd().resolve().is_relative_to(folder.resolve()):
        raise OutputError(
            f"{label}: {folder} holds the current directory, which putting the finished folder "
            f"in its place would delete under the shell; run from outside it (from its parent: "
            f"--out {folder.name})"
        )


def check_folder_path(path: str | os.PathLike[str], label: str) -> Path:
    """``path``'s nearest existing part (:func:`nearest_existing`, of its absolute form), once it
    is a folder: a folder could be made at ``path``. :class:`NotAFolderError` ``"LABEL: FILE is
    a file, not a folder"`` otherwise (``label``: how the user gave it, e.g. ``"--out OUT"``),
    before any work: making it failed after the work with a bare ``[Errno 17] File exists`` or
    ``[Errno 20] Not a directory``."""
    existing = nearest_existing(absolute_path(path))
    if not existing.is_dir():
        raise NotAFolderError(f"{label}: {existing} is a file, not a folder")
    return existing


def check_output(
    out: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    resume: str | os.PathLike[str] | None = None,
    inputs: Sequence[str | os.PathLike[str] | None] = (),
) -> Path:
    """Check that a fit may write ``out`` (absolute path returned); writes nothing.

    Raises :class:`OutputError` when ``out`` is a file, when it is or holds one of ``inputs``
    (the data the fit reads: replacing ``out`` would delete it), when it is a non-empty folder
    and ``overwrite`` is not given, when ``overwrite`` would replace a folder that no fit wrote
    (no ``result.npz`` and ``config.json``), when it holds the current directory (even empty:
    :func:`check_not_holding_cwd`), and when ``OUT.checkpoint.npz`` holds an interrupted fit
    that this one neither resumes (``resume``) nor replaces (``overwrite``)."""
    path = absolute_path(out)
    if path.parent == path:
        raise OutputError(f"--out {out}: the root folder cannot be an output folder")
    for read in inputs:
        if read is not None and absolute_path(read).resolve().is_relative_to(path.resolve()):
            raise OutputError(
                f"--out {out}: {path} holds the input {read}, which replacing the folder would "
                "delete; choose an --out outside the data"
            )
    check_folder_path(path, f"--out {out}")
    check_not_holding_cwd(path, f"--out {out}")
    if path.is_dir() and not is_empty_folder(path):
        if not overwrite:
            raise OutputError(
                f"--out {out}: {path} exists and is not empty; pass --overwrite to replace it "
                "(the files the earlier fit wrote are then deleted, others kept), or choose "
                "another --out"
            )
        missing = missing_fit_markers(path)
        if missing:
            raise OutputError(
                f"--out {out}: {path} holds files that no fit wrote (no {' or '.join(missing)}); "
                "--overwrite replaces only a fit's output folder: choose another --out"
            )
    checkpoint = checkpoint_path(path)
    resuming = resume is not None and absolute_path(resume) == checkpoint
    if checkpoint.exists() and not (resuming or overwrite):
        raise OutputError(
            f"{checkpoint} holds an interrupted fit into {path}: continue it with --resume "
            f"{checkpoint}, or pass --overwrite to start afresh (the checkpoint is then replaced)"
        )
    return path


def staging_prefix(path: Path, hidden: bool = False) -> str:
    """``OUT.partial-PID-`` (``.OUT.partial-PID-`` if ``hidden``): a staging folder's name tells
    which process made it, so a later run can tell a dead run's leftovers (SIGKILL, a power cut)
    from a live run's."""
    return f"{'.' if hidden else ''}{path.name}{STAGING_INFIX}{os.getpid()}-"


def _alive(pid: int) -> bool:
    try:
        with contextlib.suppress(PermissionError):  # someone else's process: alive
            os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def remove_stale_stagings(path: Path, hidden: bool = False) -> list[Path]:
    """Remove the staging folders beside ``path`` (``OUT.partial-PID-...``, ``.OUT.partial-...``
    if ``hidden``) whose process is gone: what a killed fit into the same OUT left behind; not one
    holding a ``*.old`` file, an old map file a refused commit could not put back and named,
    warned of again (:func:`~spcopyro._util.file_moves.kept_old_files`). Returns the removed."""
    removed = []
    name = f"{'.' if hidden else ''}{path.name}{STAGING_INFIX}"
    pattern = re.compile(re.escape(name) + r"(\d+)-")
    for candidate in path.parent.glob(f"{glob.escape(name)}*"):
        match = pattern.match(candidate.name)
        stale = match and candidate.is_dir() and not _alive(int(match.group(1)))
        if stale and not kept_old_files(candidate):  # *.old: the user's, named (and warned of)
            remove_tree(candidate)
            removed.append(candidate)
    return removed


def stage_output(
    out: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    resume: str | os.PathLike[str] | None = None,
    inputs: Sequence[str | os.PathLike[str] | None] = (),
) -> StagedOutput:
    """:func:`check_output`, then the staging folder beside ``out`` made (and ``out``'s parent):
    an unwritable place fails here, with :class:`OutputError`, before any work."""
    path = check_output(out, overwrite=overwrite, resume=resume, inputs=inputs)
    seen = file_identity(path)
    try:
        staging = staging_folder(path)
    except OSError as error:
        raise OutputError(
            f"--out {out}: cannot write in {path.parent} ({error.strerror or error})"
        ) from None
    return StagedOutput(out=path, path=Path(staging), overwrite=overwrite, seen=seen)


def staging_folder(out: str | os.PathLike[str], hidden: bool = False) -> Path:
    """A new empty folder beside ``out`` (``OUT.partial-PID-XXXXXXXX``, with a leading dot if
    ``hidden``: :func:`staging_prefix`), made as ``mkdir`` makes one; ``out``'s parent made if
    missing, and the staging folders a dead process left beside ``out`` removed first
    (:func:`remove_stale_stagings`). ``out``'s latest write is not
    :func:`~spcopyro._util.folder_commit.completed` any more."""
    path = absolute_path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_stagings(path, hidden)
    write_started(path)
    return _new_folder(path.parent, staging_prefix(path, hidden))


def stage_marked_folder(
    out: str | os.PathLike[str], overwrite: bool, *, option: str, marker: str, writer: str
) -> StagedOutput:
    """A staging folder beside ``out`` for a command that writes one folder whole (the Nav2
    export, a navigation plan): refuses a file at or above ``out``, a non-empty ``out`` without
    ``overwrite``, and with it any folder that holds no ``marker`` (so ``--overwrite`` never
    deletes a folder that ``writer`` did not write) or holds the current directory. ``option``
    names the command-line option in every message."""
    path = absolute_path(out)
    check_folder_path(path, f"{option} {out}")  # a file above it said "... File exists"
    check_not_holding_cwd(path, f"{option} {out}")
    if path.is_dir() and not is_empty_folder(path):
        if not overwrite:
            raise OutputError(
                f"{option} {out}: {path} exists and is not empty; pass --overwrite to replace "
                "it (its files are then deleted), or choose another folder"
            )
        if not (path / marker).is_file():
            raise OutputError(
                f"{option} {out}: {path} holds files that no {writer} wrote (no {marker}); "
                f"--overwrite replaces only a folder that {writer} wrote"
            )
    seen = (path.lstat().st_dev, path.lstat().st_ino) if path.exists() else None
    try:  # OUT.partial-PID-*: a killed export's is swept by the next (remove_stale_stagings)
        staging = staging_folder(path)
    except OSError as error:
        raise OutputError(f"{option} {out}: cannot write in {path.parent} ({error})") from None
    return StagedOutput(out=path, path=staging, overwrite=overwrite, seen=seen)


def _new_name(parent: Path, prefix: str, make: Callable[[Path], T]) -> tuple[Path, T]:
    """(path, ``make(path)``) for the first ``parent / (prefix + random)`` not taken yet
    (``make`` raises FileExistsError for a taken one)."""
    for _ in range(100):
        path = parent / f"{prefix}{secrets.token_hex(4)}"
        try:
            return path, make(path)
        except FileExistsError:
            continue
    raise FileExistsError(f"no free name {prefix}... in {parent}")


def _new_folder(parent: Path, prefix: str) -> Path:
    """A new folder ``parent / (prefix + random)``, its mode as ``mkdir`` gives (not 0700)."""
    return _new_name(parent, prefix, Path.mkdir)[0]


def _new_file(parent: Path, prefix: str) -> tuple[int, Path]:
    """(descriptor, path) of a new file ``parent / (prefix + random)``, its mode as ``open``'s."""
    path, descriptor = _new_name(
        parent, prefix, lambda path: os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    )
    return descriptor, path


def replace_file(path: str | os.PathLike[str], write: Callable[[BinaryIO], None]) -> Path:
    """Write a file through ``write(file)`` into a temporary file beside ``path``, then rename it
    over ``path`` (whose mode it keeps): readers see the old file or the new one, never half."""
    path = absolute_path(path)
    descriptor, partial = _new_file(path.parent, f"{path.name}{STAGING_INFIX}")
    try:
        take_mode(partial, path)  # a file there keeps its mode, as the maps (move_files_in)
        with os.fdopen(descriptor, "wb") as file:
            write(file)
        os.replace(partial, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(partial)
        raise
    return path


def replace_text(path: str | os.PathLike[str], text: str) -> Path:
    """``Path(path).write_text(text)`` (UTF-8), whole or not at all (:func:`replace_file`): a
    report rewritten in place and stopped by Ctrl-C stays the old one, not a half of the new."""
    return replace_file(path, lambda file: file.write(text.encode("utf-8")))


def replace_figure(figure: object, path: str | os.PathLike[str], **savefig: object) -> Path:
    """``figure.savefig(path, **savefig)``, whole or not at all (:func:`replace_file`); the same
    bytes. The format is ``savefig``'s ``format`` or, as savefig reads it, ``path``'s suffix
    (``png`` without one; the path is not given one). ``figure``: a matplotlib Figure."""
    kind = savefig.pop("format", None) or Path(path).suffix[1:].lower() or "png"
    draw = figure.savefig  # type: ignore[attr-defined]
    return replace_file(path, lambda file: draw(file, format=kind, **savefig))
