"""
Benchmark: the identifier node alone on a replayed 10 kHz DAQ stream (not collected by pytest).

    .venv/bin/python bench/bench_identifier_rate.py [--rate-hz 10000] [--duration 20]
        [--samples-per-message 1,20,50] [--file CSV]

A measured Quiroz rig test (``data/quiroz_mr_damper/``, default the 5 mm / 3 Hz / 0.5 A series)
is resampled to ``--rate-hz`` by linear interpolation and written as a DAQ CSV; ``rig_node``
replays it in a loop at real time into ``identifier_node`` (two processes over DDS on loopback,
a private domain) for ``--duration`` seconds, once per batch size in
``--samples-per-message`` (1 = one DDS message per sample, the layout of the per-sample stream
before batching; 20 and 50: ``DamperSamples`` batches). For each run it prints, from the
nodes' own ``/diagnostics`` and psutil:

- samples received by the identifier, lost (exact, from the batches' stream index and the
  identifier's buffer) and the rig's largest backlog;
- windows fitted per second and valid ones;
- CPU of the identifier (its process and the fit child process together) and of the rig,
  percent of one core, mean over the run (psutil ``cpu_times`` deltas);
- the rig's effective rate (the samples it got out per second: with one sample per message
  the rig itself cannot publish 10 kHz on this machine).

Every figure is from this run on this machine: quote the load printed at the end.
"""
import argparse
import glob
import os
from pathlib import Path
import random
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _default_file():
    for d in (REPO / 'data' / 'quiroz_mr_damper',):
        hits = sorted(glob.glob(str(d / 'quiroz_sine_5mm3Hz_0p5A.csv*')))
        if hits:
            return hits[0]
    raise SystemExit('bench_identifier_rate: no Quiroz file found; give --file CSV')


def resample(path, rate_hz, out):
    """Write ``path`` resampled to ``rate_hz`` (linear interpolation) as a t,x,v,f,i CSV."""
    from mr_damper_model.io.data import DamperData, read_csv, write_csv
    d = read_csv(path)
    t = np.arange(d.t[0], d.t[-1], 1.0 / rate_hz)
    cols = [np.interp(t, d.t, getattr(d, c)) for c in 'xvfi']
    write_csv(out, DamperData(t - t[0], *cols))
    return t.size


class Probe:
    """Last /diagnostics status per name (an rclpy node spun in a thread)."""

    def __init__(self):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from mr_damper_common.messages import health_from_diagnostic
        rclpy.init()
        self.node = rclpy.create_node('bench_identifier_probe')
        self.last = {}
        self._decode = health_from_diagnostic

        def on_diag(msg):
            for st in msg.status:
                self.last[st.name] = self._decode(st).values
        self.node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 100)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        import rclpy
        while not self._stop.is_set():
            rclpy.spin_once(self.node, timeout_sec=0.05)

    def close(self):
        import rclpy
        self._stop.set()
        self._thread.join(5)
        self.node.destroy_node()
        rclpy.try_shutdown()


def cpu_seconds(proc):
    """User + system CPU [s] of a psutil process and its children (0 if gone)."""
    import psutil
    total = 0.0
    try:
        for p in [proc] + proc.children(recursive=True):
            try:
                t = p.cpu_times()
                total += t.user + t.system
            except psutil.NoSuchProcess:
                pass
    except psutil.NoSuchProcess:
        pass
    return total


def run_once(csv, rate_hz, spm, duration, probe, ns):
    """One rig + identifier run; return the figures."""
    import psutil
    common = ['--ros-args', '-r', f'__ns:=/{ns}']
    rig = subprocess.Popen(
        [str(BIN / 'rig_node'), *common, '-p', 'mode:=csv', '-p', f'file:={csv}',
         '-p', 'loop:=true', '-p', 'rate_factor:=1.0', '-p', f'samples_per_message:={spm}',
         '-p', 'wait_for_subscribers:=1', '-p', 'diagnostics_period_s:=0.5'],
        stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    ident = subprocess.Popen(
        [str(BIN / 'identifier_node'), *common, '-p', f'max_rate_hz:={float(rate_hz)}',
         '-p', 'diagnostics_period_s:=0.5', '-p', 'no_sample_timeout_s:=0.0'],
        stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    procs = {'rig': psutil.Process(rig.pid), 'identifier': psutil.Process(ident.pid)}
    name_r, name_i = f'{ns}/mr_damper_rig', f'{ns}/mr_damper_identifier'
    end = time.monotonic() + 60.0
    while time.monotonic() < end and not (probe.last.get(name_r, {}).get('started')):
        time.sleep(0.1)
    time.sleep(2.0)                     # start-up transient (fit process warm, first window)
    c0 = {k: cpu_seconds(p) for k, p in procs.items()}
    s0 = dict(probe.last.get(name_i, {}))
    w0 = time.monotonic()
    time.sleep(duration)
    wall = time.monotonic() - w0
    c1 = {k: cpu_seconds(p) for k, p in procs.items()}
    s1 = dict(probe.last.get(name_i, {}))
    r1 = dict(probe.last.get(name_r, {}))
    rig.terminate()                     # the rig stops first: the identifier drains
    rig.wait(30)
    time.sleep(1.5)
    final = dict(probe.last.get(name_i, {}))
    ident.terminate()
    ident.wait(30)
    return {
        'spm': spm,
        'received': final.get('samples_received', 0),
        'lost': (final.get('stream') or {}).get('lost', 0) + final.get('samples_lost', 0),
        'backlog_max': r1.get('behind_max_samples', 0),
        'windows_per_s': (s1.get('windows_fitted', 0) - s0.get('windows_fitted', 0)) / wall,
        'valid': s1.get('windows_valid', 0),
        'cpu_ident': 100 * (c1['identifier'] - c0['identifier']) / wall,
        'cpu_rig': 100 * (c1['rig'] - c0['rig']) / wall,
        'rate_hz': r1.get('effective_rate_hz', 0.0),
    }


def main(argv=None):
    """Run the benchmark and print the table; return 0."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--rate-hz', type=float, default=10000.0)
    p.add_argument('--duration', type=float, default=20.0)
    p.add_argument('--samples-per-message', default='1,20,50')
    p.add_argument('--file', default=None, help='DAQ CSV to resample (default: a Quiroz file)')
    args = p.parse_args(argv)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(20, 220)))
    with tempfile.TemporaryDirectory() as tmp:
        os.environ.setdefault('ROS_LOG_DIR', tmp)
        csv = Path(tmp) / 'resampled.csv'
        n = resample(args.file or _default_file(), args.rate_hz, csv)
        print(f'bench_identifier_rate: {n} samples at {args.rate_hz:.0f} Hz, looped, '
              f'{args.duration:.0f} s per run, domain {os.environ["ROS_DOMAIN_ID"]}',
              flush=True)
        probe = Probe()
        rows = []
        try:
            for k, spm in enumerate(int(s) for s in args.samples_per_message.split(',')):
                rows.append(run_once(csv, args.rate_hz, spm, args.duration, probe, f'b{k}'))
                r = rows[-1]
                print(f'  samples/message {spm:3d}: done ({r["received"]} received)', flush=True)
        finally:
            probe.close()
    print(f'\n=== identifier alone at {args.rate_hz:.0f} Hz, real time ===')
    print('samples/msg  rig rate Hz  received   lost  rig backlog max  windows/s  valid  '
          'identifier CPU %  rig CPU %')
    for r in rows:
        print(f'{r["spm"]:11d}  {r["rate_hz"]:11.0f}  {r["received"]:8d}  {r["lost"]:5d}  '
              f'{r["backlog_max"]:15d}  {r["windows_per_s"]:9.2f}  {r["valid"]:5d}  '
              f'{r["cpu_ident"]:16.1f}  {r["cpu_rig"]:9.1f}')
    base = rows[0]
    for r in rows[1:]:
        if r['cpu_ident'] > 0:
            print(f'identifier CPU, {base["spm"]} vs {r["spm"]} samples/message: '
                  f'{base["cpu_ident"] / r["cpu_ident"]:.1f}x')
    print(f'load average (1 min) at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores')
    return 0


if __name__ == '__main__':
    sys.exit(main())
