"""The plain library layer behind the ``scanclique`` commands (no typer, no rich).

Scripts call these the way the commands do:

* loading: :func:`load_scan`, :func:`load_scan_pair`, :func:`load_config`,
  :func:`odometry_path` (:mod:`scanclique.tools.loading`);
* runs: :func:`run_match`, :func:`run_demo`, :func:`run_validate` returning
  :class:`MatchRun` / :class:`ValidateRun` (:mod:`scanclique.tools.runs`);
* tables: :func:`match_rows`, :func:`validation_rows`, :func:`feature_rows`,
  :func:`features_to_dict`, :func:`confusion_rows` (:mod:`scanclique.tools.reports`).

>>> from scanclique.tools import run_demo, match_rows
>>> run = run_demo(data=False)
>>> dict((m, v) for m, v, _ in match_rows(run))["verdict"] in ("accepted", "ambiguous")
True
"""

import importlib
from typing import TYPE_CHECKING, Any

#: public name -> submodule; loaded on first use (the submodules import the core)
_WHERE = {
    "load_config": "loading",
    "load_scan": "loading",
    "load_scan_pair": "loading",
    "odometry_path": "loading",
    "KINDS": "reports",
    "confusion_rows": "reports",
    "feature_rows": "reports",
    "features_to_dict": "reports",
    "match_rows": "reports",
    "validation_rows": "reports",
    "DEMO_INDICES": "runs",
    "DEMO_SEED": "runs",
    "SUCCESS_ROTATION_DEG": "runs",
    "SUCCESS_TRANSLATION": "runs",
    "MatchRun": "runs",
    "ValidateRun": "runs",
    "run_demo": "runs",
    "run_match": "runs",
    "run_validate": "runs",
    "clean_json": "jsonable",
}

if TYPE_CHECKING:  # pragma: no cover
    from .jsonable import clean_json  # noqa: F401
    from .loading import load_config, load_scan, load_scan_pair, odometry_path  # noqa: F401
    from .reports import (  # noqa: F401
        KINDS,
        confusion_rows,
        feature_rows,
        features_to_dict,
        match_rows,
        validation_rows,
    )
    from .runs import (  # noqa: F401
        DEMO_INDICES,
        DEMO_SEED,
        SUCCESS_ROTATION_DEG,
        SUCCESS_TRANSLATION,
        MatchRun,
        ValidateRun,
        run_demo,
        run_match,
        run_validate,
    )


__all__ = [
    "DEMO_INDICES",
    "DEMO_SEED",
    "KINDS",
    "SUCCESS_ROTATION_DEG",
    "SUCCESS_TRANSLATION",
    "MatchRun",
    "ValidateRun",
    "clean_json",
    "confusion_rows",
    "feature_rows",
    "features_to_dict",
    "load_config",
    "load_scan",
    "load_scan_pair",
    "match_rows",
    "odometry_path",
    "run_demo",
    "run_match",
    "run_validate",
    "validation_rows",
]


def __getattr__(name: str) -> Any:
    try:
        module = _WHERE[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_WHERE])
