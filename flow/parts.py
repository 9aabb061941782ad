"""Frames that became several: a node run on each part of a frame (``Frame.parts``).

One input may hold several things to process alike (objects found in it); a node that splits a
frame puts them in ``frame.parts``, each a ``Frame`` of its own, and the nodes wrapped by
``EachPart`` then run on every part, with the same fault isolation as frames: a part that fails
keeps its reason and skips its remaining nodes, the others go on. The frame itself fails only
when every part has. Knows nothing about faces.
"""
from __future__ import annotations

from .frame import Frame, FrameFailed
from .pipeline import run_node


class EachPart:
    """A node that runs ``node`` on each part of a frame that is still ``ok``.

    It takes the wrapped node's ``name`` and ``thread_safe``; per-part timings stay in each part's
    ``meta["timings"]`` and the frame's timing is their sum. A frame without parts fails: the node
    before it said there was nothing to process but did not fail the frame itself."""

    def __init__(self, node):
        self.node = node
        self.name = node.name
        self.thread_safe = getattr(node, "thread_safe", False)

    def __call__(self, frame: Frame) -> Frame:
        if not frame.parts:
            raise FrameFailed(f"{frame.source}: no parts to run {self.name} on")
        for i, part in enumerate(frame.parts):
            if frame.cancelled:
                part.cancel()
            frame.parts[i] = run_node(self.node, part)
        failed = [p for p in frame.parts if not p.ok]
        if len(failed) == len(frame.parts):
            raise FrameFailed(failed[0].status)
        return frame
