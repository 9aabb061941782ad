"""The native libraries' own messages kept off the terminal.

libpng and libjpeg, called by OpenCV, print what they find wrong in a file straight to the process's
standard error ("libpng error: bad adaptive filter value", "Corrupt JPEG data: premature end of data
segment"), beside the one line the loader itself gives for that file. OpenCV's log level does not reach
them. LiteRT says "INFO: Created TensorFlow Lite XNNPACK delegate for CPU." whenever a net is loaded. ``decoder_messages_dropped`` points standard error (fd 2) at a pipe while a decoder runs, then
writes back every line that is not such a message, so nothing else printed meanwhile (by another
thread) is lost; decoders run one at a time under it.
"""
from __future__ import annotations

import os
import re
import sys
import threading
from contextlib import contextmanager
from typing import Iterator

# the messages of libpng, libjpeg(-turbo) and libtiff, as their default handlers word them, OpenCV's log lines
# and LiteRT's note on loading a net
DECODER_MESSAGE = re.compile(
    rb"^(\[ ?(WARN|ERROR|INFO):\d+@[\d.]+\] |libpng (error|warning)|Corrupt JPEG data|Premature end of JPEG file|Invalid JPEG file structure|"
    rb"Invalid SOS parameters|Unsupported marker|Bogus |Inconsistent progression sequence|JPEG datastream|"
    rb"TIFFRead|TIFFFetch|TIFFReadDirectory|Warning, Unknown field|.*: Not a TIFF|INFO: Created TensorFlow Lite)")

_lock = threading.Lock()


def keep_line(line: bytes) -> bool:
    """Is ``line`` (one line of standard error) anything but a decoder's message?"""
    return DECODER_MESSAGE.match(line) is None


@contextmanager
def decoder_messages_dropped() -> Iterator[None]:
    """Within it, the decoders' messages on standard error are dropped and everything else written there
    passes (after the block). Does nothing when fd 2 cannot be redirected."""
    with _lock:
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError, AttributeError):
            yield
            return
        read_end, write_end = os.pipe()  # drained by a thread: no file is written, and no writer blocks
        chunks: list[bytes] = []

        def drain() -> None:
            while chunk := os.read(read_end, 65536):
                chunks.append(chunk)

        reader = threading.Thread(target=drain, name="stderr-drain", daemon=True)
        reader.start()
        try:
            os.dup2(write_end, 2)
            os.close(write_end)
            write_end = -1
            try:
                yield
            finally:
                try:
                    sys.stderr.flush()
                except (OSError, ValueError):
                    pass
                os.dup2(saved, 2)  # the pipe's last writer gone: the drain ends
                reader.join()
            kept = b"".join(line for line in b"".join(chunks).splitlines(keepends=True) if keep_line(line))
            if kept:
                os.write(2, kept)
        finally:
            if write_end >= 0:
                os.close(write_end)
            os.close(saved)
            os.close(read_end)
