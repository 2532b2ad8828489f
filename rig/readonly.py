"""Read-only arrays for the packages' frozen values: a result object's arrays cannot be changed
behind it, by its maker or by whoever reads it."""

from __future__ import annotations

import numpy as np


def readonly(a):
    """``a`` with its write flag cleared, returned: an ndarray is not copied (a view's flag is
    cleared, its base is left as it is: make the view from an array nobody else writes), any
    other array-like becomes a new C-contiguous array first; ``None`` passes through (an
    optional field)."""
    if a is None:
        return None
    if not isinstance(a, np.ndarray):
        a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a
