"""The one helper by which immutable records freeze their arrays (STYLE.md: results are
immutable records whose arrays are read-only)."""

from __future__ import annotations

import numpy as np

__all__ = ["readonly"]


def readonly(a, *, dtype=None, copy: bool = False):
    """``a`` as a C-contiguous, read-only ndarray; ``None`` stays ``None``.

    Parameters
    ----------
    a : array_like or None
    dtype : numpy dtype, optional
        Convert to this dtype (copying only when needed, unless ``copy``).
    copy : bool
        Always copy, so that freezing the result never freezes the caller's array.

    Examples
    --------
    >>> x = readonly([1, 2], dtype=float)
    >>> x.flags.writeable, x.dtype.name
    (False, 'float64')
    """
    if a is None:
        return None
    a = np.array(a, dtype=dtype, order="C") if copy else np.ascontiguousarray(a, dtype=dtype)
    a.setflags(write=False)
    return a
