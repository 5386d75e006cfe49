"""Running a batch: serially or on a Dask cluster, with progress, resume and summary."""
import contextlib
from dataclasses import asdict
import json
import math
from pathlib import Path
import sys
import tempfile
import time

from mr_damper_model.identification.batch.archive import discover
from mr_damper_model.identification.batch.damper import _base_row, process_damper
from mr_damper_model.identification.batch.settings import (_one_line, CHUNKS_PER_WORKER,
                                                           SCHEDULER_TIMEOUT_S)
from mr_damper_model.identification.batch.table import (_journal_rows, _write_json, _write_table,
                                                        read_table)


class Progress:
    """
    Progress bar of the batch on a text stream (stderr).

    On a terminal one line rewritten in place; otherwise a line at every tenth of the work.
    """

    def __init__(self, total, stream=None, width=30):
        self.total, self.done, self.errors = total, 0, 0
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(self.stream, 'isatty', lambda: False)())
        self._next = 0

    def update(self, row):
        """Count one finished damper (its row)."""
        self.done += 1
        self.errors += row.get('status') == 'error'
        if self.tty or self.done >= self._next or self.done == self.total:
            self._next = self.done + max(1, self.total // 10)
            self._draw()

    def _draw(self):
        frac = self.done / self.total if self.total else 1.0
        el = time.perf_counter() - self.t0
        rate = self.done / el if el > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else math.nan
        bar = '#' * int(round(frac * self.width))
        text = (f'[{bar:<{self.width}}] {self.done}/{self.total} dampers, {self.errors} '
                f'error(s), {rate:.2f} /s' + (f', {eta:.0f} s left' if self.done < self.total
                                              and math.isfinite(eta) else ''))
        end = '' if self.tty and self.done < self.total else '\n'
        self.stream.write(('\r' if self.tty else '') + text + end)
        self.stream.flush()


def _run_serial(tasks, settings, on_row):
    for task in tasks:
        on_row(process_damper(task, settings))


def process_dampers(tasks, settings):
    """Run :func:`process_damper` on each task in turn; return the rows (one Dask task)."""
    return [process_damper(t, settings) for t in tasks]


def _chunks(tasks, n_workers):
    """Split the tasks into :data:`CHUNKS_PER_WORKER` contiguous groups per worker (sizes +-1)."""
    n = max(1, min(len(tasks), CHUNKS_PER_WORKER * max(1, n_workers)))
    base, extra = divmod(len(tasks), n)
    edges = [0]
    for k in range(n):
        edges.append(edges[-1] + base + (k < extra))
    return [tasks[a:b] for a, b in zip(edges[:-1], edges[1:])]


def _run_dask(tasks, settings, on_row, *, workers, scheduler):
    """Run the tasks on Dask in chunks; a chunk lost with its worker gives error rows."""
    from dask.distributed import as_completed, Client

    def drain(client, n_workers):
        futures = {client.submit(process_dampers, chunk, settings, pure=False,
                                 key=f'mr-damper-{chunk[0].seed}-{k}'): chunk
                   for k, chunk in enumerate(_chunks(tasks, n_workers))}
        for fut in as_completed(futures):
            try:
                rows = fut.result()
            except Exception as exc:
                rows = []
                for t in futures[fut]:
                    row = _base_row(t, settings)
                    row['error'] = _one_line(f'task failed on the cluster: '
                                             f'{type(exc).__name__}: {exc}')
                    rows.append(row)
            for row in rows:
                on_row(row)
            fut.release()

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
        except (OSError, ValueError) as exc:
            raise ValueError(f'cannot reach the Dask scheduler {scheduler} '
                             f'({type(exc).__name__}: {exc})') from None
        with client:
            drain(client, len(client.scheduler_info().get('workers', {})))
        return
    with tempfile.TemporaryDirectory(prefix='mr_damper_dask_') as scratch, \
            local_cluster(workers, scratch) as cluster, Client(cluster) as client:
        drain(client, workers)


#: Dask settings of the batch's own cluster: no HTTP routes on the scheduler and the workers.
#: distributed (2026.8) starts an HTTP server in the scheduler and in every worker whatever the
#: dashboard settings (health, Prometheus metrics, JSON and info pages); with no routes it
#: answers every request with 404.
QUIET_HTTP = {'distributed.scheduler.http.routes': [], 'distributed.worker.http.routes': []}


@contextlib.contextmanager
def local_cluster(workers, scratch):
    """
    Start the batch's ``LocalCluster``: loopback only, no dashboard, no HTTP pages.

    ``workers`` single-threaded worker processes; the scheduler, nannies and workers listen on
    127.0.0.1 only; the dashboards are off and the HTTP servers distributed always starts have
    no routes (:data:`QUIET_HTTP`; the scheduler's on a free port, not 8787), so nothing of the
    cluster is reachable off this machine and nothing is served on it. ``scratch`` is its
    local directory.
    """
    import dask
    import logging
    from dask.distributed import LocalCluster
    with dask.config.set(QUIET_HTTP), LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, host='127.0.0.1',
            dashboard_address='127.0.0.1:0', scheduler_kwargs={'dashboard': False},
            worker_dashboard_address=None, silence_logs=logging.ERROR,
            local_directory=scratch) as cluster:
        yield cluster


def run_batch(root, settings, *, table, per_file=False, pattern=None, workers=0,
              scheduler=None, force=False, progress=None, summary=None, callback=None):
    """
    Identify every damper of an archive; write the table and the JSON summary.

    Parameters
    ----------
    root : str or Path
        Archive (see :func:`discover`).
    settings : BatchSettings
        Model, master and tolerances.
    table : str or Path
        CSV table; rows already in it (same record, files and settings) are kept and their
        dampers skipped unless ``force``.
    per_file, pattern
        See :func:`discover`.
    workers : int
        0: serially in this process; N: a local Dask cluster of N single-threaded worker
        processes on 127.0.0.1.
    scheduler : str, optional
        Address of an existing Dask scheduler (then ``workers`` is not used).
    force : bool
        Redo every damper.
    progress : text stream or False, optional
        Where the progress bar goes (default stderr; False: none).
    summary : str or Path, optional
        JSON summary (default: the table with the suffix ``.json``).
    callback : callable, optional
        ``callback(row)`` with each damper's row as it finishes (in finishing order).

    Returns
    -------
    dict
        The summary (see docs/batch.md).

    """
    table = Path(table)
    summary = Path(summary) if summary is not None else table.with_suffix('.json')
    journal = table.with_name(table.name + '.journal')
    tasks, ignored = discover(root, per_file=per_file, pattern=pattern, seed=settings.seed,
                              exclude=(table, summary, journal,
                                       table.with_name(f'{table.stem}_trend.csv')))
    config = settings.config_hash()
    old = read_table(table) if table.exists() else []
    old_by = {r['record']: r for r in old}
    for r in _journal_rows(journal):         # an interrupted run's finished dampers
        old_by[r['record']] = r
    todo, keep = [], []
    for t in tasks:
        prev = old_by.get(t.record)
        if (not force and prev is not None and prev.get('fingerprint') == t.fingerprint
                and prev.get('config') == config):
            keep.append(prev)
        else:
            todo.append(t)
    current = {t.record for t in tasks}
    history = [r for rec, r in old_by.items() if rec not in current]   # dampers since removed
    new_rows = []
    bar = None if progress is False else Progress(len(todo), progress)
    t0 = time.perf_counter()
    try:
        with open(journal, 'a') as jf:
            def on_row(row):
                new_rows.append(row)
                jf.write(json.dumps(row) + '\n')
                jf.flush()
                if bar is not None:
                    bar.update(row)
                if callback is not None:
                    callback(row)

            if todo and workers == 0 and scheduler is None:
                _run_serial(todo, settings, on_row)
            elif todo:
                _run_dask(todo, settings, on_row, workers=min(workers, len(todo)),
                          scheduler=scheduler)
    finally:
        if journal.exists() and journal.stat().st_size == 0:
            journal.unlink()
    wall = time.perf_counter() - t0
    rows = history + keep + new_rows
    _write_table(table, rows)
    journal.unlink(missing_ok=True)
    out = _summary(rows, settings, root=root, table=table, ignored=ignored,
                   processed=len(new_rows), skipped=len(keep), wall=wall,
                   workers=workers if scheduler is None else None, scheduler=scheduler)
    _write_json(summary, out)
    return out


def _summary(rows, settings, *, root, table, ignored, processed, skipped, wall, workers,
             scheduler):
    counts = {s: sum(r['status'] == s for r in rows)
              for s in ('pass', 'fail', 'error', 'fitted')}
    master = None
    if settings.master is not None:
        env = [{'current_a': i, 'velocity_mps': v, 'rebound_n': reb, 'compression_n': comp}
               for i, row in zip(settings.currents_a, settings.master_envelope)
               for v, (reb, comp) in zip(settings.velocities_mps, row)]
        master = {k: settings.master.get(k) for k in ('source', 'model', 'model_options')}
        master['envelope'] = env
    s = asdict(settings)
    s.pop('master_envelope')
    s.pop('master')
    return {
        'root': str(root), 'table': str(table), 'config': settings.config_hash(),
        'settings': s, 'master': master,
        'dampers': len(rows), 'processed': processed, 'skipped': skipped, 'counts': counts,
        'failed': [{'record': r['record'], 'reason': r['reason']}
                   for r in sorted(rows, key=lambda r: r['record']) if r['status'] == 'fail'],
        'errors': [{'record': r['record'], 'error': r['error']}
                   for r in sorted(rows, key=lambda r: r['record']) if r['status'] == 'error'],
        'ignored': ignored, 'wall_s': wall,
        'dampers_per_s': processed / wall if processed and wall > 0 else None,
        'workers': workers, 'scheduler': scheduler,
    }
