"""JSON-ready values: what ``--json`` prints (light: NumPy is imported only when needed)."""

from __future__ import annotations

import math
import sys
from typing import Any

__all__ = ["clean_json"]


def clean_json(obj: Any) -> Any:
    """``obj`` for strict JSON: NaN and infinities become None, NumPy scalars and arrays
    Python numbers and lists, tuples lists, dict keys strings; recursively."""
    if isinstance(obj, dict):
        return {str(k): clean_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean_json(v) for v in obj]
    np = sys.modules.get("numpy")
    if np is not None:
        if isinstance(obj, np.ndarray):
            return clean_json(obj.tolist())
        if isinstance(obj, np.generic):
            obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
