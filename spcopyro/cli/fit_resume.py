"""``spcopyro fit``'s checkpoints on the command line: which fits keep one on Ctrl-C
(:func:`keeps_checkpoint`), what ``--resume`` may name (:func:`check_resume_file`), the line
printed when Ctrl-C stops a fit (:func:`interrupted_message`; :func:`interrupted_before_fit`
before it began) and the command lines that resume it or, once written, run it again
(:func:`resume_command`, :func:`again_command`, :func:`without_resume`)."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from spcopyro._util.messages import with_article
from spcopyro.cli.common import command_line

__all__ = [
    "again_command",
    "check_resume_file",
    "error_note",
    "interrupted_before_fit",
    "interrupted_message",
    "is_resumable",
    "keeps_checkpoint",
    "keeps_finished_fit",
    "no_checkpoint_flags",
    "one_fit_for_sweeps",
    "resumable_methods",
    "resume_command",
    "without_resume",
]


RESUME_PREFIX = "--res"
"""The shortest prefix argparse reads as ``--resume`` (``--re`` is also ``--refine`` and
``--region-moves``)."""


def is_resumable(name: str) -> bool:
    """Whether the method called ``name`` is a variational method whose fit is saved on Ctrl-C
    (:mod:`spcopyro.guides.checkpoint`); only that method's module is imported (the registry
    makes each on first lookup, and svi's imports Pyro). An unknown name: False."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    if name not in INFERENCE_METHODS:
        return False
    return bool(getattr(INFERENCE_METHODS[name], "resumable", False))  # the protocol alone: False


def resumable_methods() -> list[str]:
    """The variational methods whose fit is saved on Ctrl-C, as messages list them: makes every
    method (imports all their modules, Pyro among them); one fit's checks use
    :func:`is_resumable`."""
    from spcopyro.fit.registry import INFERENCE_METHODS

    return [name for name in INFERENCE_METHODS if is_resumable(name)]


def one_fit_for_sweeps(args: argparse.Namespace) -> bool:
    """Whether this is one fit (``--chains`` 1 or left out) for a number of ``--sweeps``, not
    an ``--update``: what a fit of a method other than Gibbs must be for Ctrl-C to keep its
    iterations (:func:`keeps_checkpoint`; its finished result is kept for several fits and an
    update too, :func:`keeps_finished_fit`)."""
    return args.sweeps != "auto" and args.update is None and args.chains in (None, 1)


def keeps_finished_fit(args: argparse.Namespace) -> bool:
    """Whether Ctrl-C while this fit's outputs are written keeps the finished fit
    (:mod:`spcopyro.cli.fit_finished`): every fit (``--chains K``) of a number of ``--sweeps``,
    of a method other than Gibbs or of an ``--update``; Gibbs chains that are no update keep
    their finished chains instead (:func:`keeps_checkpoint`)."""
    return args.sweeps != "auto" and (args.method != "gibbs" or args.update is not None)


def keeps_checkpoint(args: argparse.Namespace) -> bool:
    """Whether Ctrl-C keeps a checkpoint of this fit: Gibbs chains run for a number of
    ``--sweeps``, or one fit of a variational method that resumes; never an ``--update``."""
    if args.method == "gibbs":
        return args.sweeps != "auto" and args.update is None
    return is_resumable(args.method) and one_fit_for_sweeps(args)


def no_checkpoint_flags(args: argparse.Namespace) -> str:
    """The flags for which this fit keeps no checkpoint, as ``--resume``'s refusal names them:
    ``--chains K`` for several fits of a method that resumes one (``--sweeps N --method cavi``
    alone was named, which does keep one), else ``--sweeps`` and ``--method``."""
    several = args.chains not in (None, 1) and is_resumable(args.method)
    if several and args.sweeps != "auto" and args.update is None:
        return f"--method {args.method} --chains {args.chains}"
    return f"--sweeps {args.sweeps} --method {args.method}"


def check_resume_file(resume: str) -> None:
    """An error for a ``--resume`` that names no checkpoint file: a finished fit (``--update``
    continues it), OUT itself (Ctrl-C keeps ``OUT.checkpoint.npz`` beside OUT, named when it is
    there), another folder, or nothing."""
    from spcopyro._util.outputs import checkpoint_path

    path = Path(resume)
    if (path / "result.npz").is_file():
        raise ValueError(f"--resume {resume} is a finished fit, not a checkpoint: to continue it "
                         f"with new observations use --update {resume}")  # fmt: skip
    if path.is_file():
        return
    beside = checkpoint_path(path)
    hint = (f": the fit interrupted into it kept its state in {beside}; --resume {beside}"
            if beside.is_file() else ": a fit stopped by Ctrl-C keeps its state in "
            "OUT.checkpoint.npz, beside OUT, and prints the command that resumes it")  # fmt: skip
    if path.is_dir():
        raise ValueError(f"--resume {resume} is a folder, not a checkpoint file{hint}")
    raise FileNotFoundError(f"--resume {resume}: no such checkpoint file{hint}")


def interrupted_message(
    args: argparse.Namespace,
    where: str,
    kept: Path | None,
    out: Path,
    why: str | None = None,
    finished: bool = False,
    unchanged: bool = False,
) -> str:
    """The line ``fit`` prints when Ctrl-C stops it (``kept``: its checkpoint; ``why``: none's;
    ``finished``: the fit had run all its sweeps or iterations, its outputs being written;
    ``unchanged``: ``kept`` is the checkpoint this run resumed (``--resume``), left as it
    was). A finished fit other than Gibbs chains' (an ``--update``'s too) is kept as its results
    (:mod:`spcopyro.cli.fit_finished`), which ``--resume`` writes without fitting again."""
    line = f"interrupted{where}: nothing written to {out}"
    return _kept_line(args, line, kept, out, why, finished, unchanged, error=False)


def _kept_line(
    args: argparse.Namespace,
    line: str,
    kept: Path | None,
    out: Path,
    why: str | None,
    finished: bool,
    unchanged: bool,
    error: bool,
) -> str:
    """``line`` and what is kept (``kept``), or that nothing is and why, and the command: the
    Ctrl-C line of :func:`interrupted_message`, or (``error``) the note of :func:`error_note`,
    whose commands are run once the error is fixed."""
    fixed = "once fixed, " if error else ""
    if kept is None:
        why = _why_none(args, out, finished) if why is None else why
        line = f"{line}; no checkpoint kept ({why})"
        if finished:  # the whole fit ran, and its result went with the outputs: say so, and how
            again = again_command(args)  # to get it (its seed: same)
            line = f"{line}: the finished fit is lost -- {fixed}run it again with: {again}"
        return line
    command = resume_command(args, kept)
    if unchanged:  # not "the state reached": this run's iterations are not in it
        lost = "; the iterations this run added are lost" if finished else ""
        return (f"{line}{lost}; {kept} is left as it was, with the state this run resumed "
                f"from -- continue from there with: {command}")  # fmt: skip
    if finished and keeps_finished_fit(args):  # the result itself (spcopyro.cli.fit_finished)
        return (f"{line}; the finished fit is saved in {kept} -- {fixed}write its outputs "
                f"(without fitting again) with: {command}")  # fmt: skip
    saved = "the finished chains are" if error else "the state reached is"
    return f"{line}; {saved} saved in {kept} -- {fixed}continue with: {command}"


def _why_none(args: argparse.Namespace, out: Path, finished: bool) -> str:
    """Why no checkpoint of this fit was kept (``finished``: its sweeps or iterations had all
    run), for :func:`interrupted_message` and :func:`error_note`."""
    if args.sweeps == "auto":
        return "--sweeps auto"
    if finished and (keeps_checkpoint(args) or keeps_finished_fit(args)):
        # the finished fit is kept (a vi-gibbs one too, which keeps no checkpoint of its
        # sweeps; several fits; an --update), but its file could not be written
        from spcopyro._util.outputs import checkpoint_path

        return ("its iterations had all run; the finished fit could not be saved in "
                f"{checkpoint_path(out)}")  # fmt: skip
    if args.update is not None:
        return "--update"
    if keeps_checkpoint(args):
        return "no sweep was done" if args.method == "gibbs" else "no iteration was done"
    if is_resumable(args.method):
        return f"--chains {args.chains}: {with_article(args.method)} checkpoint holds one fit"
    return f"the {args.method!r} method"


def error_note(
    args: argparse.Namespace, kept: Path | None, out: Path, finished: bool
) -> str | None:
    """The note ``fit`` prints when an error (not Ctrl-C: a full disk, a figure failing) stops
    it after its sweeps or iterations, before OUT is written (``kept``: the finished chains, or
    the finished fit where :func:`keeps_finished_fit`, :mod:`spcopyro.cli.fit_finished`): the
    command that continues from ``kept`` or writes its outputs once the error is fixed; where
    nothing was kept of a finished fit, that it is lost and why; None where nothing had
    finished and nothing was kept."""
    if kept is None and not finished:
        return None
    line = f"note: nothing written to {out}"
    return _kept_line(args, line, kept, out, None, finished, False, error=True)


def interrupted_before_fit(args: argparse.Namespace, stage: str) -> str:
    """The line ``fit`` prints when Ctrl-C stops it before the fit began, while ``stage`` (e.g.
    ``"loading the data"``): nothing was written and the checkpoint it resumes (``--resume``) or
    the fit it updates (``--update``) is left as it was; the command that starts it again."""
    line = f"interrupted while {stage}, before the fit began: nothing was changed ({args.out} not "
    if args.resume is not None:
        command = resume_command(args, Path(args.resume))
        return f"{line}written, {args.resume} left as it was) -- continue with: {command}"
    kept = "" if args.update is None else f", the fit in {args.update} left as it was"
    return f"{line}written{kept}) -- run it again with: {again_command(args)}"


def resume_command(args: argparse.Namespace, checkpoint: Path) -> str:
    """This run's command line with ``--resume CHECKPOINT`` (in place of an earlier one)."""
    return f"{again_command(args)} {shlex.join(['--resume', str(checkpoint)])}"


def again_command(args: argparse.Namespace) -> str:
    """This run's command line without its ``--resume CHECKPOINT``: the one that runs the whole
    fit again (its seed the same)."""
    return shlex.join(["spcopyro", *without_resume(args)])


def without_resume(args: argparse.Namespace) -> list[str]:
    """This run's command line without its ``--resume CHECKPOINT``: the fit it finishes, which
    the checkpoint (removed once the fit is written) is not needed to run again."""
    argv = command_line(args)
    for k in range(len(argv) - 1, -1, -1):
        flag, equals, _ = argv[k].partition("=")
        if len(flag) >= len(RESUME_PREFIX) and "--resume".startswith(flag):  # as argparse reads
            del argv[k : k + (1 if equals else 2)]
    return argv
