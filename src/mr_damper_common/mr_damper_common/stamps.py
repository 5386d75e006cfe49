"""
Stamp sanity: the one home of "is this time stamp usable?" for every consumer of stamps (no ROS).

A node that takes stamped messages (the controller its vehicle states, the identifier its rig
samples, the car its rig measurements) keeps one :class:`StampGuard` per stream and asks it
about every stamp, with its own clock's now. The guard refuses, and counts by named reason
(:data:`STAMP_REFUSALS`):

``non_finite``
    NaN or infinite stamp.
``out_of_order``
    Earlier than the reference (the newest stamp taken).
``duplicate``
    Equal to the reference (unless ``accept_equal``: then in order).
``future_stamp``
    Implausibly far ahead of the node clock: more than ``max_future_s`` beyond where the
    clock says the stream should be. With a reference ``t_ref`` taken at node time
    ``now_ref``, a stamp ``t`` received at ``now`` is in the future when
    ``t > t_ref + (now - now_ref) + max_future_s`` (the stamp advanced further than the clock
    did, by more than the horizon): this works whether the stream is stamped on the node's
    clock or on a clock of its own (a simulated car counting from 0 s). Before any reference
    the stamp is compared with the clock itself (``t > now + max_future_s``), which only
    catches streams stamped on the node's time base. Without a usable clock (``now`` None,
    not finite or <= 0: a simulated clock not started yet) nothing is in the future.

With ``stream_clock`` (the identifier's measurement stream, stamped on a clock of its own and
replayed at any rate: a rig at ``rate_factor`` 4 on wall time, a replay as fast as the reader
takes it) the horizon is measured on the stream's own clock instead: the stamps are taken to
advance ``rate`` times as fast as the node clock, ``rate`` the stream's recent advance (its
newest stamp over the last :data:`RATE_WINDOW_S` of node time, at least 1), so a stamp ``t``
is in the future when ``t > t_ref + rate * (now - now_ref) + max_future_s``; before any
reference nothing is (the stream's clock is not known yet). A batch of samples received at
once is judged as a whole (:meth:`StampGuard.batch_verdict`): its newest stamp against that
limit, so a batch cannot carry the stream ahead by more than the horizon however plausibly its
own samples follow each other (one message of 100 s of samples stamped ahead).

A refused stamp never becomes the reference, so one bad stamp costs one message, not the rest
of the run. A vehicle clock that really jumps is followed instead of refused for good: after
``rebase_after`` consecutive out-of-order stamps that increase among themselves (a clock
jumped backwards), or ``rebase_after`` consecutive future stamps that increase plausibly among
themselves (each within ``max_future_s`` plus the clock's advance of the previous one: a clock
jumped forwards beyond the horizon), the last of them is accepted as a re-based reference
(:data:`REBASED`, counted in :attr:`StampGuard.rebases`); the caller restarts whatever depends
on the stamp order (the identifier its sample buffer). A forward jump within the horizon is
simply in order. The out-of-order run follows the identifier's ``restart_samples`` rule
exactly: a duplicate ends it, a stamp not above the previous out-of-order one starts it again.

Use
---
One stamp: ``verdict = guard.offer(t, now)`` (check and, if accepted, take it as the
reference). A caller that may still refuse an accepted stamp for another reason (a sample
out of its sensor range) calls :meth:`StampGuard.check` and then :meth:`StampGuard.commit`
only for samples it keeps, as ``LiveIdentifier.add_sample`` does with ``_last_t``. A batch:
:meth:`StampGuard.screen` (a vectorised fast path for an in-order batch, the same verdicts as
offering the stamps one by one).
"""
from dataclasses import dataclass, field
import math

import numpy as np

#: Reasons a stamp is refused (the keys of :attr:`StampGuard.counts`).
STAMP_REFUSALS = ('non_finite', 'future_stamp', 'out_of_order', 'duplicate')

#: Verdict of an accepted, in-order stamp.
ACCEPTED = ''

#: Verdict of an accepted stamp that re-based the stream (a clock jump followed).
REBASED = 'rebased'

#: Node time over which a ``stream_clock`` guard measures the stream's rate [s].
RATE_WINDOW_S = 2.0
#: Shortest node time a rate is measured over [s] (a burst of batches received at once has
#: no rate of its own).
MIN_RATE_SPAN_S = 0.1


def _clock(now):
    """Return ``now`` as a float if it is a usable clock reading, else None."""
    if now is None:
        return None
    now = float(now)
    return now if math.isfinite(now) and now > 0 else None


@dataclass
class StampScreen:
    """
    Verdicts of a batch of stamps (:meth:`StampGuard.screen`).

    Attributes
    ----------
    accepted : numpy.ndarray of bool, shape (n,)
        Stamps accepted (in order or re-based).
    counts : dict
        ``{reason: count}`` of the refusals in this batch (every :data:`STAMP_REFUSALS` key).
    rebased_at : tuple of int
        Indices of the stamps that re-based the stream: samples before such an index belong
        to the old stream (the caller restarts before it).

    """

    accepted: np.ndarray
    counts: dict = field(default_factory=lambda: dict.fromkeys(STAMP_REFUSALS, 0))
    rebased_at: tuple = ()

    @property
    def n_refused(self):
        """Return the number of stamps refused in the batch."""
        return int(sum(self.counts.values()))


class StampGuard:
    """
    Refuse unusable stamps of one stream, count why, and follow real clock jumps.

    Parameters
    ----------
    max_future_s : float
        Horizon [s]: a stamp further ahead of the node clock than this is refused
        (``future_stamp``); see the module docstring for "ahead of the node clock". ``inf``
        turns the check off.
    rebase_after : int
        Consecutive out-of-order (or future) stamps, increasing among themselves, after which
        the stream is re-based on the last of them (>= 1).
    accept_equal : bool
        Take a stamp equal to the reference as in order (the controller: a vehicle may send a
        state twice) instead of refusing it as ``duplicate`` (the identifier: one sample per
        stamp).
    stream_clock : bool
        Measure the horizon on the stream's own clock (its recent rate against the node
        clock; nothing is in the future before a reference), see the module docstring.

    Attributes
    ----------
    last : float
        Reference: the newest stamp taken [s] (``-inf`` before the first and after a re-base
        until the re-basing stamp is committed).
    counts : dict
        ``{reason: count}`` of :data:`STAMP_REFUSALS` since construction (or :meth:`reset`).
    n_accepted : int
        Stamps accepted (including those that re-based).
    rebases_backward, rebases_forward : int
        Re-bases after a backward / a forward clock jump.
    last_rebase : dict or None
        ``{'direction', 'from_s', 'to_s'}`` of the latest re-base.
    rate : float
        ``stream_clock``: stream time per node time of the recent stamps (>= 1; 1 without
        ``stream_clock`` or before it is measured).

    Raises
    ------
    ValueError
        ``max_future_s`` not > 0 (or NaN), ``rebase_after`` not an integer >= 1.

    """

    def __init__(self, *, max_future_s=1.0, rebase_after=50, accept_equal=False,
                 stream_clock=False):
        max_future_s = float(max_future_s)
        if not max_future_s > 0:
            raise ValueError(f'`max_future_s` must be > 0 s, got {max_future_s}')
        if int(rebase_after) != rebase_after or rebase_after < 1:
            raise ValueError(f'`rebase_after` must be an integer >= 1, got {rebase_after!r}')
        self.max_future_s = max_future_s
        self.rebase_after = int(rebase_after)
        self.accept_equal = bool(accept_equal)
        self.stream_clock = bool(stream_clock)
        self.reset()

    def reset(self):
        """Forget the reference, the runs and every count (a new stream)."""
        self.last = -math.inf
        self._ref_now = None       # node clock when the reference was committed
        self.counts = dict.fromkeys(STAMP_REFUSALS, 0)
        self.n_accepted = 0
        self.rebases_backward = 0
        self.rebases_forward = 0
        self.last_rebase = None
        self._clear_runs()
        self._clear_rate()

    def _clear_rate(self):
        self.rate = 1.0
        self._rate_points = []     # (node time, newest stamp), one per RATE_WINDOW_S / 32

    def _clear_runs(self):
        self._ooo_run = 0
        self._ooo_last = -math.inf
        self._fut_run = 0
        self._fut_last = -math.inf
        self._fut_now = None

    @property
    def rebases(self):
        """Return the number of re-bases (backward and forward clock jumps)."""
        return self.rebases_backward + self.rebases_forward

    @property
    def n_refused(self):
        """Return the number of stamps refused, all reasons."""
        return sum(self.counts.values())

    def limit(self, now):
        """
        Return the latest plausible stamp [s] at node time ``now`` (``inf``: no clock).

        Parameters
        ----------
        now : float or None
            Node clock [s].

        """
        now = _clock(now)
        if now is None:
            return math.inf
        if self._ref_now is not None:
            return self.last + self.rate * (now - self._ref_now) + self.max_future_s
        if self.stream_clock:
            return math.inf           # the stream's clock is not known yet
        return now + self.max_future_s

    # ---------------------------------------------------------------- one stamp
    def check(self, t, now=None):
        """
        Judge one stamp, count a refusal, but do not take it as the reference.

        Parameters
        ----------
        t : float
            Stamp [s].
        now : float, optional
            Node clock [s] at receipt (None: no future check).

        Returns
        -------
        str
            :data:`ACCEPTED` (``''``), :data:`REBASED` (accepted as the first stamp of a
            re-based stream: the reference is cleared until :meth:`commit`), or the refusal
            reason (one of :data:`STAMP_REFUSALS`, counted).

        """
        t = float(t)
        if not math.isfinite(t):
            self.counts['non_finite'] += 1
            return 'non_finite'
        last = self.last
        if t < last or (t == last and not self.accept_equal):
            reason = 'duplicate' if t == last else 'out_of_order'
            if reason == 'out_of_order' and t > self._ooo_last:
                self._ooo_run += 1
            else:
                self._ooo_run = 1 if reason == 'out_of_order' else 0
            self._ooo_last = t
            if self._ooo_run < self.rebase_after:
                self.counts[reason] += 1
                return reason
            return self._rebase(t, 'backward')
        if t > self.limit(now):
            clock = _clock(now)
            if (self._fut_run and t > self._fut_last and t <= self._fut_last
                    + self.rate * (clock - self._fut_now) + self.max_future_s):
                self._fut_run += 1
            else:
                self._fut_run = 1
            self._fut_last, self._fut_now = t, clock
            if self._fut_run < self.rebase_after:
                self.counts['future_stamp'] += 1
                return 'future_stamp'
            return self._rebase(t, 'forward')
        self._clear_runs()
        self.n_accepted += 1
        return ACCEPTED

    def _rebase(self, t, direction):
        if direction == 'backward':
            self.rebases_backward += 1
        else:
            self.rebases_forward += 1
        self.last_rebase = {'direction': direction, 'from_s': self.last, 'to_s': t}
        self.last = -math.inf
        self._ref_now = None
        self._clear_runs()
        self._clear_rate()
        self.n_accepted += 1
        return REBASED

    def commit(self, t, now=None):
        """
        Take an accepted stamp as the reference (after :meth:`check` accepted it).

        Parameters
        ----------
        t : float
            The stamp [s] :meth:`check` accepted.
        now : float, optional
            Node clock [s] at its receipt (the base of the next future checks).

        """
        self.last = float(t)
        self._ref_now = _clock(now)
        if self.stream_clock and self._ref_now is not None:
            self._measure_rate()

    def _measure_rate(self):
        """Note the newest (node time, stamp) and measure the stream's rate (stream_clock)."""
        now, pts = self._ref_now, self._rate_points
        if not pts or now - pts[-1][0] >= RATE_WINDOW_S / 32:
            pts.append((now, self.last))
        while len(pts) > 2 and now - pts[1][0] >= RATE_WINDOW_S:
            pts.pop(0)
        span = now - pts[0][0]
        if span >= MIN_RATE_SPAN_S:
            self.rate = max(1.0, (self.last - pts[0][1]) / span)

    def offer(self, t, now=None):
        """
        Judge one stamp and, if accepted, take it as the reference.

        Returns
        -------
        str
            As :meth:`check`.

        """
        verdict = self.check(t, now)
        if verdict in (ACCEPTED, REBASED):
            self.commit(t, now)
        return verdict

    # ---------------------------------------------------------------- a batch
    def batch_verdict(self, t, now=None):
        """
        Judge how far a batch received at once reaches ahead, as a whole (nothing is taken).

        Only the future: the batch's newest finite stamp against :meth:`limit` at ``now``
        (order, duplicates and non-finite stamps are for the stamp-by-stamp checks). A batch
        refused here is counted whole (``future_stamp``, every stamp) and never becomes the
        reference. Consecutive refused batches that follow each other as a stream would (each
        spanning at most the horizon, and continuing the previous one within the horizon plus
        the stream's advance) re-base the stream once they hold ``rebase_after`` stamps: a
        clock that really jumped ahead is followed; a single batch spanning more than the
        horizon never is.

        Parameters
        ----------
        t : array_like with shape (n,)
            The batch's stamps [s].
        now : float, optional
            Node clock [s] at receipt (None: nothing is in the future).

        Returns
        -------
        str
            :data:`ACCEPTED`, ``'future_stamp'`` (the batch refused) or :data:`REBASED` (the
            batch begins a re-based stream: the reference is cleared; offer its stamps next).

        """
        t = np.asarray(t, dtype=float)
        t = t[np.isfinite(t)]
        if not t.size:
            return ACCEPTED
        first, newest = float(t.min()), float(t.max())
        if newest <= self.limit(now):
            return ACCEPTED
        clock = _clock(now)
        own = newest - first <= self.max_future_s
        follows = bool(self._fut_run and first > self._fut_last and newest <= self._fut_last
                       + self.rate * (clock - self._fut_now) + self.max_future_s)
        self._fut_run = (self._fut_run + t.size if follows else t.size) if own else 0
        self._fut_last, self._fut_now = newest, clock
        if follows and self._fut_run >= self.rebase_after:
            self._rebase(first, 'forward')
            self.n_accepted -= 1          # its stamps are counted as they are offered
            return REBASED
        self.counts['future_stamp'] += int(t.size)
        return 'future_stamp'

    def clean(self, t, now=None):
        """
        Tell whether a batch passes as a whole: increasing, after the reference, in the horizon.

        The fast path of a caller that takes a clean batch with array operations (the
        identifier): True means offering the stamps one by one would accept each; the caller
        then takes them with :meth:`take_clean`. Nothing is counted here.
        """
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.size == 0 or not np.isfinite(t).all():
            return False
        steps = np.diff(t)
        first_ok = t[0] > self.last or (t[0] == self.last and self.accept_equal)
        return bool(first_ok and t[0] <= self.limit(now) and (steps.size == 0 or (
            (steps.min() > 0 or (self.accept_equal and steps.min() >= 0))
            and steps.max() <= self.max_future_s)))

    def take_clean(self, t, now=None):
        """Take a batch that :meth:`clean` passed: count it accepted, its newest the reference."""
        self._clear_runs()
        self.n_accepted += len(t)
        self.commit(t[-1], now)

    def screen(self, t, now=None, *, commit=None):
        """
        Judge a batch of stamps received together, in order; same verdicts as one by one.

        Parameters
        ----------
        t : array_like with shape (n,)
            Stamps [s] in arrival order.
        now : float, optional
            Node clock [s] at receipt of the batch.
        commit : array_like of bool with shape (n,), optional
            False where the caller refuses the sample for another reason whatever the stamp
            (e.g. out of the sensor range): such a stamp is judged and counted, but never
            becomes the reference (:meth:`check` without :meth:`commit`). Default: all True.

        Returns
        -------
        StampScreen

        Raises
        ------
        ValueError
            ``t`` not one-dimensional, or ``commit`` of another length.

        """
        t = np.asarray(t, dtype=float)
        if t.ndim != 1:
            raise ValueError(f'`t` must be one-dimensional, got shape {t.shape}')
        n = t.size
        if commit is not None:
            commit = np.asarray(commit, dtype=bool)
            if commit.shape != t.shape:
                raise ValueError(f'`commit` must have the shape of `t` {t.shape}, '
                                 f'got {commit.shape}')
        out = StampScreen(np.zeros(n, dtype=bool))
        if n == 0:
            return out
        # fast path: finite, increasing, after the reference, each step within the horizon
        # (after a commit at the same now, the horizon of the next stamp is max_future_s)
        if (commit is None or commit.all()) and self.clean(t, now):
            out.accepted[:] = True
            self.take_clean(t, now)
            return out
        before = dict(self.counts)
        rebased = []
        for k in range(n):
            verdict = self.check(t[k], now)
            if verdict in (ACCEPTED, REBASED):
                out.accepted[k] = True
                if verdict == REBASED:
                    rebased.append(k)
                if commit is None or commit[k]:
                    self.commit(t[k], now)
        out.counts = {r: self.counts[r] - before[r] for r in STAMP_REFUSALS}
        out.rebased_at = tuple(rebased)
        return out

    def status(self):
        """
        Summarise the guard as a JSON-ready dict.

        Returns
        -------
        dict
            ``stamps_accepted``, ``stamps_refused`` ({reason: count}), ``rebases``,
            ``rebases_backward``, ``rebases_forward``, ``last_stamp_s`` (NaN before the first),
            ``max_future_s``, ``rebase_after``, ``rate`` (:attr:`rate`).

        """
        return {'stamps_accepted': self.n_accepted, 'stamps_refused': dict(self.counts),
                'rebases': self.rebases, 'rebases_backward': self.rebases_backward,
                'rebases_forward': self.rebases_forward,
                'last_stamp_s': self.last if math.isfinite(self.last) else math.nan,
                'max_future_s': self.max_future_s, 'rebase_after': self.rebase_after,
                'rate': self.rate}
