"""Frames as tasks on a Dask cluster (``dask.distributed``), for streams that outgrow one machine.

``DaskPipeline`` keeps ``Pipeline``'s contract: ``run(frames)`` yields every frame in input
order (``on_done`` first), a failing frame fails alone, ``frame_timeout`` limits each node, and
``stop()`` (or SIGINT / SIGTERM) takes no new frames and hands the unfinished ones back
``cancelled``. Each frame is one task running the whole node chain (``Chain``) on a worker; at
most ``in_flight`` tasks are out at once, so the client's memory does not grow with the stream.
The chain is built once per worker process and run from ``build(shared)``, where ``shared`` (e.g.
a shape model) is sent to every worker once (``Client.scatter(broadcast=True)``). A worker that
dies mid-frame has its frames redone elsewhere by Dask; a frame whose tasks kill workers again
and again (``KilledWorker``) fails with that reason. Knows nothing about faces.

Dask moves frames between processes with pickle: the cluster is trusted, as the client's own
processes are; nothing read from a user's files is unpickled.
"""
from __future__ import annotations

import queue
import threading
import uuid
from typing import Any, Callable, Iterable, Iterator

from .chain import Chain, Node
from .frame import Frame
from .stream import END, InOrder, Source, Stoppable

_CHAINS: dict[str, tuple[Chain, Callable[[], None] | None]] = {}  # in each worker: run token -> chain, close
_CHAINS_LOCK = threading.Lock()


Build = Callable[[Any], "tuple[list[Node], Callable[[Frame], None] | None, Callable[[], None] | None]"]


def process_frame(token: str, bundle: tuple[Build, Any], frame: Frame, frame_timeout: float | None) -> Frame:
    """The task: ``frame`` through this worker's chain of run ``token``, built on first use.
    bundle: (build, shared), sent to each worker once; ``build(shared)`` gives the nodes, a
    function called on every frame at the end, failed or not (e.g. to record it, or to choose
    what travels back to the client), and one called once when the run ends (``close_chain``),
    e.g. to close files the worker wrote; either may be None."""
    with _CHAINS_LOCK:
        entry = _CHAINS.get(token)
        if entry is None:
            for old in list(_CHAINS)[:-1]:  # a run that never said it ended: keep one beside this, no more
                _close(_CHAINS.pop(old)[1])
            build, shared = bundle
            nodes, finish, close = build(shared)
            entry = _CHAINS[token] = (Chain(nodes, on_done=finish, frame_timeout=frame_timeout), close)
    return entry[0].process(frame)


def close_chain(token: str) -> None:
    """Run on every worker when run ``token`` ends: forget its chain and call its ``close``."""
    with _CHAINS_LOCK:
        entry = _CHAINS.pop(token, None)
    if entry is not None:
        _close(entry[1])


def _close(close: Callable[[], None] | None) -> None:
    if close is not None:
        close()


def default_in_flight(client) -> int:
    """Tasks out at once: twice the cluster's threads (each has the next task waiting), at least 2."""
    return max(2, 2 * sum(client.nthreads().values()))


class _Flight(InOrder):
    """The frames of a run out at once: ``pending`` seq -> a future (its task out) or its Frame (finished,
    waiting for its turn); ``given`` seq -> the frame as sent, for failures and cancellation."""

    def __init__(self):
        super().__init__()
        self.given: dict[int, Frame] = {}
        self.exhausted = False

    def finished(self, item) -> bool:
        return isinstance(item, Frame)

    def running(self) -> list:
        return [f for f in self.pending.values() if not isinstance(f, Frame)]

    def cancel_all(self) -> None:
        """Every task still out given up: its frame marked cancelled, in its place."""
        for seq, f in list(self.pending.items()):
            if not isinstance(f, Frame):
                self.given[seq].cancelled = True
                self.pending[seq] = self.given.pop(seq)


class DaskPipeline(Stoppable):
    """Run frames through ``build(shared)``'s nodes as tasks of ``client``; iterate over ``run``.

    build: a picklable callable ``shared -> (nodes, finish)`` (see ``process_frame``; called once
    per worker); in_flight: tasks out at once (default: twice the cluster's threads); on_done,
    frame_timeout: as ``Pipeline``.
    """

    def __init__(self, client, build: Build, shared: Any = None,
                 on_done: Callable[[Frame], None] | None = None, frame_timeout: float | None = None,
                 in_flight: int | None = None):
        self.client, self.build, self.shared = client, build, shared
        self.on_done, self.frame_timeout = on_done, frame_timeout
        self.in_flight = in_flight or default_in_flight(client)
        super().__init__()  # stop(): tasks still out are cancelled, their frames emitted ``cancelled``
        self.max_in_flight = 0  # observed, for tests and benchmarks
        # why the cluster was lost mid-run (its scheduler died or cannot be reached), or None: the
        # frames out then are emitted ``cancelled`` and the stream ends, as after ``stop()``
        self.lost: str | None = None

    def _cluster_lost(self, exc: BaseException) -> str | None:
        """Why ``exc`` (raised by a call to the client) means the cluster is gone, or None when it is
        something else. The client is then no longer running, or says the connection was lost."""
        text = " ".join(str(exc).split()).lower()
        status = str(getattr(self.client, "status", "running")).split(".")[-1]
        cut = "scheduler-connection-lost" in text or "lost the connection to the scheduler" in text
        if status == "running" and not cut:
            return None
        try:
            where = f" at {self.client.scheduler.address}"
        except Exception:  # noqa: BLE001 - the address is only for the message
            where = ""
        return f"the Dask scheduler{where} went away ({'connection lost' if cut else f'client {status}'})"

    def run(self, frames: Iterable[Frame], handle_signals: bool = False) -> Iterator[Frame]:
        token = uuid.uuid4().hex
        # the build and what it shares go to every worker once: a task carries only its frame (the
        # build, holding every input's path, sent with each task made the client grow 250 kB a frame)
        bundle = self.client.scatter((self.build, self.shared), broadcast=True, hash=False)
        source = Source(frames, queue.Queue(maxsize=self.in_flight), self._stop, name="flow-dask-source")
        flight = _Flight()
        with self.signals(handle_signals):
            source.start()
            try:
                while True:
                    halted = self._advance(flight, source, token, bundle)
                    for frame in flight.ready():  # input order
                        if self.on_done is not None:
                            self.on_done(frame)
                        yield frame
                    if not flight.pending and (flight.exhausted or halted):
                        break
            finally:
                source.close()
                if self.lost is None:  # (a lost cluster has nothing to cancel or close)
                    leftover = flight.running()
                    if leftover:
                        self.client.cancel(leftover)
                    self._close_workers(token)
        if source.errors:
            raise source.errors[0]

    def _advance(self, flight: _Flight, source: Source, token: str, bundle) -> bool:
        """Tasks submitted while there is room, finished ones collected; on a stop, or when the cluster
        is lost, the tasks still out cancelled and their frames marked so. Returns whether the run halts."""
        halted = self._stop.is_set() or self.lost is not None
        try:
            if not halted:
                self._submit(flight, source, token, bundle)
                self._collect(flight)
        except Exception as exc:  # noqa: BLE001 - the cluster going away is the stream's end, not a crash
            self.lost = self._cluster_lost(exc)
            if self.lost is None:
                raise
            halted = True
        if halted:  # tasks still out are cancelled; their frames go on as cancelled
            running = flight.running()
            if running and self.lost is None:
                self.client.cancel(running)
            flight.cancel_all()
        return halted

    def _submit(self, flight: _Flight, source: Source, token: str, bundle) -> None:
        """Frames from the source as tasks until ``in_flight`` are out (failed or skipped ones pass)."""
        while not flight.exhausted and len(flight.pending) < self.in_flight:
            item = source.get(timeout=0.05 if flight.pending else 0.5)
            if item is None:
                return
            if item is END:
                flight.exhausted = True
                return
            seq, frame = item
            if frame.skipped or not frame.ok:
                flight.put(seq, frame)
                continue
            flight.given[seq] = frame
            flight.pending[seq] = self.client.submit(process_frame, token, bundle, frame, self.frame_timeout,
                                                 pure=False, key=f"frame-{seq}-{token}")
            self.max_in_flight = max(self.max_in_flight, len(flight.pending))

    def _collect(self, flight: _Flight) -> None:
        """Wait a little for a task to finish, then take every finished one's frame."""
        from distributed import wait

        running = flight.running()
        if not running:
            return
        try:
            wait(running, timeout=0.2, return_when="FIRST_COMPLETED")
        except TimeoutError:  # none finished yet: look at the source and the stop flag again
            pass
        for seq, f in list(flight.pending.items()):
            if not isinstance(f, Frame) and f.done():
                flight.pending[seq] = self._result(f, flight.given[seq])
                flight.given.pop(seq)

    def _close_workers(self, token: str) -> None:
        """``close_chain`` on every worker still there (a worker that died has nothing to close).
        A close that fails is reported as a warning: the frames are done, the files it left
        may end early."""
        import warnings

        try:
            self.client.run(close_chain, token)
        except Exception as exc:  # noqa: BLE001 - the cluster went away, a worker's close failed
            warnings.warn(f"closing the workers' part of the run: {type(exc).__name__}: {exc}", stacklevel=2)

    def _result(self, future, frame: Frame) -> Frame:
        """The task's frame, or ``frame`` failed with why the task did not finish (a task lost with the
        cluster raises: the stream ends there)."""
        try:
            return future.result()
        except Exception as exc:  # noqa: BLE001 - KilledWorker, a task's error...: this frame's
            if self._cluster_lost(exc) is not None:
                raise
            text = f"{frame.source}: {type(exc).__name__}: {exc}"
            frame.fail("dask", " ".join(text.split())[:500])
            frame.error = exc
            return frame


def ordered_map(client, fn: Callable[[Any, Any], Any], items: Iterable[Any], shared: Any = None,
                in_flight: int | None = None) -> Iterator[Any]:
    """``fn(shared, item)`` for each item as tasks of ``client``, results in item order, at most
    ``in_flight`` tasks out (default: twice the cluster's threads); ``shared`` is sent to every
    worker once. An exception in a task is raised here, as ``map`` would."""
    from distributed import wait

    limit = in_flight or default_in_flight(client)
    shared_f = client.scatter(shared, broadcast=True, hash=False)
    token = uuid.uuid4().hex
    out: list = []
    items = iter(items)
    exhausted = False
    k = 0
    try:
        while True:
            while not exhausted and len(out) < limit:
                try:
                    item = next(items)
                except StopIteration:
                    exhausted = True
                    break
                out.append(client.submit(fn, shared_f, item, pure=False, key=f"item-{k}-{token}"))
                k += 1
            if not out:
                return
            wait(out[:1])
            yield out.pop(0).result()
    finally:
        if out:
            client.cancel(out)


def local_map(fn: Callable[[Any, Any], Any], items: Iterable[Any], shared: Any = None) -> Iterator[Any]:
    """``ordered_map`` on this thread: the same results, no cluster."""
    for item in items:
        yield fn(shared, item)
