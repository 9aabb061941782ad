"""Names from recordings (file names, sources) made safe to print and to draw."""
from __future__ import annotations


def printable(text: str) -> str:
    """``text`` as a font can draw it: bytes of a file name that were not UTF-8 (lone surrogates)
    become U+FFFD."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def one_line(text: str) -> str:
    """``text`` on one line of a terminal: control characters (tab, newline, escape) and bytes
    that were not UTF-8 written as Python escapes, so a file name cannot break a table's rows."""
    return "".join(c if c.isprintable() or c == " " else c.encode("unicode_escape", "backslashreplace").decode("ascii")
                   for c in text)


def plot_label(text: str) -> str:
    """``text`` as matplotlib draws it literally: ``printable``, one line, and ``$`` escaped (two of
    them would start mathtext, and a lone one fails the drawing)."""
    return one_line(printable(text)).replace("$", r"\$")
