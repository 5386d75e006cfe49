"""Tests of quarter_car_sim.runtime.control_thread: paced steps, timing, death (fake clock)."""
import pytest

from quarter_car_sim.runtime.control_thread import ControlThread
from quarter_car_sim.simulate.live_loop import LoopTiming, Pacer

from fake_clock import FakeClock


def test_steps_are_booked_with_latency_step_time_and_lateness():
    clock = FakeClock()
    # factor 0: as fast as possible (the pacer never sleeps), wake-up times from the fake clock
    pacer = Pacer(1e-3, 0.0, clock=clock)
    timing = LoopTiming(None)
    seen = []

    def step(wall):
        clock.t += 0.0002                # command computed in 0.2 ms
        thread.command_sent()
        clock.t += 0.0003                # then 0.3 ms to advance the car
        seen.append(wall)

    after = []
    thread = ControlThread(step, pacer, timing, clock=clock,
                           after_step=lambda w, lat, late: after.append((w, lat, late)))
    assert thread.run(max_steps=4) is None
    assert thread.steps == 4 and timing.n == 4
    assert seen == pytest.approx([100.0, 100.0005, 100.001, 100.0015])
    st = thread.status()
    assert st['latency']['max_ms'] == pytest.approx(0.2)
    assert st['step']['p50_ms'] == pytest.approx(0.5)
    assert st['period']['n'] == 3 and st['period']['mean_ms'] == pytest.approx(0.5)
    assert st['late_reanchors'] == 0 and st['steps'] == 4
    assert [a[1] for a in after] == pytest.approx([2e-4] * 4)


def test_latency_is_the_whole_step_without_a_mark():
    clock = FakeClock()
    timing = LoopTiming(None)

    def step(wall):
        clock.t += 0.001
    ControlThread(step, Pacer(1e-3, 0.0, clock=clock), timing, clock=clock).run(max_steps=2)
    assert timing.stats()['latency']['p50_ms'] == pytest.approx(1.0)


def test_real_time_pacing_books_lateness_and_reanchors():
    clock = FakeClock(0.0)
    # real time: steps due every 1 ms; the fake clock is already 0.2 s ahead at the first
    # step (no sleep needed), so the pacer is more than max_burst periods behind: re-anchored
    pacer = Pacer(1e-3, 1.0, clock=clock, max_burst=5)
    timing = LoopTiming(1e-3)
    clock.t = 0.2
    thread = ControlThread(lambda wall: None, pacer, timing, clock=clock)
    thread.run(max_steps=1)
    st = thread.status()
    assert st['late_reanchors'] == 1
    assert st['lateness']['max_ms'] == pytest.approx(200.0)


def test_a_failing_step_ends_the_loop_and_says_why():
    clock = FakeClock()
    errors = []

    def step(wall):
        if thread.steps == 2:
            raise RuntimeError('publish failed')
    thread = ControlThread(step, Pacer(1e-3, 0.0, clock=clock), LoopTiming(None),
                           clock=clock, on_error=errors.append)
    assert thread.run() == 'RuntimeError: publish failed'
    assert thread.steps == 2 and not thread.running
    assert errors == ['RuntimeError: publish failed']


def test_stop_ends_the_thread_and_an_error_after_stop_is_not_a_failure():
    clock = FakeClock()
    calls = []

    def step(wall):
        calls.append(wall)
        if len(calls) == 3:
            thread.running = False       # what stop() does from another thread
            raise RuntimeError('publish after shutdown')
    thread = ControlThread(step, Pacer(1e-3, 0.0, clock=clock), LoopTiming(None), clock=clock)
    thread.start()
    thread._thread.join(30.0)            # hang guard: the third step ends the loop itself
    thread.stop(timeout_s=30.0)
    assert not thread.alive() and thread.failed is None and len(calls) == 3


def test_before_first_runs_once_before_the_steps():
    clock = FakeClock()
    order = []
    thread = ControlThread(lambda wall: order.append('step'), Pacer(1e-3, 0.0, clock=clock),
                           LoopTiming(None), clock=clock,
                           before_first=lambda: order.append('wait'))
    thread.run(max_steps=2)
    assert order == ['wait', 'step', 'step']
