"""
The hypervisor's steal time during a bench run, and the deadline misses of the seconds without it.

On a virtual machine the hypervisor now and then runs something else (another guest, its own
work) on the physical core under a vCPU that has work: the guest kernel counts that time as
*steal* per CPU in ``/proc/stat`` (8th value, in clock ticks of ``USER_HZ``). No code in the
guest runs meanwhile, so a real-time loop there misses every deadline that falls in a stolen
stretch of a few milliseconds, whatever its own speed.

:class:`StealSampler` samples every CPU's steal count in a thread while a run goes on.
:func:`deadline_counts` reads the vehicle controller's cumulative deadline counts from the
``/diagnostics`` statuses of a suite recording (one a second). :func:`quiet_split` then splits
the run's status intervals into those during which no CPU lost a tick to the hypervisor and the
others, with the cycles and misses of each: what the vehicle computer does on a quiet machine,
beside what the platform cost it.

Used by ``bench/bench_vehicle.py``.
"""
import bisect
import os
from pathlib import Path
import threading
import time

#: Seconds per ``/proc/stat`` clock tick (``USER_HZ``).
TICK_S = 1.0 / os.sysconf('SC_CLK_TCK')


def steal_ticks(text=None):
    """
    Return ``{cpu: ticks}``: each CPU's steal time so far, from ``/proc/stat``.

    Parameters
    ----------
    text : str, optional
        The file's text (default: read it now).

    """
    text = Path('/proc/stat').read_text() if text is None else text
    out = {}
    for line in text.splitlines():
        f = line.split()
        if len(f) > 8 and f[0].startswith('cpu') and f[0][3:].isdigit():
            out[int(f[0][3:])] = int(f[8])
    return out


class StealSampler:
    """
    Sample every CPU's steal ticks every ``period_s`` in a thread, as a context manager.

    ``samples`` holds ``(time.time(), {cpu: ticks})``, the first taken on entry and the last on
    exit.
    """

    def __init__(self, period_s=0.2, read=steal_ticks):
        self.period_s = float(period_s)
        self._read = read
        self.samples = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='steal sampler', daemon=True)

    def _sample(self):
        self.samples.append((time.time(), self._read()))

    def _run(self):
        while not self._stop.wait(self.period_s):
            self._sample()

    def __enter__(self):
        self._sample()
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._sample()
        return False

    def shares(self):
        """Return ``{cpu: share}``: each CPU's steal over the sampled span, as a share of it."""
        if len(self.samples) < 2:
            return {}
        (t0, a), (t1, b) = self.samples[0], self.samples[-1]
        span = max(t1 - t0, 1e-9)
        return {cpu: (b[cpu] - a.get(cpu, 0)) * TICK_S / span for cpu in sorted(b)}


def deadline_counts(mcap):
    """
    Return ``[(t_s, cycles, misses)]``: the vehicle controller's deadline counts per status.

    ``t_s`` is the status's stamp (epoch [s]); ``cycles`` and ``misses`` are its deadline
    supervision's cumulative ``cycles`` and ``deadline_misses`` (either layout of the vehicle
    computer), read from the ``/diagnostics`` statuses recorded in the suite's ``mcap`` file.
    """
    from mr_damper_bringup.topics import decode_status
    from mr_damper_bringup.vehicle_suite import chain_statuses, COMPUTER, CONTROLLER
    from mr_damper_common.messages.header import stamp_to_seconds
    from mr_damper_common.recording.mcap_scan import McapScan
    from mr_damper_model.io.bag_types import suite_typestore
    typestore = suite_typestore()
    reader = McapScan(mcap)
    out = []
    for _, msgtype, _, raw in reader.messages({'/diagnostics'}):
        msg = reader.deserialize(raw, msgtype, typestore)
        statuses = decode_status('diagnostics', msg)
        if COMPUTER not in statuses and CONTROLLER not in statuses:
            continue
        deadline = chain_statuses(statuses)[2].get('deadline') or {}
        cycles, misses = deadline.get('cycles'), deadline.get('deadline_misses')
        if isinstance(cycles, int) and isinstance(misses, int):
            out.append((stamp_to_seconds(msg.header.stamp), cycles, misses))
    return sorted(out)


def quiet_split(counts, samples):
    """
    Split the status intervals by the hypervisor's steal in them.

    An interval between two statuses is *quiet* when no CPU's steal count rose from the last
    sample at or before its start to the first sample at or after its end (a tick is 10 ms:
    a shorter steal may still hide in a quiet one).

    Parameters
    ----------
    counts : list of (t_s, cycles, misses)
        :func:`deadline_counts`.
    samples : list of (t_s, {cpu: ticks})
        :attr:`StealSampler.samples`.

    Returns
    -------
    dict
        ``quiet`` and ``stolen``, each ``intervals``, ``cycles``, ``misses`` and ``on_time``
        (the share of its cycles not missed, None without cycles); ``unsampled``: intervals
        outside the samples.

    """
    out = {side: {'intervals': 0, 'cycles': 0, 'misses': 0} for side in ('quiet', 'stolen')}
    out['unsampled'] = 0
    times = [t for t, _ in samples]
    totals = [sum(ticks.values()) for _, ticks in samples]
    for (ta, ca, ma), (tb, cb, mb) in zip(counts, counts[1:]):
        i = bisect.bisect_right(times, ta) - 1      # the last sample at or before ta
        j = bisect.bisect_left(times, tb)           # the first at or after tb
        if i < 0 or j >= len(times) or cb < ca or mb < ma:
            out['unsampled'] += 1
            continue
        side = out['quiet' if totals[j] == totals[i] else 'stolen']
        side['intervals'] += 1
        side['cycles'] += cb - ca
        side['misses'] += mb - ma
    for side in ('quiet', 'stolen'):
        d = out[side]
        d['on_time'] = 1.0 - d['misses'] / d['cycles'] if d['cycles'] else None
    return out
