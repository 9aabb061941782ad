"""JSON that every reader takes: numpy values as Python's, and no NaN or infinity (which ``json``
writes as bare ``NaN``, which strict JSON, SQLite's JSON and browsers refuse)."""
from __future__ import annotations

import math

import numpy as np


def jsonable(x):
    """``json.dumps``'s ``default`` for what it cannot write: numpy scalars and arrays as Python's,
    anything else as its text."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def json_safe(x):
    """``x`` (dicts, lists, tuples, numbers, numpy values, strings) with every non-finite number as
    None and numpy values as Python's: ``json.dumps(json_safe(x), allow_nan=False)`` never fails on
    a number."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
