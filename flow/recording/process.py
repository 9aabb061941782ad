"""``ProcessSinks``: sinks that write in a process of their own, off the run's interpreter lock.

A recording is Python work per event (Rerun's Arrow conversion, MCAP's records, the Foxglove
copies): 25-30 ms a frame at 64x64 and K = 59, all of it under the lock the fit's threads need,
which made a recorded run 2x the unrecorded one while the machine's other core idled. Here the
recorder thread only turns each event into bytes (``wire``) and sends them down a socket; a child
process rebuilds the events and runs the sinks, on the other core.

The child is ``sys.executable`` with this module's ``serve`` (not ``multiprocessing``'s spawn,
which re-runs the caller's ``__main__`` in the child: a user's script without a main guard would
start over). The sinks are named, not pickled: ``(callable, args, kwargs)`` with JSON arguments,
imported by name in the child. If the run dies, the child reads end-of-file and closes its files
as a finished run would; it ignores SIGINT and SIGTERM (the run closes it).

The child's allocator gives freed memory back at once (``CHILD_ENV``): sinks written in Rust
(Rerun's bindings) allocate through mimalloc, which by default keeps freed pages for later and,
over a long recording, let the child's RSS saw by about 30 MiB around its level
(``benchmarks/bench_soak.py``); with them returned at once it moves by a few MiB, at the same speed.
"""
from __future__ import annotations

import importlib
import json
import os
import signal
import subprocess
import sys
from collections import OrderedDict
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import wire
from .events import Event, OnMask, Sink

SinkSpec = tuple[Callable[..., Sink], tuple, dict]  # a sink factory and its JSON arguments

# set in the child's environment unless the caller's environment sets them already
CHILD_ENV = {"MIMALLOC_PURGE_DELAY": "0"}  # mimalloc: return freed pages to the system at once


def child_environment(environ: Mapping[str, str]) -> dict[str, str]:
    """The recording process's environment: ``environ`` with ``CHILD_ENV`` where it sets none of its
    own, and this interpreter's ``sys.path`` as ``PYTHONPATH`` (the sinks are imported by name)."""
    return {**CHILD_ENV, **environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}


class ProcessSinks(Sink):
    """The sinks ``specs`` make, run in a child process; one ``Sink`` to a ``Recorder``.

    ``write`` and ``name_frame`` return once the event is sent; ``frame_done`` returns once every
    sink has flushed the frame (its error, if any, raised here as ``RuntimeError``); ``close``
    closes them and waits for the child. ``paths``: the files the sinks have written (a Rerun
    sink's segments included), as of the last ``frame_done`` or ``close``.
    ``max_masks``: ``OnMask`` grids the child keeps (each is sent once, then named by key).
    ``renew_frames``: with one sink, a new child every this many frames (``_renew``; the sink's
    factory then takes ``previous_paths``), for a sink whose library grows with what it has seen.
    """

    def __init__(self, specs: Sequence[SinkSpec], max_masks: int = 16, renew_frames: int | None = None):
        named = [[f"{fn.__module__}:{fn.__qualname__}", list(args), dict(kwargs)] for fn, args, kwargs in specs]
        json.dumps(named)  # TypeError now, for an argument the child could not be given
        if renew_frames is not None and (len(named) != 1 or renew_frames < 1):
            raise ValueError("renew_frames: one sink, renewed after a whole number of frames")
        self.paths: list[Path] = []
        self.max_masks, self.renew_frames = max_masks, renew_frames
        self._named = named
        self._frames = 0  # frames done by this child
        self._names: dict[int, str] = {}  # frames named and not done: a renewed child is told them again
        self._start(named)

    def _start(self, named: list) -> None:
        """A child making the sinks ``named``; masks are sent anew."""
        self._masks: OrderedDict[int, tuple[np.ndarray, int]] = OrderedDict()  # id(mask) -> (mask, key)
        self._next_key = 0
        self._conn, child = Pipe(duplex=True)
        env = child_environment(os.environ)
        self._proc = subprocess.Popen(
            [sys.executable, "-c", f"from {__name__} import serve; serve({child.fileno()})"],
            pass_fds=(child.fileno(),), stdin=subprocess.DEVNULL, env=env)
        child.close()
        self._closed = False
        self._send({"op": "open", "sinks": named})

    def _renew(self) -> None:
        """Close the child and go on in a new one, its sink made with ``previous_paths=`` the files
        the last one wrote (it goes on after them): whatever a sink's library keeps for the life of
        a process is let go."""
        self.close()
        name, args, kwargs = self._named[0]
        self._frames = 0
        self._start([[name, args, {**kwargs, "previous_paths": [str(p) for p in self.paths]}]])
        for frame, frame_name in self._names.items():  # frames under way: their rows go on under their names
            self._send({"op": "name", "frame": frame, "name": frame_name})

    def _send(self, header: dict, value: Any = None) -> None:
        data = wire.encode(header, value, self._mask_key)
        try:
            self._conn.send_bytes(data)
        except OSError:
            raise self._gone() from None

    def _recv(self) -> dict:
        try:
            return wire.decode(self._conn.recv_bytes(), {})
        except (EOFError, OSError):
            raise self._gone() from None

    def _gone(self) -> RuntimeError:
        code = self._proc.wait(timeout=60)
        return RuntimeError(f"the recording process ended (exit status {code})")

    def _mask_key(self, value: OnMask) -> int:
        """The key the child knows ``value.mask`` by, sending it first if it is new."""
        mask = value.mask
        entry = self._masks.get(id(mask))
        if entry is not None and entry[0] is mask:
            self._masks.move_to_end(id(mask))
            return entry[1]
        key, self._next_key = self._next_key, self._next_key + 1
        self._send({"op": "mask", "key": key}, np.asarray(mask, bool))
        self._masks[id(mask)] = (mask, key)  # held: its id stays its own while it is a key
        if len(self._masks) > self.max_masks:
            _, (_, old) = self._masks.popitem(last=False)
            self._send({"op": "forget", "key": old})
        return key

    def name_frame(self, frame: int, name: str) -> None:
        if self.renew_frames is not None:
            self._names[frame] = name
        self._send({"op": "name", "frame": frame, "name": name})

    def write(self, event: Event) -> None:
        self._send({"op": "event", "frame": event.frame, "path": event.path, "kind": event.kind.value,
                    "iteration": event.iteration}, event.value)

    def frame_done(self, frame: int) -> None:
        self._names.pop(frame, None)
        self._send({"op": "done", "frame": frame})
        while True:
            reply = self._recv()
            self.paths = [Path(p) for p in reply["paths"]]
            if reply.get("error"):
                raise RuntimeError(reply["error"])
            if reply["op"] == "done" and reply["frame"] == frame:
                break
        self._frames += 1
        if self.renew_frames is not None and self._frames >= self.renew_frames:
            self._renew()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        reply: dict = {}
        try:
            self._send({"op": "close"})
            reply = self._recv()
            self.paths = [Path(p) for p in reply["paths"]]
        finally:
            self._conn.close()
            try:
                self._proc.wait(timeout=300)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        if reply.get("error"):
            raise RuntimeError(reply["error"])


def renewed_sink(factory: str, args: list, kwargs: dict, every: int) -> ProcessSinks:
    """The sink ``factory`` (``module:name``) makes from ``args`` and ``kwargs``, in a process of its
    own made anew every ``every`` frames (``ProcessSinks.renew_frames``): a ``ProcessSinks`` factory
    of its own, so the recording process hosts it beside its other sinks."""
    return ProcessSinks([(_factory(factory), tuple(args), kwargs)], renew_frames=every)


def _factory(name: str) -> Callable[..., Sink]:
    module, _, attr = name.partition(":")
    return getattr(importlib.import_module(module), attr)


def serve(fd: int) -> None:
    """The child: make the sinks, then write what comes down ``fd`` until ``close`` or end of file.

    After a sink's first error nothing more is written; the error is the answer to every later
    ``done`` and to ``close``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    conn = Connection(fd)
    masks: dict[int, np.ndarray] = {}
    sinks: list[Sink] = []
    error = None
    try:
        for name, args, kwargs in wire.decode(conn.recv_bytes(), masks)["sinks"]:
            sinks.append(_factory(name)(*args, **kwargs))
    except BaseException as exc:  # noqa: BLE001 - the run hears of it at its next frame_done
        error = _describe(exc)
    while True:
        try:
            msg = wire.decode(conn.recv_bytes(), masks)
        except (EOFError, OSError):  # the run is gone: close the files as a finished run would
            break
        op = msg["op"]
        if op == "close":
            break
        if op == "mask":
            masks[msg["key"]] = msg["value"]
        elif op == "forget":
            masks.pop(msg["key"], None)
        elif error is None:
            error = _deliver(sinks, op, msg)
        if op == "done":
            conn.send_bytes(wire.encode({"op": "done", "frame": msg["frame"], "error": error,
                                         "paths": _paths(sinks)}))
    for s in sinks:
        try:
            s.close()
        except BaseException as exc:  # noqa: BLE001
            error = error or _describe(exc)
    try:
        conn.send_bytes(wire.encode({"op": "closed", "error": error, "paths": _paths(sinks)}))
    except OSError:
        pass  # nobody is listening: the run ended without closing


def _deliver(sinks: list[Sink], op: str, msg: dict) -> str | None:
    """An event, a frame's name or a frame's end given to every sink; the first error, described, or None."""
    try:
        for s in sinks:
            if op == "event":
                s.write(Event(msg["frame"], msg["path"], msg["kind"], msg["value"], msg["iteration"]))
            elif op == "name":
                s.name_frame(msg["frame"], msg["name"])
            elif op == "done":
                s.frame_done(msg["frame"])
    except BaseException as exc:  # noqa: BLE001 - reported at the frame's done
        return _describe(exc)
    return None


def _paths(sinks: list[Sink]) -> list[str]:
    return [str(p) for s in sinks for p in s.paths]


def _describe(exc: BaseException) -> str:
    return str(exc) or type(exc).__name__
