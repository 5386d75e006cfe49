"""
A node whose depth-1 reader is flooded while it takes its events keeps going (issue 32, sec. 1).

On this Fast DDS (3.2.3, rmw_fastrtps_cpp 9.3.3) a subscription with its MESSAGE_LOST event
armed can freeze its node for good: the take of the event and the receive thread reporting a
lost sample lock the event's and the reader's mutexes in opposite orders (ros2/rmw_fastrtps#890,
regression test ros2/rmw_implementation#278). The suite arms it nowhere now and counts lost
messages from their own sequence numbers. ``flood_take.py`` builds the upstream test's scenario
with ``DropCounter.subscribe`` on the suite's executor; here it must

- keep its take loop going: every progress line further on than the last, ``done`` reached,
  exit 0 (the guard is a hang guard only: a frozen loop prints nothing more until killed);
- have lost batches (else the scenario did not happen) and count every one of them: each batch
  numbered from the first to the last one taken was either taken or counted lost.

On the old code (the event armed: ``flood_take.py --arm-message-lost``) runs freeze at a random
moment; ``bench/bench_message_lost_hang.py`` counts them.
"""
import pytest

from integration.flood_take import run_take

#: take-loop iterations of a run (a few seconds on an idle machine)
ITERATIONS = 1000


@pytest.mark.integration
@pytest.mark.parametrize('options', [[], ['--reliable']], ids=['best_effort', 'reliable'])
def test_flooded_reader_keeps_taking_and_counts_every_lost_batch(options):
    run = run_take(ITERATIONS, *options)
    assert not run.hung, f'take loop froze after: {run.lines[-3:]}'
    assert run.returncode == 0, run.lines[-20:]
    progress, done = run.counts('progress'), run.counts('done')
    assert len(done) == 1, run.lines[-20:]
    steps = progress + done
    assert all(b[0] > a[0] and b[1] >= a[1] for a, b in zip(steps, steps[1:])), steps
    it, taken, lost, span = done[0]
    assert it >= ITERATIONS and taken > 0 and lost > 0
    assert taken + lost == span, done
