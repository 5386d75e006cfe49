"""
fifo_on_first_call: the calling thread's policy set once, before the callback; refusals said.

freeze_heap: the heap there is leaves the collector's passes; objects made later do not.
"""
import gc
import os
import threading
import weakref

import pytest

from mr_damper_common.scheduling import fifo_on_first_call, freeze_heap


def _policy():
    return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority


def test_the_first_callers_thread_goes_fifo_before_the_callback_and_only_it():
    seen, errors = [], []
    wrapped = fifo_on_first_call(lambda x: seen.append((x, _policy())) or x * 2, 5,
                                 errors.append)
    out = []
    worker = threading.Thread(target=lambda: out.extend(wrapped(k) for k in range(3)))
    worker.start()
    worker.join()
    assert out == [0, 2, 4] and [x for x, _ in seen] == [0, 1, 2]
    policies = {p for _, p in seen}
    if errors:                                  # not allowed here: said, nothing changed
        assert policies == {(os.SCHED_OTHER, 0)} and len(errors) == 1
        assert wrapped.error == errors[0]
    else:                                       # root: FIFO at 5 from the first call on
        assert policies == {(os.SCHED_FIFO, 5)} and wrapped.error is None
    assert _policy() == (os.SCHED_OTHER, 0)     # the caller of the wrapping untouched


def test_a_refusal_goes_to_on_error_and_the_callback_still_runs(monkeypatch):
    def refuse(pid, policy, param):
        raise PermissionError(1, 'Operation not permitted')
    monkeypatch.setattr(os, 'sched_setscheduler', refuse)
    errors = []
    wrapped = fifo_on_first_call(lambda: 'ran', 10, errors.append)
    assert wrapped.error is None                                  # no call yet
    assert [wrapped(), wrapped()] == ['ran', 'ran']
    assert len(errors) == 1 and 'not permitted' in errors[0]      # tried once, said once
    assert wrapped.error == errors[0]                             # kept for a status


@pytest.mark.parametrize('priority', [0, 100, -1])
def test_a_priority_outside_1_to_99_is_refused(priority):
    with pytest.raises(ValueError, match='1..99'):
        fifo_on_first_call(print, priority)


class _Cycle:
    """An object that refers to itself: only the cyclic collector frees it."""

    def __init__(self):
        self.me = self


def test_the_heap_there_is_leaves_the_collectors_passes_and_later_garbage_does_not():
    before = [object() for _ in range(3)] + [[k] for k in range(3)]  # tracked: lists
    try:
        freeze_heap()
        assert gc.get_freeze_count() >= 3
        tracked = {id(o) for o in gc.get_objects()}
        assert not any(id(o) in tracked for o in before[3:])          # frozen, not walked
        later = _Cycle()                                              # a cycle made later
        assert any(o is later for o in gc.get_objects())              # walked as before
        gone = weakref.ref(later)
        del later
        gc.collect()
        assert gone() is None                                         # and collected
    finally:
        gc.unfreeze()                                                 # the worker's heap back
