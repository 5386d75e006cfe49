"""
Tests of the batch identification (``mr-damper-identify --batch``).

The code under test is mr_damper_model.identification.batch.

Archive: a handful of short generated dampers (kwok-current, i_ref 1 A, three current levels,
a 15 mm / 1.2 Hz sine, 1 % force noise), each the master damper with its viscous and
hysteretic coefficients (c0, c1, alpha0..2) scaled by a known factor. The envelope forces of
those coefficients scale by about the same factor, so with the default 10 % tolerance a scale of
0.97-1.03 passes and 0.7 or 1.35 fails, far from the boundary whatever the noise: the pass /
fail is known. A truncated file and a file with a wrong column name must fail alone.
"""
import csv
import datetime
import json
import os
import socket

import numpy as np
import psutil
import pytest

from mr_damper_model.identification import batch
from mr_damper_model.tools.cli import run as cli_run
from mr_damper_model.io.data import DamperData, write_csv
from mr_damper_model.models import get_model
from mr_damper_model.io.params_file import save_params
from mr_damper_model.models.presets import thesis_kwok_current

MODEL = get_model('kwok-current', i_ref_a=1.0)
_, TRUTH = thesis_kwok_current()
SCALED = ('c0', 'c1', 'alpha0', 'alpha1', 'alpha2')
#: record id -> scale of the master's viscous / hysteretic coefficients
SCALES = {'SN001': 1.0, 'SN002': 1.03, 'SN003': 0.7, 'SN004': 1.35, 'SN005': 0.97}


def scaled(params, scale, names=SCALED):
    return {k: v * scale if k in names else v for k, v in params.items()}


def record(params, seed, *, model=MODEL, levels=(0.0, 0.5, 1.0), rate=500.0, n=600,
           amp=0.015, freq=1.2, noise=0.01):
    t = np.arange(len(levels) * n) / rate
    w = 2 * np.pi * freq
    x = amp * np.sin(w * t)
    v = amp * w * np.cos(w * t)
    i = np.repeat(np.asarray(levels, dtype=float), n)
    f = model.force(model.from_dict(params), x, v, i=i, t=t)
    f = f + noise * np.max(np.abs(f)) * np.random.default_rng(seed).standard_normal(f.size)
    return DamperData(t, x, v, f, i)


@pytest.fixture(scope='module')
def archive(tmp_path_factory):
    base = tmp_path_factory.mktemp('batch')
    root = base / 'archive'
    for k, (name, scale) in enumerate(sorted(SCALES.items())):
        (root / name).mkdir(parents=True)
        write_csv(root / name / 'eol_test.csv', record(scaled(TRUTH, scale), k))
    good = (root / 'SN001' / 'eol_test.csv').read_text()
    (root / 'SN901').mkdir()
    (root / 'SN901' / 'eol_test.csv').write_text(good[:2000])             # cut mid-line
    (root / 'SN902').mkdir()
    (root / 'SN902' / 'eol_test.csv').write_text('t,x,v,force,i\n' + good.split('\n', 1)[1])
    (root / 'notes.txt').write_text('not a damper')
    master = base / 'master.json'
    save_params(master, {'model': 'kwok-current', 'parameters': TRUTH,
                         'model_options': {'i_ref_a': 1.0}, 'current_min_a': 0.0,
                         'current_max_a': 1.0})
    return root, master


def settings_for(master, **kw):
    m = batch.load_master(master)
    return batch.BatchSettings(master=m, currents_a=batch.master_currents(m), **kw)


def rows_by_record(path):
    return {r['record']: r for r in batch.read_table(path)}


def test_force_envelope_is_the_analytic_peak_force():
    # Kwok with k = delta = f0 = 0: F = c v + alpha tanh(beta v), increasing in v, so the
    # largest force of a cycle is at the peak velocity V (a sample of the reference sine)
    p = {'c': 800.0, 'k': 0.0, 'alpha': 400.0, 'beta': 25.0, 'delta': 0.0, 'f0': 0.0}
    vel = (0.02, 0.1)
    env = batch.force_envelope('kwok', None, p, [0.0], vel, 0.01)
    want = np.array([800.0 * V + 400.0 * np.tanh(25.0 * V) for V in vel])
    np.testing.assert_allclose(env[0, :, 0], want, rtol=1e-12)
    np.testing.assert_allclose(env[0, :, 1], -want, rtol=1e-12)
    cols = batch.envelope_columns([0.0], vel)
    assert cols[:2] == ['env_0A_0.02mps_rebound_n', 'env_0A_0.02mps_compression_n']


def test_discover_folders_files_patterns_and_seeds(tmp_path):
    for rel in ('A1/x.csv', 'B2/y.csv', 'loose.csv'):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text('t\n')
    (tmp_path / '.git').mkdir()
    tasks, ignored = batch.discover(tmp_path, seed=3)
    assert [t.record for t in tasks] == ['A1', 'B2'] and ignored == ['.git', 'loose.csv']
    assert [t.serial for t in tasks] == ['A1', 'B2']
    # the seed depends on the base seed and the id only, not on which other dampers exist
    (tmp_path / 'A0').mkdir()
    (tmp_path / 'A0' / 'z.csv').write_text('t\n')
    again, _ = batch.discover(tmp_path, seed=3)
    assert {t.record: t.seed for t in again}['B2'] == tasks[1].seed
    assert batch.discover(tmp_path, seed=4)[0][1].seed != again[1].seed
    # one damper per file: serial and date from the pattern; non-matching names listed
    (tmp_path / 'fleet' / 'SN7').mkdir(parents=True)
    for name in ('SN7_2026-01-05.csv', 'SN7_20260305T0830.csv', 'SN7_1999-13-01.csv',
                 'other.csv'):
        (tmp_path / 'fleet' / 'SN7' / name).write_text('t\n')
    tasks, ignored = batch.discover(tmp_path / 'fleet', per_file=True,
                                    pattern=r'(?P<serial>SN\d+)_(?P<date>[\dT:-]+)\.csv$')
    assert ignored == ['SN7/other.csv']
    assert [(t.serial, t.test_time) for t in tasks] == [
        ('SN7', ''), ('SN7', '2026-01-05T00:00:00'), ('SN7', '2026-03-05T08:30:00')]
    assert 'ISO 8601' in tasks[0].time_error
    with pytest.raises(ValueError, match='not a regular expression'):
        batch.discover(tmp_path, per_file=True, pattern='(')


@pytest.mark.parametrize('n, workers', [(7, 2), (17, 2), (200, 2), (200, 1), (3, 8)])
def test_dampers_go_to_the_cluster_in_chunks_of_every_task_once(n, workers):
    chunks = batch.run._chunks(list(range(n)), workers)
    assert [t for c in chunks for t in c] == list(range(n))
    assert len(chunks) == min(n, batch.settings.CHUNKS_PER_WORKER * workers)
    assert max(map(len, chunks)) - min(map(len, chunks)) <= 1


@pytest.mark.slow
def test_batch_pass_fail_bad_files_and_resume(archive, tmp_path):
    root, master = archive
    s = settings_for(master)
    table = tmp_path / 'batch.csv'
    finished = []
    out = batch.run_batch(root, s, table=table, progress=False, callback=finished.append)
    rows = rows_by_record(table)
    assert len(finished) == 7 and out['processed'] == 7 and out['skipped'] == 0
    for name, scale in SCALES.items():
        want = 'pass' if abs(scale - 1.0) <= 0.05 else 'fail'
        assert rows[name]['status'] == want, (name, rows[name]['reason'])
        assert (float(rows[name]['envelope_worst_ratio']) <= 1.0) == (want == 'pass')
        assert float(rows[name]['nrmse_percent']) < 2.0
    assert 'envelope' in rows['SN003']['reason']
    # the bad files fail alone, each with its problem in the table
    assert rows['SN901']['status'] == rows['SN902']['status'] == 'error'
    assert 'eol_test.csv' in rows['SN901']['error']
    assert 'missing column(s) f' in rows['SN902']['error']
    assert out['counts'] == {'pass': 3, 'fail': 2, 'error': 2, 'fitted': 0}
    assert out['ignored'] == ['notes.txt']
    summary = json.loads(table.with_suffix('.json').read_text())
    assert summary['counts'] == out['counts'] and len(summary['master']['envelope']) == 9
    assert {e['record'] for e in summary['errors']} == {'SN901', 'SN902'}
    # the master's own damper: parameters near the truth (the collinear ones via the force)
    p = {k: float(rows['SN001'][f'p_{k}']) for k in MODEL.param_names}
    env = batch.force_envelope('kwok-current', {'i_ref_a': 1.0}, p, s.currents_a,
                               s.velocities_mps, s.stroke_m)
    np.testing.assert_allclose(env, np.asarray(s.master_envelope), rtol=0.05, atol=5.0)

    # a re-run does nothing and leaves the table as it was
    first = table.read_bytes()
    again = batch.run_batch(root, s, table=table, progress=False)
    assert again['processed'] == 0 and again['skipped'] == 7 and table.read_bytes() == first
    moved = tmp_path / 'elsewhere' / 'master_copy.json'         # the same master elsewhere
    moved.parent.mkdir()
    moved.write_bytes(master.read_bytes())
    assert settings_for(moved).config_hash() == s.config_hash()
    # a changed file is redone, the others are not; --force redoes all
    f = root / 'SN005' / 'eol_test.csv'
    st = f.stat()
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
    redo = []
    batch.run_batch(root, s, table=table, progress=False, callback=redo.append)
    assert [r['record'] for r in redo] == ['SN005']
    before = {r['record']: r for r in csv.DictReader(first.decode().splitlines())}
    after = rows_by_record(table)
    assert after['SN005']['fingerprint'] != before['SN005']['fingerprint']
    for r in (before, after):
        r['SN005'].pop('fingerprint')
    assert after == before          # the same files give the same row
    forced = batch.run_batch(root, s, table=table, progress=False, force=True)
    assert forced['processed'] == 7
    # other tolerances are other settings: every row is redone
    tight = settings_for(master, rel_tol=0.02, abs_tol_n=1.0)
    out = batch.run_batch(root, tight, table=table, progress=False)
    assert out['processed'] == 7 and out['counts']['pass'] < 3


def test_interrupted_run_resumes_from_its_journal(archive, tmp_path):
    root, master = archive
    s = settings_for(master)
    table = tmp_path / 'b.csv'
    full = batch.run_batch(root, s, table=tmp_path / 'full.csv', progress=False)
    assert full['processed'] == 7
    # a run killed after two dampers left their rows in the journal (the last line cut)
    rows = batch.read_table(tmp_path / 'full.csv')[:2]
    (tmp_path / 'b.csv.journal').write_text(
        ''.join(json.dumps(r) + '\n' for r in rows) + '{"record": "SN0')
    done = []
    out = batch.run_batch(root, s, table=table, progress=False, callback=done.append)
    assert out['processed'] == 5 and out['skipped'] == 2
    everything = {r['record'] for r in batch.read_table(tmp_path / 'full.csv')}
    assert sorted(r['record'] for r in done) == sorted(everything - {r['record'] for r in rows})
    assert table.read_bytes() == (tmp_path / 'full.csv').read_bytes()
    assert not (tmp_path / 'b.csv.journal').exists()


def _listening_addresses():
    """Addresses ``(ip, port)`` of the TCP sockets this process and its children listen on."""
    procs = [psutil.Process()] + psutil.Process().children(recursive=True)
    out = []
    for p in procs:
        try:
            conns = p.net_connections(kind='inet')
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        out += [(c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN
                and c.family in (socket.AF_INET, socket.AF_INET6)]
    return out, len(procs) - 1


#: Pages a Dask scheduler or worker serves over HTTP (dashboard, health, Prometheus, JSON, info)
HTTP_PAGES = ('/status', '/health', '/metrics', '/json/counts.json', '/info/main/workers.html')


def _http_pages(addresses):
    """Return ``{(port, page): HTTP status}`` of the pages served on ``addresses``."""
    import http.client
    got = {}
    for ip, port in addresses:
        for page in HTTP_PAGES:
            conn = http.client.HTTPConnection(ip, port, timeout=10.0)   # a hang guard
            try:
                conn.request('GET', page)
                got[(port, page)] = conn.getresponse().status
            except (OSError, http.client.HTTPException):
                break                                   # not an HTTP server (a Dask comm)
            finally:
                conn.close()
    return got


@pytest.mark.slow
def test_workers_and_a_scheduler_give_the_serial_table_on_loopback_only(
        archive, tmp_path, capsys):
    from dask.distributed import LocalCluster
    root, master = archive
    s = settings_for(master)
    serial = tmp_path / 'serial.csv'
    batch.run_batch(root, s, table=serial, progress=False, workers=0)
    seen = []

    def look(row):
        if not seen:
            addresses, children = _listening_addresses()
            seen.append((addresses, children, _http_pages(addresses)))

    # the batch's own LocalCluster: two worker processes, every socket on loopback, and no
    # page served (distributed's HTTP servers run with no routes: 404 for every page)
    two = tmp_path / 'two.csv'
    out = batch.run_batch(root, s, table=two, progress=False, workers=2, callback=look)
    assert out['workers'] == 2
    addresses, children, pages = seen[0]
    assert children >= 2 and addresses, 'no cluster processes or sockets seen'
    assert {ip for ip, _ in addresses} == {'127.0.0.1'}, addresses
    assert 8787 not in {port for _, port in addresses}
    assert len({port for port, _ in pages}) >= 3, pages     # the scheduler's and 2 workers'
    assert set(pages.values()) == {404}, pages
    # the command line on an existing scheduler with one worker
    one = tmp_path / 'one.csv'
    with LocalCluster(n_workers=1, threads_per_worker=1, host='127.0.0.1',
                      dashboard_address=None, worker_dashboard_address=None,
                      local_directory=str(tmp_path / 'scratch')) as cluster:
        assert cli_run(['--batch', str(root), '--master', str(master), '--scheduler',
                        cluster.scheduler_address, '--table', str(one)]) == 0
    io = capsys.readouterr()
    assert '7/7 dampers' in io.err and '3 pass, 2 fail, 2 error' in io.out
    summary = json.loads(one.with_suffix('.json').read_text())
    assert summary['scheduler'] == cluster.scheduler_address and summary['workers'] is None
    assert serial.read_bytes() == two.read_bytes() == one.read_bytes()


@pytest.mark.slow
def test_trend_recovers_a_known_drift(tmp_path, capsys):
    # serial AG1 ages: its viscous c and hysteretic alpha fall linearly, 10 % and 15 % over
    # 120 days; serial NEW1 does not change. Kwok model, one current, thesis cam (30 mm,
    # 1.1 Hz), 0.3 % force noise: c comes out within about 1.4 N s/m (s.d. over seeds), so the
    # slope of 5 records 30 days apart within about 2 % of the drift of c (80 N s/m); the
    # tolerance below is 10 %.
    kwok = get_model('kwok')
    p0 = {'c': 800.0, 'k': 150.0, 'alpha': 400.0, 'beta': 25.0, 'delta': 0.4, 'f0': 6.0}
    days = np.array([0.0, 30.0, 60.0, 90.0, 120.0])
    start = datetime.date(2026, 1, 10)
    root = tmp_path / 'fleet'
    root.mkdir()
    truth_env = []
    for k, d in enumerate(days):
        date = (start + datetime.timedelta(days=int(d))).isoformat()
        p = dict(p0, c=800.0 * (1 - 0.10 * d / 120), alpha=400.0 * (1 - 0.15 * d / 120))
        kw = dict(model=kwok, levels=(0.0,), n=1500, amp=0.03, freq=1.1, noise=0.003)
        write_csv(root / f'AG1_{date}.csv', record(p, 10 + k, **kw))
        write_csv(root / f'NEW1_{date}.csv', record(p0, 20 + k, **kw))
        truth_env.append(batch.force_envelope('kwok', None, p, [0.0], [0.05], 0.01).ravel())
    table = tmp_path / 'fleet.csv'
    code = cli_run(['--batch', str(root), '--serial-pattern',
                    r'(?P<serial>[A-Z]+\d)_(?P<date>\d{4}-\d\d-\d\d)\.csv', '--model', 'kwok',
                    '--workers', '0', '--currents', '0', '--velocities', '0.05',
                    '--table', str(table), '--trend'])
    assert code == 0, capsys.readouterr().err
    with open(tmp_path / 'fleet_trend.csv', newline='') as fh:
        tr = {(r['serial'], r['quantity']): r for r in csv.DictReader(fh)}
    for name, per_day in (('c', -800.0 * 0.10 / 120), ('alpha', -400.0 * 0.15 / 120)):
        got = float(tr[('AG1', f'p_{name}')]['slope_per_day'])
        assert got == pytest.approx(per_day, rel=0.1), name
        assert abs(float(tr[('NEW1', f'p_{name}')]['change_percent'])) < 2.0
        assert tr[('AG1', f'p_{name}')]['records'] == '5'
    env_drift = np.polyfit(days, np.array(truth_env), 1)[0] * 120.0     # rebound, compression
    for side, want in zip(('rebound', 'compression'), env_drift):
        got = float(tr[('AG1', f'env_0A_0.05mps_{side}_n')]['change'])
        assert got == pytest.approx(want, rel=0.1), side
        assert abs(float(tr[('NEW1', f'env_0A_0.05mps_{side}_n')]['change'])) < 0.1 * \
            abs(want)
    assert (tmp_path / 'fleet_trend.png').stat().st_size > 10000
    assert 'trend: 2 serial(s)' in capsys.readouterr().out


@pytest.mark.parametrize('extra, message', [
    (['a.csv'], 'no FILE arguments'),
    (['--serial-pattern', 'x', '--folder-pattern', 'y'], 'exclude each other'),
    (['--per-current'], '--per-current cannot be used with --batch'),
    (['--master', 'missing.json'], 'cannot read parameter file'),
    (['--workers', '2', '--scheduler', 'tcp://127.0.0.1:1'], 'exclude each other'),
    (['--param-range', 'c0=5:1'], 'NAME=LO:HI'),
])
def test_batch_usage_errors(tmp_path, capsys, extra, message):
    assert cli_run(['--batch', str(tmp_path)] + extra) == 2
    assert message in capsys.readouterr().err


def test_without_files_or_batch_the_tool_says_what_is_missing(capsys):
    assert cli_run([]) == 2
    assert 'required: FILE' in capsys.readouterr().err


def test_params_files_of_the_table_load_through_params_file(tmp_path):
    # each damper's end-of-line record as a parameter file: what a vehicle controller loads
    from mr_damper_model.identification.batch import row_params, write_params_files
    from mr_damper_model.io.params_file import load_params
    from mr_damper_model.models import get_model
    names = get_model('kwok-current').param_names
    base = {'model': 'kwok-current', 'current_min_a': '0.0', 'current_max_a': '1.0',
            'nrmse_percent': '2.5', 'seed': '7', 'reason': '', 'test_time': ''}
    rows = [dict(base, record='a/1', serial='SN1', status='pass',
                 **{f'p_{n}': repr(float(k + 1)) for k, n in enumerate(names)}),
            dict(base, record='b', serial='SN2', status='fail', reason='envelope: 3 of 9',
                 **{f'p_{n}': '2.0' for n in names}),
            dict(base, record='c', serial='SN3', status='error', model='', error='truncated'),
            dict(base, record='a/0', serial='SN1', status='pass', test_time='2026-01-01',
                 **{f'p_{n}': '9.0' for n in names})]
    written = write_params_files(rows, tmp_path)
    assert sorted(written) == ['SN1', 'SN2']             # the error row has no model
    one = load_params(written['SN1'], model='kwok-current')
    # SN1 tested twice: the newer record (by test time) is the damper's
    assert one.parameters == {n: 9.0 for n in names}
    assert one.valid and one.model_options == {'i_ref_a': 2.0}
    assert (one.current_min_a, one.current_max_a) == (0.0, 1.0)
    assert one.metrics['nrmse_percent'] == 2.5 and 'record a/0' in one.source
    two = load_params(written['SN2'])
    assert two.valid is False and 'envelope: 3 of 9' in two.source
    master = {'model': 'kwok-current', 'model_options': {'i_ref_a': 1.0}}
    assert row_params(rows[0], master)['model_options'] == {'i_ref_a': 1.0}
    with pytest.raises(ValueError, match='no model'):
        row_params(rows[2])
