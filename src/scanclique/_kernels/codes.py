"""Modes, statuses and options of the clique kernels, as ``IntEnum`` (no numba here).

The kernels take and return plain integers (pass ``int(Mode.ALL_MAXIMUM)``); inside them
the members are read as the module-level integer constants at the end of this file, frozen
at compile time (the cache stamp of :mod:`scanclique._kernels` recompiles them when this
file changes).
"""

from __future__ import annotations

from enum import IntEnum, IntFlag

__all__ = [
    "Mode",
    "Status",
    "Option",
    "NO_LIMIT",
    "MAXIMUM",
    "ENUMERATE",
    "ALL_MAXIMUM",
    "FINISHED",
    "TIME_LIMIT",
    "PHASE_BUDGET",
    "CLIQUE_LIMIT",
    "NODE_LIMIT",
    "NOT_RUN",
    "INVALID",
    "OPT_MAXSAT",
    "OPT_LOCAL_SEARCH",
]

#: a node limit that is never reached (2**62 nodes)
NO_LIMIT = 1 << 62


class Mode(IntEnum):
    """What :func:`scanclique._kernels.clique_search.solve` looks for."""

    #: a maximum clique (cliques larger than ``floor``); the bar rises with each one found
    MAXIMUM = 0
    #: every clique of size ``floor + 1``, at most ``limit`` of them (the bar stays)
    ENUMERATE = 1
    #: MAXIMUM, then, if it finished, ENUMERATE with ``floor = omega - 1``
    ALL_MAXIMUM = 2


class Status(IntEnum):
    """How a search ended."""

    #: the search ran to its end (the result is proven)
    FINISHED = 0
    #: the wall-clock guard (``time_limit``) stopped it
    TIME_LIMIT = 1
    #: the node budget of a first, cheap phase ran out: the next phase takes over (never
    #: returned by the entry points)
    PHASE_BUDGET = 2
    #: more than ``limit`` cliques of the enumerated size
    CLIQUE_LIMIT = 3
    #: the caller's node limit (``node_limit``) stopped it
    NODE_LIMIT = 4
    #: the phase did not run (the enumeration after an unfinished maximum search)
    NOT_RUN = -1
    #: the input is not a valid adjacency matrix (see ``solve_dense``)
    INVALID = -2


class Option(IntFlag):
    """Option bits of the full search (``opts``)."""

    #: filter the branching vertices with MaxSAT-style reasoning
    MAXSAT = 1
    #: improve the greedy initial clique by tabu local search
    LOCAL_SEARCH = 2
    DEFAULT = MAXSAT | LOCAL_SEARCH


# The members as plain ints, the form the kernels read (numba freezes module-level ints at
# compile time; an IntEnum member inside a kernel would be an object).
MAXIMUM = int(Mode.MAXIMUM)
ENUMERATE = int(Mode.ENUMERATE)
ALL_MAXIMUM = int(Mode.ALL_MAXIMUM)
FINISHED = int(Status.FINISHED)
TIME_LIMIT = int(Status.TIME_LIMIT)
PHASE_BUDGET = int(Status.PHASE_BUDGET)
CLIQUE_LIMIT = int(Status.CLIQUE_LIMIT)
NODE_LIMIT = int(Status.NODE_LIMIT)
NOT_RUN = int(Status.NOT_RUN)
INVALID = int(Status.INVALID)
OPT_MAXSAT = int(Option.MAXSAT)
OPT_LOCAL_SEARCH = int(Option.LOCAL_SEARCH)
