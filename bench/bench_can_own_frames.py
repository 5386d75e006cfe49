#!/usr/bin/env python3
"""
The CPU a bus reader spends per sensor cycle with and without its own frames (udp_loopback).

On ``udp_loopback`` every process of the bus used to receive every frame it sent and throw it
away in Python; the bus now drops them in the kernel, as socketcan does
(``mr_damper_can.bus``: ``receive_own_messages=False``). This bench runs the vehicle suite's
traffic between two processes on a bus of its own, in rounds that alternate the two settings:

- ``car``: every 2 ms (its clock) the three chassis sensor frames, every fifth cycle the four
  driver status frames; its reader thread takes what comes (the commands);
- ``computer``: its reader thread answers the third sensor frame of each cycle with one command
  frame at once, as the vehicle computer's loop does.

Per round and process it prints the reader thread's CPU time per cycle (``time.thread_time``:
the frames' receive path, python-can's ``recv`` and what comes with each wake-up) and the
frames it received per cycle, then the medians of the rounds per setting and their ratio.
No estimator, law or decoding runs: this is the bus's share only.

Usage::

    .venv/bin/python bench/bench_can_own_frames.py [--rounds 3] [--seconds 5] [--port 47311]
"""
import argparse
import multiprocessing as mp
import os
import statistics
import sys
import time

CYCLE_S = 0.002
SENSOR_IDS = (0x200, 0x201, 0x202)
STATUS_IDS = (0x120, 0x121, 0x122, 0x123)
COMMAND_ID = 0x100
STATUS_EVERY = 5


def _reader(bus, stop, answer, out):
    """Receive until ``stop``; answer the last sensor frame of a cycle when ``answer``."""
    import can
    cpu0, n = time.thread_time(), 0
    while not stop.is_set():
        msg = bus.recv(0.05)
        if msg is None:
            continue
        n += 1
        if answer and msg.arbitration_id == SENSOR_IDS[-1]:
            bus.send(can.Message(arbitration_id=COMMAND_ID, data=bytes(8),
                                 is_extended_id=False))
    out['cpu_s'], out['frames'] = time.thread_time() - cpu0, n


def _side(role, channel, own, seconds, queue):
    """One process of the bus: ``car`` (sends the cycles) or ``computer`` (answers them)."""
    import threading

    import can
    from mr_damper_can.bus import make_bus
    bus = make_bus('udp_loopback', channel, receive_own_messages=own)
    stop, out = threading.Event(), {}
    reader = threading.Thread(target=_reader, args=(bus, stop, role == 'computer', out))
    reader.start()
    cycles = 0
    if role == 'car':
        time.sleep(0.5)                       # the computer's socket is open by then
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            for fid in SENSOR_IDS:
                bus.send(can.Message(arbitration_id=fid, data=bytes(8), is_extended_id=False))
            if cycles % STATUS_EVERY == 0:
                for fid in STATUS_IDS:
                    bus.send(can.Message(arbitration_id=fid, data=bytes(5),
                                         is_extended_id=False))
            cycles += 1
            time.sleep(max(0.0, t0 + cycles * CYCLE_S - time.monotonic()))
        time.sleep(0.2)
    else:
        time.sleep(seconds + 1.0)
    stop.set()
    reader.join()
    bus.shutdown()
    queue.put((role, cycles, out['cpu_s'], out['frames'], bus.own_frames_filtered))


def one_round(own, seconds, port):
    """Run both processes once; return ``{role: (cpu_s, frames)}`` and the car's cycles."""
    ctx = mp.get_context('spawn')
    queue = ctx.Queue()
    channel = f'239.74.163.2:{port}'
    procs = [ctx.Process(target=_side, args=(role, channel, own, seconds, queue))
             for role in ('computer', 'car')]
    for p in procs:
        p.start()
    got = {}
    for _ in procs:
        role, cycles, cpu_s, frames, filtered = queue.get(timeout=seconds + 120.0)
        got[role] = (cpu_s, frames, filtered)
        if role == 'car':
            got['cycles'] = cycles
    for p in procs:
        p.join()
    return got


def main(argv=None):
    """Run the rounds; print each and the medians per setting."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--rounds', type=int, default=3)
    ap.add_argument('--seconds', type=float, default=5.0)
    ap.add_argument('--port', type=int, default=47311)
    args = ap.parse_args(argv)
    print(f'udp_loopback own frames: {args.rounds} rounds per setting of {args.seconds:g} s, '
          f'cycle {CYCLE_S * 1e3:g} ms; load {os.getloadavg()[0]:.2f}; CPUs '
          f'{sorted(os.sched_getaffinity(0))}')
    per = {False: {'car': [], 'computer': []}, True: {'car': [], 'computer': []}}
    for k in range(args.rounds):
        for own in (True, False):
            got = one_round(own, args.seconds, args.port + 2 * k + int(own))
            cycles = got['cycles']
            line = []
            for role in ('car', 'computer'):
                cpu_s, frames, filtered = got[role]
                per[own][role].append(cpu_s / cycles)
                line.append(f'{role} {cpu_s / cycles * 1e6:6.1f} us/cycle, '
                            f'{frames / cycles:.2f} frames/cycle (filtered {filtered})')
            print(f'round {k + 1}, own frames {"received" if own else "dropped "}: '
                  + '; '.join(line))
    print('median of the rounds, reader CPU per cycle:')
    for role in ('car', 'computer'):
        a = statistics.median(per[True][role])
        b = statistics.median(per[False][role])
        print(f'  {role:8s} own received {a * 1e6:6.1f} us, dropped {b * 1e6:6.1f} us: '
              f'{a / b:.2f}x')
    print(f'load at the end {os.getloadavg()[0]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
