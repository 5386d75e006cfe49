#!/usr/bin/env python3
"""
What the vehicle computer's 1 Hz ``/diagnostics`` status costs to build, three ways (issue 34).

``vehicle_computer_node`` builds its status (the bridge, the filter, the controller, the loop:
over three hundred key-values) once a second in its executor's thread, beside the bus reader
that runs the control path. Python code there holds the GIL the reader needs after each frame,
so every millisecond of it is one the reader may wait for.

The status of one :class:`~semi_active_control.runtime.VehicleLoop` after ``--cycles`` recorded
bus cycles (the bridge's too, as the node's) is written into a ``DiagnosticStatus`` three ways,
interleaved, in one run:

1. ``json, new``: every value's text through ``json.dumps`` (the status's way before
   1 Dec 2026) and a new ``KeyValue`` message per entry;
2. ``direct, new``: :func:`mr_damper_common.health.value_text` (plain ints, floats, bools and
   None written directly, as JSON would) and a new ``KeyValue`` per entry;
3. ``direct, reused``: as 2 with the last status's ``KeyValue`` messages reused
   (``diagnostic_status_msg(..., key_values=...)``, what ``DiagnosticsPublisher`` does now).

Each way's time includes the status dict (``VehicleLoop.status`` and ``VehicleBridge.status``,
also printed alone). The three must give the same key-values (checked). Prints p50 and p99 [ms]
per way and the p50 ratios to the first. Pin it to a core (``taskset -c 1``).

Usage::

    .venv/bin/python bench/bench_diagnostics_status.py [--cycles 2000] [--repeats 300]
"""
import argparse
import json
import math
import os
from pathlib import Path
import statistics
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_vehicle_cycle import CYCLE_S, make_loop, sensor_cycles  # noqa: E402  (same cycles)
from mr_damper_common.health import finite_or_none, non_finite_text  # noqa: E402

WAYS = ('json, new', 'direct, new', 'direct, reused')


def json_text(value):
    """Return a value's text with JSON for every non-string value (the way before)."""
    if isinstance(value, str):
        return value
    if hasattr(value, 'tolist'):
        value = value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return non_finite_text(value)
    return json.dumps(finite_or_none(value))


def json_status_msg(name, health):
    """Return the ``DiagnosticStatus`` of ``health`` with every value's text JSON's."""
    from mr_damper_common import health as module
    from mr_damper_common.messages.diagnostics import diagnostic_status_msg
    direct = module.value_text
    module.value_text = json_text           # flatten's value writer, for this status only
    try:
        return diagnostic_status_msg(name, health)
    finally:
        module.value_text = direct


def status_source(n_cycles):
    """Return ``status()``: the node's status dict after ``n_cycles`` recorded cycles."""
    from semi_active_control.runtime import VehicleLoop
    acc, travel = sensor_cycles(n_cycles)
    estimator, controller, send = make_loop()
    controller.configure(0.0)
    loop = VehicleLoop(estimator, controller, send)
    loop.activate(0.0)
    for k in range(n_cycles):
        t = (k + 1) * CYCLE_S
        loop.cycle(k + 1, t, acc[k], travel[k], t + 1e-4)
    bridge = send.__self__
    t_now = n_cycles * CYCLE_S

    def status():
        st = loop.status(t_now)
        st['bridge'] = bridge.status()
        return st
    return status


def main(argv=None):
    """Run the bench; print per way the p50 / p99 [ms] and the p50 ratios to the first."""
    from mr_damper_common.health import Health, OK
    from mr_damper_common.messages.diagnostics import diagnostic_status_msg
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--cycles', type=int, default=2000, help='recorded cycles before the status')
    ap.add_argument('--repeats', type=int, default=300, help='statuses per way')
    ap.add_argument('--json', help='write the figures to this file')
    args = ap.parse_args(argv)
    status = status_source(args.cycles)
    reused = {}
    ways = {
        WAYS[0]: lambda: json_status_msg('vehicle_computer', Health(OK, 'ok', status())),
        WAYS[1]: lambda: diagnostic_status_msg('vehicle_computer', Health(OK, 'ok', status())),
        WAYS[2]: lambda: diagnostic_status_msg('vehicle_computer', Health(OK, 'ok', status()),
                                               key_values=reused),
    }
    one = Health(OK, 'ok', status())
    texts = [[(kv.key, kv.value) for kv in msg.values] for msg in (
        json_status_msg('v', one), diagnostic_status_msg('v', one),
        diagnostic_status_msg('v', one, key_values={}))]
    if not (texts[0] == texts[1] == texts[2]):
        raise SystemExit('the ways wrote different key-values')
    print(f'diagnostics status: {len(texts[0])} key-values after {args.cycles} cycles, '
          f'{args.repeats} statuses per way; load {os.getloadavg()[0]:.2f}; '
          f'CPUs {sorted(os.sched_getaffinity(0))}; {sys.version.split()[0]}', flush=True)
    times = {way: [] for way in ('status dict',) + WAYS}
    for _ in range(args.repeats):           # interleaved: the machine's drift hits all alike
        t0 = time.perf_counter()
        status()
        times['status dict'].append(time.perf_counter() - t0)
        for way, build in ways.items():
            t0 = time.perf_counter()
            build()
            times[way].append(time.perf_counter() - t0)
    out = {'key_values': len(texts[0]), 'cycles': args.cycles, 'repeats': args.repeats,
           'ways': {}}
    for way, t in times.items():
        t = sorted(t)
        out['ways'][way] = {'p50_ms': 1e3 * statistics.median(t),
                            'p99_ms': 1e3 * t[min(len(t) - 1, int(0.99 * len(t)))]}
    ref = out['ways'][WAYS[0]]['p50_ms']
    print(f'\n{"way":16s} {"p50 [ms]":>9s} {"p99 [ms]":>9s}   p50 / "{WAYS[0]}"')
    for way, fig in out['ways'].items():
        print(f'{way:16s} {fig["p50_ms"]:9.3f} {fig["p99_ms"]:9.3f}   '
              f'{fig["p50_ms"] / ref:.2f}')
    print(f'"{WAYS[0]}" / "{WAYS[2]}" p50: {ref / out["ways"][WAYS[2]]["p50_ms"]:.2f}x')
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
