"""TOML files of configurations: read, write, round trip.

The matcher's :class:`~scanclique.config.MatchConfig` by default; the same functions take
any configuration record built the same way (frozen dataclasses of scalars, tuples and
nested records): the mapper's :class:`~scanclique.mapping.MapConfig` and the filter's
:class:`~scanclique.slam.SlamConfig` (``base=MapConfig()``, ``cls=SlamConfig``).

A configuration file has one table per pipeline stage, each key a field of that stage's
dataclass (see :mod:`scanclique.config`); keys left out keep their defaults::

    [correspondence]
    point_point = 0.3
    signed = false

    [pose]
    method = "median"

Reading is strict: an unknown table or key, or a value of the wrong type, raises
:class:`~scanclique.errors.ConfigError` naming the file and the dotted key
(``"run.toml: unknown key 'features.foo' (known in [features]: ...)"``), and so does a
file that is not valid TOML (with the parser's line and column). Writing uses a small
emitter of the nested dict (floats are written with ``repr``, so reading back gives the
same values bit for bit; tuples are arrays; TOML has no null, so a field that is ``None``
is written as the string ``"none"``, which is read back as ``None`` only where the field
may be ``None``).

Examples
--------
>>> from scanclique.config import paper_config
>>> text = dumps_config(paper_config())
>>> loads_config(text) == paper_config()
True
>>> print(dumps_config(paper_config()).split("[pose]")[1].strip().splitlines()[0])
method = "median"
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import sys
from pathlib import Path

from ..config import MatchConfig, a_or_an, config_from_dict, config_to_dict
from ..errors import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["read_config", "write_config", "loads_config", "dumps_config", "toml_dumps"]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")
_HEADER = "# scanclique configuration ({}): one table per stage.\n"
NONE = "none"
"""How a field that is ``None`` is written (TOML has no null)."""


def _is_config(obj) -> bool:
    """A configuration record (an instance of a dataclass, not the class)."""
    return dataclasses.is_dataclass(obj) and not isinstance(obj, type)


# ---------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------
def _type_name(value) -> str:
    names = {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "an array",
    }
    return names.get(type(value), type(value).__name__)


def _is_section(f) -> bool:
    """Whether field ``f`` holds a nested configuration record (a TOML table)."""
    default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
    return dataclasses.is_dataclass(default)


def _check_tree(data: dict, cls, source: str, prefix: str = "") -> dict:
    """Check ``data`` against the fields of dataclass ``cls``; return it with integers
    given for float fields turned into floats. Errors name ``source`` and the dotted key."""
    known = {f.name: f for f in dataclasses.fields(cls)}
    out = {}
    for key, value in data.items():
        dotted = f"{prefix}{key}"
        if key not in known:
            if prefix:
                where = f"keys in [{prefix[:-1]}]"
            elif all(_is_section(g) for g in known.values()):
                where = "tables"
            else:  # a SlamConfig: keys at the top, and the [association] table
                where = "keys and tables"
            raise ConfigError(
                f"{source}: unknown key {dotted!r} (known {where}: {', '.join(known)})"
            )
        f = known[key]
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if dataclasses.is_dataclass(default):
            if not isinstance(value, dict):
                raise ConfigError(f"{source}: {dotted!r} must be a table, got {_type_name(value)}")
            out[key] = _check_tree(value, type(default), source, f"{dotted}.")
            continue
        if isinstance(value, dict):
            raise ConfigError(f"{source}: {dotted!r} expects {_type_name(default)}, got a table")
        optional = "None" in str(f.type)
        if optional and value == NONE:
            out[key] = None
            continue
        if default is None:  # an optional field off by default: its type from the annotation
            default = _default_of_type(str(f.type))
        if isinstance(default, tuple):
            out[key] = _tuple(value, default, source, dotted)
            continue
        if isinstance(default, bool):
            ok = isinstance(value, bool)
        elif isinstance(default, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
            if ok and not _INT64[0] <= value <= _INT64[1]:
                raise ConfigError(
                    f"{source}: {dotted!r} expects a 64-bit integer "
                    f"({_INT64[0]}..{_INT64[1]}), got {value}"
                )
        elif isinstance(default, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            if ok and isinstance(value, int) and abs(value) > 2**1023:
                raise ConfigError(f"{source}: {dotted!r} expects a number, got {value} (too large)")
            value = float(value) if ok else value
        else:
            ok = isinstance(value, type(default))
        if not ok:
            raise ConfigError(
                f"{source}: {dotted!r} expects {_type_name(default)}, "
                f"got {_type_name(value)} {value!r}"
            )
        out[key] = value
    return out


def _default_of_type(annotation: str):
    """A stand-in default of an optional field's type (``"float | None"`` -> 0.0)."""
    for name, value in (("tuple", ()), ("float", 0.0), ("int", 0), ("bool", False), ("str", "")):
        if name in annotation:
            return value
    return None


def _tuple(value, default: tuple, source: str, dotted: str) -> tuple:
    """``value`` (a TOML array) as a tuple of numbers, as long as ``default`` when it is."""
    n = len(default)
    what = f"an array of {n} numbers" if n else "an array of numbers"
    if not isinstance(value, list) or (n and len(value) != n):
        raise ConfigError(f"{source}: {dotted!r} expects {what}, got {_type_name(value)} {value!r}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{source}: {dotted!r} expects {what}, got {value!r}")
    return tuple(float(v) for v in value)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _from_dict(data: dict, source: str, base, cls):
    if cls is None:
        cls = type(base) if base is not None else MatchConfig
    if base is None:
        base = cls()
    elif not isinstance(base, cls):
        raise ConfigError(
            f"{source}: base is {a_or_an(type(base).__name__)}, not {a_or_an(cls.__name__)}"
        )
    checked = _check_tree(data, cls, source)
    try:
        return config_from_dict(_merge(config_to_dict(base), checked), cls)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None


def loads_config(text: str, source: str = "<string>", base=None, cls=None):
    """A configuration from TOML text; ``source`` names it in error messages.

    Keys left out take their values from ``base`` (default: ``cls()``), e.g.
    ``base=paper_config()`` for a file of changes to the paper's configuration. ``cls``
    is the configuration's class (default: ``base``'s, else :class:`MatchConfig`).

    >>> from scanclique.mapping import MapConfig
    >>> cfg = loads_config("[loops]\\nenabled = false", base=MapConfig())
    >>> cfg.loops.enabled, cfg.front_end == MapConfig().front_end
    (False, True)

    Raises
    ------
    ConfigError
        Invalid TOML, an unknown key, a value of the wrong type or out of range.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
    return _from_dict(data, source, base, cls)


MAX_CONFIG_BYTES = 1024 * 1024
"""Largest configuration file read (bytes)."""

_INT64 = (-(2**63), 2**63 - 1)


def read_config(path: str | os.PathLike, base=None, cls=None):
    """Read a configuration from a TOML file; keys left out take their values from ``base``
    (default: ``cls()``; ``cls`` default: ``base``'s class, else :class:`MatchConfig`).

    Raises
    ------
    DataNotFoundError
        If there is no such file.
    ConfigError
        Unreadable or invalid TOML, an unknown key (named with its table), a value of the
        wrong type or out of range; the message starts with the file name.
    """
    from ..errors import DataNotFoundError, ParseError
    from .text import check_path, open_regular

    source = check_path(path, "the configuration path")
    try:
        with open_regular(source, "configuration file") as fh:
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except DataNotFoundError:
        raise
    except ParseError as exc:  # a directory, FIFO or device: one ConfigError line
        raise ConfigError(str(exc)) from None
    except OSError as exc:
        raise ConfigError(f"{source}: cannot read: {exc.strerror or exc}") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(
            f"{source}: larger than {MAX_CONFIG_BYTES // 1024} KiB: not a scanclique "
            "configuration (`scanclique config` writes one of about 4 KiB)"
        )
    bom = raw.startswith(b"\xef\xbb\xbf")  # a byte order mark (Windows editors) is dropped
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{source}: not UTF-8 text (byte {exc.start + 3 * bom})") from None
    return loads_config(text, source, base, cls)


# ---------------------------------------------------------------------------------------
# Writing: a small TOML emitter for nested dicts of scalars
# ---------------------------------------------------------------------------------------
def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _string(k)


def _string(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _value(v, where: str) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, where) for x in v) + "]"
    raise ConfigError(f"cannot write {where} = {v!r} to TOML ({type(v).__name__})")


def toml_dumps(data: dict, header: str = "") -> str:
    """TOML text of a nested dict of scalars (bool, int, float, str, lists of them).

    Scalars of a table come before its sub-tables; sub-tables are written as
    ``[a.b]`` headers. ``None`` has no TOML form and raises :class:`ConfigError`.

    >>> print(toml_dumps({"n": 1, "pose": {"method": "lsq", "w": 0.5}}), end="")
    n = 1
    <BLANKLINE>
    [pose]
    method = "lsq"
    w = 0.5
    """
    lines: list[str] = [header] if header else []

    def emit(table: dict, path: tuple[str, ...]) -> None:
        scalars = [(k, v) for k, v in table.items() if not isinstance(v, dict)]
        tables = [(k, v) for k, v in table.items() if isinstance(v, dict)]
        if path and (scalars or not tables):
            if lines:
                lines.append("")
            lines.append("[" + ".".join(_key(p) for p in path) + "]")
        for k, v in scalars:
            lines.append(f"{_key(k)} = {_value(v, '.'.join((*path, k)))}")
        for k, v in tables:
            emit(v, (*path, k))

    emit(data, ())
    return "\n".join(lines) + "\n"


def dumps_config(config=None, comment: str | None = None) -> str:
    """TOML text of a configuration (default: ``MatchConfig()``; any configuration record,
    e.g. a ``MapConfig`` or ``SlamConfig``), every field written.

    ``comment`` (one or more lines) is added to the header as ``#`` comments.
    """
    from ..errors import ArgumentError

    cfg = config if config is not None else MatchConfig()
    if not _is_config(cfg):
        raise ArgumentError(f"config must be a configuration record, got {type(cfg).__name__}")
    header = _HEADER.format(type(cfg).__name__)
    if comment:
        header += "".join(f"# {line}\n" for line in comment.splitlines())
    return toml_dumps(_none_as_string(config_to_dict(cfg)), header=header.rstrip("\n"))


def _none_as_string(d: dict) -> dict:
    """``d`` with every ``None`` replaced by :data:`NONE` (TOML has no null)."""
    return {k: _none_as_string(v) if isinstance(v, dict) else NONE if v is None else v
            for k, v in d.items()}  # fmt: skip


def write_config(path, config, comment: str | None = None) -> Path:
    """Write ``config`` to ``path`` as TOML (parent directories must exist); returns the path.

    The arguments come in the order of every writer of :mod:`scanclique.io` (path first:
    ``write_scans_text(path, scans)``, ``write_scans_npz(path, scans)``,
    ``write_dimacs(path, graph)``). The old order ``write_config(config, path)`` still
    works and emits a :class:`DeprecationWarning`.

    Parameters
    ----------
    path : str or path-like
        The file, overwritten.
    config : MatchConfig, MapConfig, SlamConfig or another configuration record
    comment : str, optional
        Written as ``#`` lines at the top.

    Raises
    ------
    ConfigError
        If the file cannot be written.
    ArgumentError
        ``config`` is not a configuration record or ``path`` not a path.
    """
    from ..errors import ArgumentError

    if _is_config(path) and isinstance(config, (str, os.PathLike)):
        import warnings

        warnings.warn(
            "write_config(config, path) is deprecated: use write_config(path, config), the "
            "order of the other writers",
            DeprecationWarning,
            stacklevel=2,
        )
        path, config = config, path
    if not _is_config(config):
        raise ArgumentError(
            f"config must be a configuration record (MatchConfig, MapConfig, SlamConfig), "
            f"got {type(config).__name__}"
        )
    if not isinstance(path, (str, os.PathLike)):
        raise ArgumentError(f"path must be a file path, got {path!r}")
    p = Path(path)
    try:
        p.write_text(dumps_config(config, comment), encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{os.fspath(path)}: cannot write: {exc.strerror or exc}") from None
    return p
