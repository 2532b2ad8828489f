"""rig.threads.Prefetch: an iterator run ahead in a thread keeps order and content, hands exceptions over,
and stops when its consumer stops."""

import threading
import time

import pytest

from rig.threads import prefetch


def test_items_arrive_in_order_and_unchanged():
    assert list(prefetch(iter(range(1000)), 3)) == list(range(1000))
    assert list(prefetch([], 1)) == []


def test_a_producer_exception_is_raised_where_its_item_would_have_been():
    def items():
        yield 1
        yield 2
        raise ZeroDivisionError("bench diverged at t = 3 s")

    got = []
    with pytest.raises(ZeroDivisionError, match="t = 3 s"):
        for x in prefetch(items(), 2):
            got.append(x)
    assert got == [1, 2]


def test_the_producer_stops_soon_after_the_consumer_stops():
    made = []
    finished = threading.Event()

    def items():
        try:
            for i in range(10_000):
                made.append(i)
                yield i
        finally:
            finished.set()

    it = prefetch(items(), 2)
    assert [next(it) for _ in range(5)] == [0, 1, 2, 3, 4]
    it.close()
    deadline = time.monotonic() + 5.0
    while len(made) < 10_000 and time.monotonic() < deadline and not finished.is_set():
        n = len(made)
        time.sleep(0.2)
        if len(made) == n:
            break
    # at most the queue (2), the item being put and the one being made beyond the five consumed
    assert len(made) <= 5 + 2 + 2


@pytest.mark.parametrize("depth", [0, -1, 1.5, True])
def test_bad_depth_is_refused_naming_the_value(depth):
    with pytest.raises(ValueError, match=f"depth = {depth!r} is invalid"):
        prefetch([1], depth)
