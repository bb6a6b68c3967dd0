"""What an output directory holds from an earlier run (the ``map`` and ``slam`` commands).

A run that draws no figure must not leave beside its files the figure of an earlier run
into the same directory, which would show another map; but nothing it did not write is
ever removed.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["remove_earlier_output"]


def remove_earlier_output(outdir: Path, name: str) -> Path | None:
    """Remove ``outdir/name`` when it is a file that the ``report.json`` beside it lists
    among the files an earlier run wrote (its ``files`` mapping); return its path when
    removed, else None (nothing else is ever removed)."""
    path = Path(outdir) / name
    if not path.is_file():
        return None
    try:
        files = json.loads((Path(outdir) / "report.json").read_text(encoding="utf-8"))["files"]
        listed = any(Path(str(v)).name == name for v in files.values())
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    if not listed:
        return None
    path.unlink()
    return path
