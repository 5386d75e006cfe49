"""
Benchmark: ``mr-damper-record`` against the simulated rig at 1, 2 and 4 kHz (not a test).

    .venv/bin/python bench/bench_record.py [--seconds 20] [--rates 1000 2000 4000]

For each measurement rate: ``rig_node`` (sim, ``duration_s`` = ``--seconds`` of samples,
``wait_for_subscribers`` 1) publishes into ``mr-damper-record`` (every suite topic, the suite's
QoS), in a private domain on loopback. Once the rig has ended by itself the recorder is stopped
with SIGINT (it drains, then closes the file). Read back from the MCAP (rosbags): measurements
recorded, stamp gaps, the rig's final ``samples_published`` (its last status, recorded too), the
file size; psutil gives the recorder's CPU (share of one core) and peak RSS. Targets: nothing
lost at every rate; flat memory.

Alternative in the same run: the same rates with ``--only measurement`` (one subscription), to
show what the other topics cost.
"""
import argparse
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import tempfile
import time

import psutil

BIN = Path(sys.executable).parent


def _env(domain):
    return dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', ROS_DOMAIN_ID=str(domain),
                PYTHONUNBUFFERED='1')


def run_one(rate_hz, seconds, only, work, domain):
    """Record one rig run; return a dict of figures."""
    from mr_damper_bringup.report import read_recording
    out = Path(work) / f'rec_{rate_hz}_{"meas" if only else "all"}.mcap'
    env = _env(domain)
    rec_cmd = [str(BIN / 'mr-damper-record'), '--out', str(out)]
    if only:
        rec_cmd += ['--only', 'measurement', '--only', 'diagnostics']
    rec = subprocess.Popen(rec_cmd, env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, start_new_session=True)
    rig = subprocess.Popen([str(BIN / 'rig_node'), '--ros-args', '-p', 'mode:=sim',
                            '-p', f'rate_hz:={float(rate_hz)}', '-p', f'duration_s:={seconds:.1f}',
                            '-p', 'wait_for_subscribers:=1', '-p', 'diagnostics_period_s:=0.2'],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           start_new_session=True)
    p = psutil.Process(rec.pid)
    p.cpu_percent(None)
    cpu, rss, t0 = [], 0.0, time.monotonic()
    while rig.poll() is None and time.monotonic() - t0 < seconds + 60:
        time.sleep(1.0)
        cpu.append(p.cpu_percent(None))
        rss = max(rss, p.memory_info().rss / 2 ** 20)
    if rig.poll() is None:
        rig.send_signal(signal.SIGINT)
        rig.wait(15)
    time.sleep(1.0)                       # the rig's last status reaches the recorder
    rec.send_signal(signal.SIGINT)
    rec.wait(60)
    with tempfile.TemporaryDirectory() as tmp:
        r = read_recording(out, tmp)
    published = (r['status'].get('rig') or {}).get('samples_published')
    busy = sorted(cpu)[len(cpu) // 2] if cpu else float('nan')
    return {'rate_hz': rate_hz, 'topics': 'measurement' if only else 'all',
            'recorded': r['measurements_received'], 'gaps': r['measurement_gaps'],
            'published': published, 'cpu_median_percent': busy, 'rss_peak_mb': rss,
            'file_mb': out.stat().st_size / 2 ** 20, 'rig_rc': rig.returncode,
            'rec_rc': rec.returncode}


def main(argv=None):
    """Run every rate with all topics and with the measurement alone; print the table."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seconds', type=float, default=20.0, help='rig samples per run [s]')
    ap.add_argument('--rates', type=int, nargs='+', default=[1000, 2000, 4000])
    args = ap.parse_args(argv)
    print(f'bench_record: load at start {os.getloadavg()}, {os.cpu_count()} CPUs', flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for rate in args.rates:
            for only in (False, True):
                rows.append(run_one(rate, args.seconds, only, work, random.randint(20, 220)))
                print(rows[-1], flush=True)
    print(f'\n{"rate Hz":>8s} {"topics":>12s} {"published":>10s} {"recorded":>9s} {"lost":>5s} '
          f'{"gaps":>5s} {"CPU %":>6s} {"RSS MB":>7s} {"file MB":>8s}')
    for r in rows:
        lost = None if r['published'] is None else r['published'] - r['recorded']
        print(f'{r["rate_hz"]:8d} {r["topics"]:>12s} {str(r["published"]):>10s} '
              f'{r["recorded"]:9d} {str(lost):>5s} {r["gaps"]:5d} '
              f'{r["cpu_median_percent"]:6.1f} {r["rss_peak_mb"]:7.1f} {r["file_mb"]:8.2f}')
    print(f'load at end {os.getloadavg()}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
