"""The stream core both engines share (``flow/stream.py``): the re-order buffer and the source."""
import queue
import threading

from shadowflow.flow import Frame
from shadowflow.flow.stream import END, InOrder, Source


def test_in_order_lets_an_item_leave_only_when_every_earlier_one_has():
    order = InOrder()
    for seq in (2, 1, 4):
        order.put(seq, f"f{seq}")
    assert list(order.ready()) == []  # 0 not finished: nothing may leave
    order.put(0, "f0")
    assert list(order.ready()) == ["f0", "f1", "f2"]  # 3 missing: 4 waits
    order.put(3, "f3")
    assert list(order.ready()) == ["f3", "f4"]
    assert order.pending == {} and order.next_seq == 5


def test_in_order_holds_back_unfinished_work_in_its_place():
    class Futures(InOrder):
        def finished(self, item):
            return item != "running"

    order = Futures()
    order.put(0, "done")
    order.put(1, "running")
    order.put(2, "done")
    assert list(order.ready()) == ["done"]
    assert order.next_seq == 1 and set(order.pending) == {1, 2}


def test_source_feeds_in_order_then_ends_once_per_reader():
    q = queue.Queue(maxsize=2)
    taken = []
    src = Source((Frame(i, f"s{i}") for i in range(5)), q, threading.Event(), ends=3,
                 on_take=lambda: taken.append(1))
    src.start()
    got = [q.get(timeout=5) for _ in range(8)]
    assert [seq for seq, _ in got[:5]] == [0, 1, 2, 3, 4]
    assert got[5:] == [END, END, END]
    assert len(taken) == 5 and src.errors == []


def test_a_stopped_source_takes_no_more_frames_and_keeps_what_broke_it():
    stop = threading.Event()
    pulled = []

    def frames():
        for i in range(100):
            pulled.append(i)
            if i == 3:
                stop.set()
            yield Frame(i, f"s{i}")

    q = queue.Queue()
    src = Source(frames(), q, stop)
    src.start()
    items = []
    while (item := src.get(timeout=5)) is not END:
        items.append(item)
    # the frame read as the stop came is not taken, and none after it is read
    assert [seq for seq, _ in items] == [0, 1, 2] and pulled == [0, 1, 2, 3]

    def broken():
        yield Frame(0, "ok")
        raise OSError("the folder went away")

    src = Source(broken(), queue.Queue(), threading.Event())
    src.start()
    assert src.get(timeout=5)[0] == 0 and src.get(timeout=5) is END
    assert [str(e) for e in src.errors] == ["the folder went away"]
