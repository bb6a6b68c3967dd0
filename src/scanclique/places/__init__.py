"""Topological place recognition (paper §2, the second application): a database of
places, each a stored batch observation; a query scan returns the places it sees and its
pose relative to each, verified by the clique matcher and validated (paper §7).

* :mod:`.signature` — rotation-invariant signatures, the prefilter's vectors;
"""

from .signature import SIGNATURE_SIZE, SIGNATURE_VERSION, scan_signature, signature_distance

__all__ = ["SIGNATURE_SIZE", "SIGNATURE_VERSION", "scan_signature", "signature_distance"]
