"""
The live identifier's sample buffer: a ring of accepted samples and the windows it hands out.

No ROS, no lock of its own: :class:`~mr_damper_model.live.identifier.LiveIdentifier` holds its
lock around every call (samples arrive in one thread, windows are taken in another).  The ring
holds two windows and three hops (plus ``backlog_windows`` hops); the stamp guard judges each
sample's stamp (order, duplicates, future stamps on the stream's own clock, re-base after a
clock jump); sequence numbers tell which samples a window has handed out and which left the
ring before one did (``samples_lost``).
"""
import math

import numpy as np

from mr_damper_common.stamps import ACCEPTED, REBASED, StampGuard


class SampleRing:
    """
    Ring buffer of samples ``(t, x, v, f, i)`` of one stream, with its stamp guard.

    Parameters
    ----------
    config : LiveConfig
        ``window_s``, ``hop_s``, ``backlog_windows`` and ``max_rate_hz`` size the ring;
        ``max_future_s`` and ``restart_samples`` set the stamp guard.
    counters : dict
        The identifier's counters (``samples_received``, ``samples_accepted``, ``rejected``,
        ``out_of_range``, ``stamp_gaps``, ``stream_restarts``, ``samples_lost``,
        ``windows_due``, ``windows_superseded``, ``windows_overflow``), counted in place.
    on_restart : callable
        Called (no argument) when a stamp starts a new stream; it must call :meth:`restart`.

    Attributes
    ----------
    buf : numpy.ndarray with shape (cap, 5)
        The ring; ``head`` is the next write position, ``count`` the samples held.
    last_t : float
        Newest accepted stamp [s].
    t_origin : float or None
        First stamp of the stream [s].
    next_index : int
        Index m of the next due window end.
    seq, handed : int
        Samples accepted so far (all streams); sequence number of the first sample not yet
        handed out by a window.

    """

    def __init__(self, config, counters, on_restart):
        cfg = config
        # two windows and three hops: room for the samples of superseded windows
        self.cap = int(math.ceil((2 * cfg.window_s + (3 + int(cfg.backlog_windows)) * cfg.hop_s)
                                 * cfg.max_rate_hz)) + 16
        self.buf = np.empty((self.cap, 5))
        self.count = 0
        self.head = 0
        self.last_t = -math.inf
        self.t_origin = None
        self.next_index = 0
        self.stamps = StampGuard(max_future_s=cfg.max_future_s or math.inf,
                                 rebase_after=cfg.restart_samples, stream_clock=True)
        self.seq = 0
        self.handed = 0
        self.counters = counters
        self._on_restart = on_restart

    def restart(self):
        """Start a new stream: the samples not handed out are lost, the ring is empty."""
        self.counters['stream_restarts'] += 1
        self.counters['samples_lost'] += self.seq - self.handed
        self.handed = self.seq
        self.count = 0
        self.head = 0
        self.last_t = -math.inf
        self.t_origin = None
        self.next_index = 0

    def add_one(self, t, x, v, f, i, cfg, now=None, judged=False):
        """
        Offer one sample; return '' if accepted, else the rejection reason (counted).

        ``judged``: its batch passed the future test (no future check of its own).
        """
        c = self.counters
        c['samples_received'] += 1
        if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(v)
                and math.isfinite(f) and math.isfinite(i)):
            c['rejected']['nonfinite'] += 1
            return 'nonfinite'
        # order, duplicates, future (unless judged with its batch), clock jumps
        verdict = self.stamps.check(t, None if judged else now)
        if verdict == REBASED:
            self._on_restart()
        elif verdict != ACCEPTED:
            c['rejected'][verdict] += 1
            return verdict
        # range checks after the stamp checks: a sample is late before it is implausible
        channel = ('force' if abs(f) > cfg.force_limit_n else
                   'velocity' if abs(v) > cfg.velocity_limit_m_s else
                   'displacement' if abs(x) > cfg.displacement_limit_m else
                   'current' if not (cfg.current_limit_min_a <= i
                                     <= cfg.current_limit_max_a) else '')
        if channel:
            c['out_of_range'][channel] += 1
            return channel + '_range'
        if self.t_origin is None:
            self.t_origin = t
        elif t - self.last_t > cfg.max_gap_s:
            # counted once per gap, here: the windows across it may all be superseded
            c['stamp_gaps'] += 1
        row = self.buf[self.head]
        row[0] = t
        row[1] = x
        row[2] = v
        row[3] = f
        row[4] = i
        self.head = (self.head + 1) % self.cap
        if self.count < self.cap:
            self.count += 1
        self.last_t = t
        self.stamps.commit(t, now)
        self.seq += 1
        c['samples_accepted'] += 1
        return ''

    def clean_batch(self, t, x, v, f, i, cfg, now):
        """Tell whether every sample of the batch would be accepted as it is."""
        if not t[0] > self.last_t or not self.stamps.clean(t, now):
            return False
        if t.shape[0] > 1 and not bool(np.all(np.diff(t) > 0.0)):
            return False
        with np.errstate(invalid='ignore'):
            return bool(np.all(np.abs(f) <= cfg.force_limit_n)
                        and np.all(np.abs(v) <= cfg.velocity_limit_m_s)
                        and np.all(np.abs(x) <= cfg.displacement_limit_m)
                        and np.all(i >= cfg.current_limit_min_a)
                        and np.all(i <= cfg.current_limit_max_a)
                        and np.all(np.isfinite(t)))

    def append_batch(self, t, x, v, f, i, cfg, now):
        """Take a clean batch (see :meth:`clean_batch`) with array operations."""
        c = self.counters
        n = t.shape[0]
        c['samples_received'] += n
        if self.t_origin is None:
            self.t_origin = float(t[0])
            steps = np.diff(t)
        else:
            steps = np.diff(t, prepend=self.last_t)
        c['stamp_gaps'] += int(np.count_nonzero(steps > cfg.max_gap_s))
        cap = self.cap
        if n > cap:   # only the newest cap samples can stay (older ones are lost below)
            keep = slice(n - cap, n)
            skipped = n - cap
        else:
            keep, skipped = slice(0, n), 0
        rows = np.column_stack((t[keep], x[keep], v[keep], f[keep], i[keep]))
        if skipped:
            self.seq += skipped   # passed through the buffer at once: never handed out
        m = rows.shape[0]
        first = min(m, cap - self.head)
        self.buf[self.head:self.head + first] = rows[:first]
        if m > first:
            self.buf[:m - first] = rows[first:]
        self.head = (self.head + m) % cap
        self.count = min(self.count + m, cap)
        self.last_t = float(t[-1])
        self.seq += m
        c['samples_accepted'] += n
        self.stamps.take_clean(t, now)

    def next_window(self, cfg):
        """
        Take the due window: ``(rows, k_window, end_s, n_new, first_new_seq, m)`` or None.

        ``rows`` (a copy) are the samples from the older of the window start and the first
        sample not yet handed out up to the window end ``end_s``; the window's own samples
        start at ``rows[k_window]``, the last ``n_new`` are new; ``m`` is the window's index.
        See ``LiveIdentifier.next_window`` for the schedule.
        """
        if self.t_origin is None:
            return None
        first_end = self.t_origin + cfg.window_s
        if self.last_t < first_end + self.next_index * cfg.hop_s:
            return None
        m = int(math.floor((self.last_t - first_end) / cfg.hop_s + 1e-9))
        m = max(m, self.next_index)
        n = self.count
        oldest = self.seq - n
        if cfg.backlog_windows:
            m = self._in_order_index(m, n, cfg.hop_s)
        else:
            self.counters['windows_superseded'] += m - self.next_index
        self.counters['windows_due'] += 1
        self.next_index = m + 1
        end = first_end + m * cfg.hop_s
        if self.handed < oldest:
            self.counters['samples_lost'] += oldest - self.handed
            self.handed = oldest
        idx = (self.head - n + np.arange(n)) % self.cap
        t = self.buf[idx, 0]
        k_end = int(np.searchsorted(t, end + 1e-9, side='right'))
        k_win = int(np.searchsorted(t, end - cfg.window_s + 1e-9, side='right'))
        k_new = min(self.handed - oldest, k_end)
        rows = self.buf[idx[min(k_win, k_new):k_end]]
        self.handed = oldest + k_end
        return rows, max(k_win - k_new, 0), end, k_end - k_new, oldest + k_new, m

    def _in_order_index(self, newest, n, hop_s):
        """Index of the oldest due window whose samples are all still buffered."""
        m = self.next_index
        t_old = self.buf[(self.head - n) % self.cap, 0]
        start = self.t_origin + m * hop_s      # samples after it form window m
        if n == self.cap and t_old > start + 1e-9:
            m_kept = int(math.ceil((t_old - self.t_origin) / hop_s - 1e-9))
            m = min(max(m, m_kept), newest)
            self.counters['windows_overflow'] += m - self.next_index
        return m

    def give_back(self, first_new_seq, n_new, n):
        """Offer the last ``n`` of a window's ``n_new`` new samples again with the next one."""
        self.handed = min(self.handed, first_new_seq + n_new - n)
