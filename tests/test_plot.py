"""Figures (scanclique.plot): the paper's Fig. 8-10 are drawn and written as PNG."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import matplotlib  # noqa: E402

import scanclique as sc  # noqa: E402
from scanclique import plot  # noqa: E402

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def pair():
    return sc.sim.simulate_pair(np.random.default_rng(7))


@pytest.fixture(scope="module")
def matched(pair):
    return sc.match_scans(pair.scan_a, pair.scan_b)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plot._pyplot().close("all")


def _is_png(path) -> bool:
    return path.is_file() and path.read_bytes()[:8] == PNG_MAGIC and path.stat().st_size > 5000


def test_plot_features_draws_every_kind_present(pair, tmp_path):
    feats = sc.extract_features(pair.scan_a)
    ax = plot.plot_features(pair.scan_a, feats, title="scan A")
    assert ax.get_title() == "scan A"
    labels = set(ax.get_legend_handles_labels()[1])
    assert {"scan points", "sensor"} <= labels
    if feats.n_lines:
        assert "line" in labels
    for kind, (_, _, name) in plot.FEATURE_STYLE.items():
        assert (name in labels) == bool(np.any(feats.points_label == kind))
    out = plot.save_figure(ax.figure, tmp_path / "sub" / "features.png")
    assert _is_png(out)


def test_plot_match_writes_png(pair, matched, tmp_path):
    out = tmp_path / "match.png"
    fig = plot.plot_match(pair.scan_a, pair.scan_b, matched, out, reference=pair.pose_a_b)
    assert _is_png(out)
    assert len(fig.axes) == 3
    title = fig._suptitle.get_text()
    assert f"clique {matched.clique_size} pairs" in title
    assert "score" in title and "ambiguous" in title


def test_plot_match_into_figure_axes_and_three_axes(pair, matched):
    plt = plot._pyplot()
    fig = plt.figure()
    assert plot.plot_match(pair.scan_a, pair.scan_b, matched, fig) is fig
    assert len(fig.axes) == 3
    fig2, ax = plt.subplots()
    assert plot.plot_match(pair.scan_a, pair.scan_b, matched, ax) is fig2
    # the overlay joins every mapped pair
    assert f"mapped pairs ({len(matched.pairs)})" in ax.get_legend_handles_labels()[1]
    fig3, axes = plt.subplots(1, 3)
    plot.plot_match(pair.scan_a, pair.scan_b, matched, list(axes))
    assert axes[2].get_title().startswith("B mapped into A")
    fig4 = plot.plot_match(pair.scan_a, pair.scan_b, matched)
    assert isinstance(fig4, matplotlib.figure.Figure)
    with pytest.raises(TypeError):
        plot.plot_match(pair.scan_a, pair.scan_b, matched, 42)


def test_mapping_segments_follow_the_pose(matched):
    pose = matched.pose
    pts, lns = plot._mapping_segments(matched, pose)
    point_pairs = [p for p in matched.pairs if p.kind != "line"]
    line_pairs = [p for p in matched.pairs if p.kind == "line"]
    assert (len(pts), len(lns)) == (len(point_pairs), len(line_pairs))
    fa, fb = matched.features_a, matched.features_b
    for seg, p in zip(pts, point_pairs, strict=True):
        np.testing.assert_allclose(seg[0], fa.points_xy[p.a])
        np.testing.assert_allclose(seg[1], pose.transform(fb.points_xy[p.b][None])[0])
    for seg, p in zip(lns, line_pairs, strict=True):
        np.testing.assert_allclose(seg[0], fa.lines_ends[p.a].mean(axis=0))
        np.testing.assert_allclose(seg[1], pose.transform(fb.lines_ends[p.b]).mean(axis=0))


def test_plot_match_without_pose_says_why(tmp_path):
    empty = sc.Scan.from_ranges(np.full(181, np.nan))
    m = sc.match_scans(empty, empty)
    assert m.pose is None
    fig = plot.plot_match(empty, empty, m)
    texts = [t.get_text() for t in fig.axes[2].texts]
    assert any(m.reason in t for t in texts)
    out = plot.save_figure(fig, tmp_path / "none.png")
    assert _is_png(out)


def test_core_does_not_import_matplotlib():
    code = "import sys, scanclique; scanclique.match_scans; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
