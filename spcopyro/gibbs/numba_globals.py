r"""The compiled draw of pi, theta and w given the labels (eqs. 14-17), its prior part ahead.

Each global is a table of Dirichlet rows, row r drawn as normalised gamma variates

.. math::

    G_{rc} \sim \mathrm{Gamma}(b + s_{rc}, 1), \qquad
    \log \phi_{rc} = \log G_{rc} - \log \textstyle\sum_{c'} G_{rc'},

b the table's symmetric concentration (alpha / L or alpha for pi, chi for theta, beta for w) and
s its statistics given the labels (cells per concept; image and word counts of the cells of each
concept). Wherever s_rc = 0 (every concept without observed cells, every word none of a
concept's cells heard; three quarters of the 26.4k variates of a public house at L = 120) the
shape is b: it does not depend on the labels. A sweep can therefore draw its globals in two
parts (opt-in, :func:`prior_thread`; the default is the one-pass draw of
:mod:`~spcopyro.gibbs.numba_sweep`: on the project's shared 2-core machine the worker's ratio to
the one-pass sweep ranged 0.62-1.37 from run to run, ``benchmarks/prior_thread.py``):

1. **Ahead** (:func:`start_prior_draws`): every entry of every table gets a Gamma(b) variate,
   from streams of their own (one per row, seeded from the row and a seed the sweep draws from
   its torch generator before the labels), independent of the state. On a machine with a spare
   CPU a worker thread draws them while the label loop runs (:func:`prior_thread`); the calling
   thread draws whatever chunks of rows the worker has not claimed when it needs them, leaving
   out the rows it will redraw whole. The numbers are the same whichever thread draws a row,
   and with the worker off.
2. **After the labels** (:func:`finish_globals`): every entry with s_rc != 0 is drawn afresh
   from Gamma(b + s_rc) with the sweep's stream, the others keep their prior variate; rows are
   normalised in linear space where every shape is >= 1, by log-sum-exp where one is below 1
   (log G(a) = log G(a + 1) + log(U) / a, :mod:`~spcopyro.gibbs.numba_random`).

**Exact.** Given the labels, the kept prior variates are independent Gamma(b) variates (drawn
from streams nothing else reads, and never reused by a later sweep), independent of the fresh
ones; which entries keep theirs depends on the labels alone. Each row is then a vector of
independent Gamma(b + s_rc) variates, and normalised it is a Dir(b + s_r) draw. (Keeping the
*previous* sweep's rows of the concepts whose counts did not change would not be exact: that
event is correlated with the old theta.)
"""

from __future__ import annotations

import atexit
import math
import os
import queue
import threading
from collections.abc import Callable, Sequence

import numpy as np
from numba import njit

from spcopyro._util.threads import usable_cpus
from spcopyro.gibbs.numba_random import bits_to_uniform, marsaglia_tsang, next_bits

__all__ = [
    "PriorDraws",
    "abandon_prior_draws",
    "finish_globals",
    "prior_thread",
    "start_prior_draws",
    "two_part",
]

CHUNK_ENTRIES = 4096
"""About this many variates per chunk of rows of the prior draw (one claim each)."""
_U_GOLDEN, _U_MIX1, _U_MIX2 = (
    np.uint64(k) for k in (0x9E3779B97F4A7C15, 0xBF58476D1CE4E5B9, 0x94D049BB133111EB)
)
_U27, _U30, _U31 = np.uint64(27), np.uint64(30), np.uint64(31)


# ------------------------------------------------------------------------------------ kernels


@njit(cache=True, inline="always")
def _gamma_draw(
    a: float, s0: np.uint64, s1: np.uint64, s2: np.uint64, s3: np.uint64, state: np.ndarray
) -> tuple[float, float, np.uint64, np.uint64, np.uint64, np.uint64]:
    """(G, log G, next RNG state) for G ~ Gamma(a), a finite and positive; for a < 1, G is
    Gamma(a + 1)'s variate (only its log carries the boost log(U) / a)."""
    extra = 0.0
    if a < 1.0:
        bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
        extra = math.log(1.0 - bits_to_uniform(bits)) / a  # 1 - U lies in (0, 1]
        a += 1.0
    if a == 1.0:  # Gamma(1) is Exp(1): -log(1 - U), exactly
        draw = 0.0
        while draw == 0.0:  # U = 0 exactly (p = 2^-53): log G would be -inf
            bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
            draw = -math.log(1.0 - bits_to_uniform(bits))
    else:
        d = a - 1.0 / 3.0
        draw, s0, s1, s2, s3 = marsaglia_tsang(d, 1.0 / math.sqrt(9.0 * d), s0, s1, s2, s3, state)
    return draw, math.log(draw) + extra, s0, s1, s2, s3


@njit(cache=True, inline="always")
def _splitmix(x: np.uint64) -> tuple[np.uint64, np.uint64]:
    """(the next SplitMix64 output, the advanced counter) from counter ``x``."""
    x = x + _U_GOLDEN
    z = (x ^ (x >> _U30)) * _U_MIX1
    z = (z ^ (z >> _U27)) * _U_MIX2
    return z ^ (z >> _U31), x


@njit(cache=True, inline="always")
def _row_stream(
    seed: np.uint64, row: np.int64
) -> tuple[np.uint64, np.uint64, np.uint64, np.uint64]:
    """The xoshiro256++ state of global row ``row``'s own stream: SplitMix64 from the hash of
    (seed, row)."""
    key, _ = _splitmix(seed + np.uint64(row + 1) * _U_GOLDEN)
    s0, x = _splitmix(key)
    s1, x = _splitmix(x)
    s2, x = _splitmix(x)
    s3, x = _splitmix(x)
    return s0, s1, s2, s3


@njit(cache=True, nogil=True)
def _prior_chunk(
    base: float,
    linear: np.ndarray,
    log_g: np.ndarray,
    row_sums: np.ndarray,
    start: int,
    stop: int,
    seed: np.uint64,
    first_row: int,
    skip: np.ndarray,
) -> None:
    """Rows start:stop of a table [R, C], each from its own stream (:func:`_row_stream` of row
    first_row + r): linear = G ~ Gamma(base) (Gamma(base + 1) for base < 1), log_g = log G
    (boosted for base < 1), row_sums [R] = sum_c linear. Rows where ``skip`` [R] is set are
    left alone (every entry of theirs will be drawn afresh). ``base`` is finite and positive."""
    state = np.empty(4, dtype=np.uint64)  # the ziggurat's slow-path scratch
    a, boosted = base, base < 1.0
    if boosted:
        a = base + 1.0
    d = a - 1.0 / 3.0
    scale = 1.0 / math.sqrt(9.0 * d) if a > 1.0 else 0.0
    for r in range(start, stop):
        if skip[r]:
            continue
        s0, s1, s2, s3 = _row_stream(seed, first_row + r)
        total = 0.0
        for c in range(linear.shape[1]):
            extra = 0.0
            if boosted:
                bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                extra = math.log(1.0 - bits_to_uniform(bits)) / base
            if a == 1.0:
                draw = 0.0
                while draw == 0.0:
                    bits, s0, s1, s2, s3 = next_bits(s0, s1, s2, s3)
                    draw = -math.log(1.0 - bits_to_uniform(bits))
            else:
                draw, s0, s1, s2, s3 = marsaglia_tsang(d, scale, s0, s1, s2, s3, state)
            linear[r, c] = draw
            log_g[r, c] = math.log(draw) + extra
            total += draw
        row_sums[r] = total


@njit(cache=True, nogil=True)
def _posterior_rows(
    base: float,
    statistics: np.ndarray,
    linear: np.ndarray,
    log_g: np.ndarray,
    row_sums: np.ndarray,
    state: np.ndarray,
) -> int:
    """Complete the prior draw of a table [R, C] to R Dirichlet(base + statistics[r]) rows, in
    place in ``log_g`` (module doc): entries with a nonzero statistic drawn afresh with
    ``state``, then every row normalised. Returns -1, or the flat index of the first shape that
    is not finite and positive (then ``log_g`` is garbage)."""
    R, C = statistics.shape
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    boosted = np.zeros(R, dtype=np.bool_)  # [R] rows with a shape below 1
    for r in range(R):
        touched = False
        boosted[r] = base < 1.0
        for c in range(C):
            s = statistics[r, c]
            if s == 0.0:
                continue
            a = base + s
            if not 0.0 < a < np.inf:  # NaN too
                state[0], state[1], state[2], state[3] = s0, s1, s2, s3
                return r * C + c
            if a < 1.0:
                boosted[r] = True
            linear[r, c], log_g[r, c], s0, s1, s2, s3 = _gamma_draw(a, s0, s1, s2, s3, state)
            touched = True
        if touched and not boosted[r]:
            total = 0.0
            for c in range(C):
                total += linear[r, c]
            row_sums[r] = total
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    for r in range(R):
        if boosted[r]:  # log-sum-exp: G(a) underflows in linear space for small a
            top = -np.inf
            for c in range(C):
                top = max(top, log_g[r, c])
            total = 0.0
            for c in range(C):
                total += math.exp(log_g[r, c] - top)
            shift = top + math.log(total)
        else:  # every shape >= 1: the linear sum is safe
            shift = math.log(row_sums[r])
        for c in range(C):
            log_g[r, c] -= shift
    return -1


# ------------------------------------------------------------------------------ the prior part


class PriorDraws:
    """One sweep's Gamma(b) variates for every entry of every table, drawn in chunks of rows by
    whichever thread claims them first (the worker of :func:`prior_thread`, or the caller of
    :meth:`tables`). Each row has its own stream, seeded from (seed, row) alone, so the numbers
    do not depend on who draws them; the caller skips the rows all of whose entries it will
    draw afresh (the worker, drawing before the labels, cannot know them)."""

    def __init__(
        self,
        bases: Sequence[float],
        shapes: Sequence[tuple[int, int]],
        seed: int,
        hint: Callable[[], Sequence[np.ndarray]] | None = None,
    ):
        self.bases = [float(b) for b in bases]
        self.linear = [np.empty(shape) for shape in shapes]  # [R, C] each
        self.log_g = [np.empty(shape) for shape in shapes]  # [R, C] each
        self.row_sums = [np.empty(shape[0]) for shape in shapes]  # [R] each
        self._chunks = []  # (table, start row, stop row)
        self._first_rows = []  # each table's first global row (its rows' streams follow)
        first = 0
        for index, (rows, columns) in enumerate(shapes):
            step = max(1, CHUNK_ENTRIES // max(columns, 1))
            self._chunks += [(index, r, min(r + step, rows)) for r in range(0, rows, step)]
            self._first_rows.append(first)
            first += rows
        self._no_skip = [np.zeros(shape[0], dtype=np.bool_) for shape in shapes]
        self.drawn = [np.zeros(shape[0], dtype=np.bool_) for shape in shapes]  # [R] each
        self._hint = hint
        self._seed = np.uint64(int(seed) & ((1 << 64) - 1))
        self._lock = threading.Lock()
        self._claimed = 0
        self._done = 0
        self._finished = threading.Event()
        self._error: BaseException | None = None
        self.released = False  # no longer counted as an active sweep (abandon_prior_draws)
        if not self._chunks:
            self._finished.set()

    def _claim(self) -> int:
        with self._lock:
            if self._claimed == len(self._chunks):
                return -1
            self._claimed += 1
            return self._claimed - 1

    def draw(self, skip: Sequence[np.ndarray] | None = None) -> None:
        """Draw chunks until none is left unclaimed (a worker's job, and the caller's help),
        leaving out the rows where ``skip`` (one [R] bool mask per table) is set; without it
        (the worker) the rows the hint guesses will be redrawn whole. Which rows are drawn does
        not change any number: :meth:`tables` draws the missing ones from their own streams."""
        if skip is None:
            try:
                skip = self._no_skip if self._hint is None else self._hint()
            except Exception:  # only a guess: without it every row is drawn
                skip = self._no_skip
        while (k := self._claim()) >= 0:
            try:
                index, start, stop = self._chunks[k]
                _prior_chunk(
                    self.bases[index], self.linear[index], self.log_g[index],
                    self.row_sums[index], start, stop, self._seed, self._first_rows[index],
                    skip[index],
                )  # fmt: skip
                self.drawn[index][start:stop] = ~skip[index][start:stop]
            except BaseException as error:  # re-raised by tables(); never a silent hang
                self._error = error
            finally:
                with self._lock:
                    self._done += 1
                    if self._done == len(self._chunks):
                        self._finished.set()

    def tables(
        self, skip: Sequence[np.ndarray] | None = None
    ) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
        """(base, linear, log_g, row_sums) per table once every row outside ``skip`` is drawn:
        the caller draws the unclaimed chunks, waits for those in flight on the worker, then
        draws the rows the worker's hint left out wrongly."""
        self.draw(skip)
        self._finished.wait()
        if self._error is not None:
            raise self._error
        skip = self._no_skip if skip is None else skip
        for index, (drawn, left) in enumerate(zip(self.drawn, skip, strict=True)):
            done = drawn | left  # [R] rows drawn, or not needed
            if not done.all():
                _prior_chunk(
                    self.bases[index], self.linear[index], self.log_g[index],
                    self.row_sums[index], 0, done.shape[0], self._seed,
                    self._first_rows[index], done,
                )  # fmt: skip
                drawn |= ~done
        return list(zip(self.bases, self.linear, self.log_g, self.row_sums, strict=True))


# ------------------------------------------------------------------------------- the worker

_MODES = ("one-pass", "auto", "on", "off")
_mode = os.environ.get("SPCOPYRO_PRIOR_THREAD", "one-pass")
_jobs: queue.SimpleQueue[PriorDraws | None] = queue.SimpleQueue()  # None: the worker returns
_worker: threading.Thread | None = None
_worker_lock = threading.Lock()
_active = 0  # sweeps drawing their globals in this process right now (chains run in threads)


def prior_thread(mode: str | None = None) -> str:
    """How the compiled sweep draws its globals, set to ``mode`` when given (environment
    variable ``SPCOPYRO_PRIOR_THREAD``): ``"one-pass"`` (the default) every variate after the
    labels on the calling thread, without this module (the two-part draw did not pay reliably on
    the project's shared 2-core machine: module doc); the
    two-part draw with ``"auto"`` (the worker while at most half the usable CPUs run sweeps in
    this process), ``"on"`` (always) or ``"off"`` (never). The two-part modes draw the same
    numbers as each other, which differ from the one-pass draw's (same distribution)."""
    global _mode
    if mode is not None:
        if mode not in _MODES:
            raise ValueError(f"prior_thread mode must be one of {_MODES}, got {mode!r}")
        _mode = mode
    return _mode


def two_part() -> bool:
    """Whether the compiled sweep draws its globals in two parts (:func:`prior_thread`)."""
    return _mode in _MODES and _mode != "one-pass"


def _use_worker() -> bool:
    if _mode in ("off", "one-pass") or _mode not in _MODES:
        return False
    return _mode == "on" or 2 * _active <= usable_cpus()


def _serve() -> None:
    while (job := _jobs.get()) is not None:
        job.draw()


@atexit.register
def _stop_worker() -> None:
    """At exit, let the worker finish the jobs it has and return. Left running, a daemon thread
    that takes the GIL back (from a torch call in the hint, or compiled code) while the
    interpreter finalizes is ended by ``pthread_exit``, whose unwinding through C++ frames
    aborts the process ("terminate called without an active exception", CPython bpo-42969)."""
    with _worker_lock:
        worker = _worker
    if worker is not None and worker.is_alive():
        _jobs.put(None)
        worker.join()


def _submit(job: PriorDraws) -> None:
    global _worker
    with _worker_lock:
        if _worker is None or not _worker.is_alive():
            _worker = threading.Thread(target=_serve, name="spcopyro-prior-draws", daemon=True)
            _worker.start()
    _jobs.put(job)


def _count_active(change: int) -> None:
    global _active
    with _worker_lock:
        _active += change


def start_prior_draws(
    bases: Sequence[float],
    shapes: Sequence[tuple[int, int]],
    seed: int,
    hint: Callable[[], Sequence[np.ndarray]] | None = None,
) -> PriorDraws:
    """Start one sweep's prior draw (tables of ``shapes`` [R, C] with concentrations ``bases``,
    every base finite and positive) from ``seed``, on the worker when :func:`prior_thread` says
    so; then :func:`finish_globals` (or :func:`abandon_prior_draws` if the sweep fails).
    ``hint()``, called on the worker, guesses the rows that will be redrawn whole (one [R] bool
    mask per table; e.g. from the labels before the sweep): the worker leaves them out. A wrong
    guess costs time, never a different number."""
    _count_active(1)
    job = PriorDraws(bases, shapes, seed, hint)
    if _use_worker():
        _submit(job)
    return job


def abandon_prior_draws(job: PriorDraws) -> None:
    """Give up a started prior draw (the sweep failed): it no longer counts as active."""
    if not job.released:
        job.released = True
        _count_active(-1)


def finish_globals(
    job: PriorDraws, statistics: Sequence[np.ndarray], state: np.ndarray
) -> tuple[list[np.ndarray], int, int]:
    """([R, C] log Dirichlet rows per table, -1, -1) given each table's statistics (float64,
    C-contiguous, the shapes of :func:`start_prior_draws`), drawn with the RNG ``state``; or
    (partial, table index, flat index) of the first shape that is not finite and positive."""
    try:
        # rows whose every entry has a statistic are drawn afresh whole: their prior variates
        # are not needed (the worker may have drawn them anyway; the numbers are the same)
        tables = job.tables([(stats != 0.0).all(axis=1) for stats in statistics])
    finally:
        abandon_prior_draws(job)
    out = []
    for index, ((base, linear, log_g, row_sums), stats) in enumerate(
        zip(tables, statistics, strict=True)
    ):
        bad = _posterior_rows(base, stats, linear, log_g, row_sums, state)
        if bad >= 0:
            return out, index, bad
        out.append(log_g)
    return out, -1, -1
