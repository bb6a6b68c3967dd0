"""The README's commands and outputs, checked so that they cannot drift (issue 15 item 12).

* every ``scanclique ...`` line of the ``sh`` block of "## Command line" runs (in a
  scratch directory, after the README's own Python snippet has written ``a.txt`` and
  ``b.txt``; ``../shared/data`` is the data directory) and exits with 0 (those that draw
  a figure or search long only with ``SCANCLIQUE_SLOW_TESTS=1``: about 5 minutes on a
  loaded 2-core machine);
* the sample table of ``scanclique match intel 120 121`` matches a fresh run: numbers
  within half a unit of their last shown digit (plus a little slack), words exactly;
* the pose in the comment of the "## Python" example matches ``match_scans``.

Needs the shared Intel log (skipped without it).
"""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

import pytest
from conftest import require_log
from typer.testing import CliRunner

from scanclique import cli, datasets

README = Path(__file__).resolve().parents[1] / "README.md"
SLOW = os.environ.get("SCANCLIQUE_SLOW_TESTS", "") not in ("", "0")
#: commands that draw a figure or search long: run with SCANCLIQUE_SLOW_TESTS=1
_SLOW_WORDS = ("--plot", " demo", "--all", "--paper")
runner = CliRunner()
pytestmark = pytest.mark.realdata


def _section(title: str) -> str:
    text = README.read_text(encoding="utf-8")
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 3)
    return text[start : end if end > 0 else None]


def _blocks(section: str, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", section, flags=re.S)


def _commands() -> list[str]:
    out = []
    for block in _blocks(_section("Command line"), "sh"):
        for line in block.splitlines():
            line = re.split(r"\s#\s", line, maxsplit=1)[0].strip()
            if line.startswith("scanclique "):
                out.append(line)
    return out


def _shown_table(section: str, command: str) -> dict[str, str]:
    """Metric -> value of the text table printed after ``command``."""
    i = section.index(f"`{command}` prints:")
    table = _blocks(section[i:], "text")[0]
    rows = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip("│").split("│")]
        if len(cells) == 3 and cells[0] and cells[0] != "..." and cells[0] != "Metric":
            rows[cells[0]] = cells[1]
    return rows


def _close(shown: str, actual: str) -> bool:
    try:
        a, b = float(shown), float(actual)
    except ValueError:
        return shown == actual
    decimals = len(shown.split(".")[1]) if "." in shown else 0
    return abs(a - b) <= 0.5 * 10.0**-decimals + 1e-3 * max(1.0, abs(a))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    require_log("intel")
    d = tmp_path_factory.mktemp("readme")
    snippet = next(
        b for b in _blocks(_section("Command line"), "python") if "write_scans_text" in b
    )
    import os

    old = os.getcwd()
    os.chdir(d)
    try:
        exec(compile(snippet, "README.md", "exec"), {})  # the README's own recipe
    finally:
        os.chdir(old)
    assert (d / "a.txt").is_file() and (d / "b.txt").is_file()
    return d


def test_the_command_list_is_found():
    cmds = _commands()
    assert len(cmds) >= 8
    assert any(c.startswith("scanclique match intel 120 121") for c in cmds)


@pytest.mark.parametrize(
    "command",
    [
        pytest.param(
            c,
            marks=pytest.mark.skipif(
                not SLOW and any(w in c for w in _SLOW_WORDS),
                reason="draws a figure or searches long; set SCANCLIQUE_SLOW_TESTS=1",
            ),
        )
        for c in _commands()
    ],
)
def test_each_shown_command_runs(command, workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    data = str(datasets.data_dir())
    words = shlex.split(command.replace("../shared/data", data))[1:]
    redirect = None
    if ">" in words:
        k = words.index(">")
        words, redirect = words[:k], words[k + 1]
    r = runner.invoke(cli.app, words)
    assert r.exit_code == 0, (command, r.output)
    if redirect:
        Path(redirect).write_text(r.stdout)
    for w in words:  # files the command was asked to write exist
        if w.endswith((".png", ".pdf", ".svg")) or w == "used.toml":
            assert (workdir / w).is_file(), (command, w)


def test_match_table_in_the_readme_is_current():
    require_log("intel")
    shown = _shown_table(_section("Command line"), "scanclique match intel 120 121")
    assert {"pose x", "pose y", "clique size", "error translation", "verdict"} <= set(shown)
    r = runner.invoke(cli.app, ["match", "intel", "120", "121"])
    assert r.exit_code == 0, r.output
    actual = {}
    for line in r.stdout.splitlines():
        cells = [c.strip() for c in line.strip("│").split("│")]
        if len(cells) == 3 and cells[0]:
            actual.setdefault(cells[0], cells[1])
    for metric, value in shown.items():
        assert metric in actual, metric
        assert _close(value, actual[metric]), (metric, value, actual[metric])


def test_python_example_pose_is_current():
    path = require_log("intel")
    import scanclique as sc

    section = _section("Python")
    code = _blocks(section, "python")[0]
    m = re.search(r"match_scans\(scans\[(\d+)\], scans\[(\d+)\]\)", code)
    shown = re.search(r"# \(([-\d.]+), ([-\d.]+), ([-\d.]+)\)", code)
    assert m and shown
    scans = sc.read_scans(path)
    match = sc.match_scans(scans[int(m[1])], scans[int(m[2])])
    for s, v in zip(shown.groups(), (match.pose.x, match.pose.y, match.pose.theta), strict=True):
        assert _close(s, f"{v:.6f}"), (s, v)
