"""Recordings of a run: every iteration's arrays and scalars, to MCAP and Rerun files.

Nodes hand ``Event``s (``events``) to a ``Recorder`` (``recorder``); one writer thread takes them
from a bounded queue and passes them to each ``Sink`` (``McapSink`` in ``mcap_sink``,
``RerunSink`` in ``rerun_sink``), so encoding and compression stay off the compute threads and
Rerun's per-thread time cursor lives on a single thread. Times are explicit on every event:
timeline ``frame`` (the frame's position in the stream) and timeline ``iteration`` (absent for
once-per-frame products). ``codec`` is the array message, ``reader`` reads MCAP files back, ``tap`` keeps a channel's
scalars in memory for the run's own report. The
on-disk formats are documented in ``recordings/README.md``. Knows nothing about faces.
"""
from .codec import decode_array, encode_array, log_time_ns
from .events import Event, Kind, OnMask, Sink
from .mcap_sink import McapSink
from .process import ProcessSinks
from .reader import FrameRecording, FrameStream, Recording, RecordingError, read_mcap
from .recorder import Recorder, RecordOptions
from .rerun_sink import RerunSink
from .tap import ScalarsTap

__all__ = ["Event", "FrameRecording", "FrameStream", "Kind", "McapSink", "OnMask", "ProcessSinks", "RecordOptions", "Recorder", "Recording",
           "RecordingError", "RerunSink", "ScalarsTap", "Sink", "decode_array", "encode_array", "log_time_ns", "read_mcap"]
