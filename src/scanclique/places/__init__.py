"""Topological place recognition (paper §2, the second application): a database of
places, each a stored batch observation; a query scan returns the places it sees and its
pose relative to each, verified by the clique matcher and validated (paper §7).

>>> import scanclique as sc
>>> from scanclique.places import PlaceDB, PlaceHit       # doctest: +SKIP

* :mod:`.signature` — rotation-invariant signatures, the prefilter's vectors;
* :mod:`.index` — exact brute-force nearest-signature search;
* :mod:`.hashing` — geometric hashing of feature triangles, the second prefilter;
* :mod:`.store` — the SQLite store (WAL, typed blobs, schema version, stored config);
* :mod:`.verify` — match and validate a candidate: accepted / ambiguous / rejected;
* :mod:`.database` — :class:`PlaceDB` and :class:`PlaceHit`, the contract;
* :mod:`.locate` — :class:`Localiser`: a run's scans located in the places' map as they
  come, by recognition and (:mod:`.track`) by tracking from the last scan placed;
* :mod:`.loops` — every revisit of a log, serially, over local processes or Dask.
"""

from .database import PlaceDB, PlaceHit
from .index import SignatureIndex
from .locate import Localiser, Located
from .signature import SIGNATURE_SIZE, SIGNATURE_VERSION, scan_signature, signature_distance
from .store import PlaceStore
from .verify import ACCEPTED, AMBIGUOUS, REJECTED, Verification, verify_pair

__all__ = [
    "ACCEPTED",
    "AMBIGUOUS",
    "REJECTED",
    "SIGNATURE_SIZE",
    "SIGNATURE_VERSION",
    "Localiser",
    "Located",
    "PlaceDB",
    "PlaceHit",
    "PlaceStore",
    "SignatureIndex",
    "Verification",
    "scan_signature",
    "signature_distance",
    "verify_pair",
]
