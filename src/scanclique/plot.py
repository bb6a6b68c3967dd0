"""Figures of the paper (Bailey et al. 2000, Fig. 8–10): features of a scan, and one scan
overlaid on the other by the matched pose with the feature mapping drawn in.

matplotlib is imported inside the functions (it is an optional dependency: ``pip install
scanclique[plot]``); the core never imports this module. Without a display (Linux with
neither ``DISPLAY`` nor ``WAYLAND_DISPLAY``, and no ``MPLBACKEND``) the Agg backend is
selected before pyplot is first imported.

Examples
--------
>>> import numpy as np, tempfile, pathlib
>>> import scanclique as sc
>>> ang = np.radians(np.arange(-90, 91, 1.0))
>>> r = 2.0 / np.cos(np.clip(ang, -1.2, 1.2))
>>> r[88:92] = 1.0  # a pole in front of a wall
>>> scan = sc.Scan.from_ranges(r)
>>> ax = plot_features(scan, sc.extract_features(scan))
>>> out = save_figure(ax.figure, pathlib.Path(tempfile.mkdtemp()) / "features.png")
>>> out.stat().st_size > 5_000
True
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .features import CORNER, EDGE_CCW, EDGE_CW, FOREGROUND_POINT, Features
from .geometry import Pose2
from .kinds import kind_name
from .scan import Scan

__all__ = [
    "plot_features", "plot_match", "plot_located", "save_figure", "ellipse_outline",
    "FEATURE_STYLE",
]  # fmt: skip

#: marker, colour and legend label of each point-feature kind
FEATURE_STYLE = {
    FOREGROUND_POINT: ("o", "tab:green", "foreground point"),
    EDGE_CW: ("v", "tab:orange", "edge (cw)"),
    EDGE_CCW: ("^", "tab:purple", "edge (ccw)"),
    CORNER: ("s", "tab:red", "corner"),
}
_OTHER_COLOURS = ("tab:brown", "tab:pink", "tab:olive", "tab:cyan")
_LINE_COLOUR = "tab:blue"
_A_COLOUR = "0.35"
_B_COLOUR = "tab:orange"
_CLUSTER_COLOURS = ("#8c8c8c", "#b0b0b0")


def ellipse_outline(mean, cov, nsig: float = 3.0, n: int = 24) -> np.ndarray:
    """The ``nsig``-sigma ellipse of a 2-D Gaussian (``mean`` (2,), ``cov`` (2, 2)) as
    ``n`` points (n, 2) on its outline, the first repeated last (a closed polyline).

    >>> ellipse_outline([1.0, 0.0], np.diag([4.0, 1.0]), nsig=1.0, n=5).round(6).tolist()[:2]
    [[1.0, 1.0], [3.0, 0.0]]
    """
    w, v = np.linalg.eigh(np.asarray(cov, dtype=float))
    t = np.linspace(0, 2 * math.pi, n)
    circle = np.sqrt(np.maximum(w, 0.0))[:, None] * nsig * np.vstack([np.cos(t), np.sin(t)])
    return (v @ circle).T + np.asarray(mean, dtype=float)


def _pyplot():
    """pyplot, choosing the Agg backend first when there is no display."""
    import matplotlib

    headless = sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )
    if headless and "MPLBACKEND" not in os.environ and "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _sensor_size(points: np.ndarray) -> float:
    if len(points) == 0:
        return 0.3
    extent = float(np.ptp(points, axis=0).max())
    return float(np.clip(0.025 * extent, 0.2, 1.2))


def _draw_sensor(ax, pose: Pose2, size: float, colour: str, label: str | None = None):
    """The sensor as a triangle pointing along its +x axis (the paper's convention)."""
    tri = np.array([[size, 0.0], [-0.5 * size, 0.45 * size], [-0.5 * size, -0.45 * size]])
    xy = pose.transform(tri)
    from matplotlib.patches import Polygon

    ax.add_patch(
        Polygon(xy, closed=True, facecolor=colour, edgecolor="black", lw=0.8, zorder=6, label=label)
    )


def _cluster_polylines(scan: Scan, features: Features, pose: Pose2) -> list[np.ndarray]:
    xy = scan.xy()
    out = []
    for start, stop in features.clusters:
        seg = xy[start:stop]
        seg = seg[np.isfinite(seg).all(axis=1)]
        if len(seg) >= 2:
            out.append(pose.transform(seg))
    return out


def _draw_scan_features(
    ax,
    scan: Scan,
    features: Features,
    *,
    pose: Pose2 | None = None,
    point_colour: str = _A_COLOUR,
    line_colour: str = _LINE_COLOUR,
    labels: bool = True,
    label_prefix: str = "",
    scan_label: str = "scan points",
    sensor_colour: str = "gold",
    line_label: str = "line",
    sensor_label: str = "sensor",
    point_size: float = 5.0,
    line_width: float = 2.4,
):
    """Raw points, clusters, line segments, point features by kind and the sensor, mapped
    into the axes' frame by ``pose`` (identity: the scan's own sensor frame)."""
    from matplotlib.collections import LineCollection

    T = pose or Pose2.identity()
    pts = T.transform(scan.points()) if scan.n_valid else np.zeros((0, 2))
    # clusters: thin polylines through consecutive points, alternating shades
    polys = _cluster_polylines(scan, features, T)
    if polys:
        colours = [_CLUSTER_COLOURS[i % 2] for i in range(len(polys))]
        ax.add_collection(LineCollection(polys, colors=colours, linewidths=0.7, zorder=1))
    ax.scatter(
        pts[:, 0], pts[:, 1], s=point_size, c=point_colour, linewidths=0, zorder=2, label=scan_label
    )
    # line features: thick segments
    if features.n_lines:
        ends = T.transform(features.lines_ends.reshape(-1, 2)).reshape(-1, 2, 2)
        ax.add_collection(
            LineCollection(ends, colors=line_colour, linewidths=line_width, alpha=0.85, zorder=3)
        )
        ax.plot([], [], color=line_colour, lw=line_width, label=line_label)
        if labels:
            for i, seg in enumerate(ends):
                mid = seg.mean(axis=0)
                ax.annotate(
                    f"{label_prefix}L{i}",
                    mid,
                    fontsize=6,
                    color=line_colour,
                    zorder=7,
                    xytext=(2, 2),
                    textcoords="offset points",
                )
    # point features by kind
    if features.n_points:
        pxy = T.transform(features.points_xy)
        styles = dict(FEATURE_STYLE)
        others = sorted(set(np.unique(features.points_label).tolist()) - set(styles))
        for q, lab in enumerate(others):  # kinds registered in scanclique.kinds
            styles[lab] = ("D", _OTHER_COLOURS[q % len(_OTHER_COLOURS)], kind_name(lab))
        for kind, (marker, colour, name) in styles.items():
            sel = features.points_label == kind
            if sel.any():
                ax.scatter(
                    pxy[sel, 0],
                    pxy[sel, 1],
                    s=42,
                    marker=marker,
                    c=colour,
                    edgecolors="black",
                    linewidths=0.5,
                    zorder=5,
                    label=name,
                )
        if labels:
            for i, p in enumerate(pxy):
                ax.annotate(
                    f"{label_prefix}{i}",
                    p,
                    fontsize=6,
                    zorder=7,
                    xytext=(3, -8),
                    textcoords="offset points",
                )
    _draw_sensor(ax, T, _sensor_size(pts), sensor_colour, label=sensor_label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def plot_features(
    scan: Scan,
    features: Features,
    ax=None,
    title: str | None = None,
    *,
    labels: bool = True,
    legend: bool = True,
):
    """Draw one scan and its features (the paper's Fig. 8 and 9), in the sensor frame.

    Raw points (grey dots), clusters (thin grey polylines), line features (thick blue
    segments, labelled ``L<i>``), point features by kind (foreground point, edge cw,
    edge ccw, corner; labelled by their index in ``features.points_xy``) and the sensor as
    a triangle pointing along +x.

    Parameters
    ----------
    scan : Scan
    features : Features
        Features of ``scan`` (e.g. :func:`scanclique.extract_features` or
        ``ScanMatch.features_a``).
    ax : matplotlib Axes, optional
        Drawn into; a new figure when None.
    title : str, optional
    labels : bool
        Write feature indices next to the features.
    legend : bool
        Add a legend of the kinds present.

    Returns
    -------
    matplotlib Axes
    """
    if ax is None:
        plt = _pyplot()
        _, ax = plt.subplots(figsize=(7, 6), layout="constrained")
    _draw_scan_features(ax, scan, features, labels=labels)
    counts = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in features.counts().items() if v)
    ax.set_title(
        title if title is not None else f"{len(features)} features: {counts or 'none'}", fontsize=10
    )
    if legend:
        ax.legend(loc="best", fontsize=7, markerscale=1.0, framealpha=0.85)
    return ax


def _mapping_segments(match, pose: Pose2) -> tuple[np.ndarray, np.ndarray]:
    """Segments joining each mapped feature of A to its partner of B mapped into A:
    (point pairs, line pairs); for lines, the mid points of the segments."""
    fa, fb = match.features_a, match.features_b
    pts, lns = [], []
    for p in match.pairs:
        if p.kind == "line":
            a = fa.lines_ends[p.a].mean(axis=0)
            b = pose.transform(fb.lines_ends[p.b].mean(axis=0)[None])[0]
            lns.append((a, b))
        else:
            a = fa.points_xy[p.a]
            b = pose.transform(fb.points_xy[p.b][None])[0]
            pts.append((a, b))
    return np.array(pts).reshape(-1, 2, 2), np.array(lns).reshape(-1, 2, 2)


def _pair_names(match) -> list[str]:
    """``A2-B0`` for point pairs, then ``AL0-BL0`` for line pairs (the order of
    :func:`_mapping_segments`)."""
    pts = [f"A{p.a}-B{p.b}" for p in match.pairs if p.kind != "line"]
    lns = [f"AL{p.a}-BL{p.b}" for p in match.pairs if p.kind == "line"]
    return pts + lns


def _draw_overlay(ax, scan_a: Scan, scan_b: Scan, match, reference: Pose2 | None = None) -> None:
    """Scan B mapped into A's frame by ``match.pose`` with the mapping (the paper's Fig. 10)."""
    from matplotlib.collections import LineCollection

    if match.pose is None:
        ax.text(
            0.5,
            0.5,
            f"no pose:\n{match.reason or 'unknown reason'}",
            ha="center",
            va="center",
            wrap=True,
            fontsize=11,
            transform=ax.transAxes,
        )
        ax.set_title("B overlaid on A: undetermined", fontsize=10)
        ax.set_xticks([])
        ax.set_yticks([])
        return
    pose = match.pose
    _draw_scan_features(
        ax,
        scan_a,
        match.features_a,
        labels=False,
        scan_label="scan A",
        sensor_colour="gold",
        line_label="lines of A",
        sensor_label="sensor A",
        point_size=9,
        line_width=3.6,
    )
    _draw_scan_features(
        ax,
        scan_b,
        match.features_b,
        pose=pose,
        point_colour=_B_COLOUR,
        line_colour="tab:cyan",
        labels=False,
        scan_label="scan B (mapped)",
        sensor_colour="tab:orange",
        line_label="lines of B",
        sensor_label="sensor B (mapped)",
        point_size=9,
        line_width=1.5,
    )
    pt_segs, ln_segs = _mapping_segments(match, pose)
    segs = (
        np.concatenate((pt_segs, ln_segs)) if len(pt_segs) + len(ln_segs) else np.zeros((0, 2, 2))
    )
    if len(segs):
        ax.add_collection(LineCollection(segs, colors="crimson", linewidths=1.4, zorder=8))
        ends = segs.reshape(-1, 2)
        ax.scatter(ends[:, 0], ends[:, 1], s=10, c="crimson", zorder=8)
    for text, (a, b) in zip(_pair_names(match), np.concatenate((pt_segs, ln_segs)), strict=True):
        ax.annotate(
            text,
            (a + b) / 2,
            fontsize=6,
            color="crimson",
            zorder=9,
            xytext=(4, 4),
            textcoords="offset points",
        )
    ax.plot([], [], color="crimson", lw=1.4, label=f"mapped pairs ({len(match.pairs)})")
    if reference is not None:
        size = _sensor_size(scan_a.points()) if scan_a.n_valid else 0.3
        tri = np.array(
            [[size, 0.0], [-0.5 * size, 0.45 * size], [-0.5 * size, -0.45 * size], [size, 0.0]]
        )
        xy = reference.transform(tri)
        ax.plot(
            xy[:, 0], xy[:, 1], color="black", lw=1.0, ls="--", zorder=9, label="B's reference pose"
        )
    ax.set_title("B mapped into A's frame by the match pose, mapped features joined", fontsize=10)


def _pose_text(match) -> str:
    if match.pose is None:
        return f"no pose: {match.reason}"
    p = match.pose
    proven = "" if match.optimal else " (not proven maximum)"
    return (
        f"B in A: x = {p.x:.3f} m, y = {p.y:.3f} m, θ = {math.degrees(p.theta):.2f}°"
        f"   |   clique {match.clique_size} pairs{proven}, "
        f"score {match.score:.2f}, ambiguous: {'yes' if match.ambiguous else 'no'}"
    )


def plot_match(
    scan_a: Scan,
    scan_b: Scan,
    match,
    path_or_ax=None,
    *,
    reference: Pose2 | None = None,
    names: tuple[str, str] = ("A", "B"),
):
    """The paper's Fig. 8–10 for one match: features of A, features of B, and B overlaid on
    A by ``match.pose`` (B's points mapped by ``match.pose.transform``) with each mapped
    pair joined by a red segment (point pairs: A's point to B's point mapped into A; line
    pairs: the mid points of the two segments).

    Parameters
    ----------
    scan_a, scan_b : Scan
    match : ScanMatch
        ``match_scans(scan_a, scan_b)``. When ``match.pose`` is None the overlay panel
        says why (``match.reason``).
    path_or_ax : str, path-like, Figure, Axes, sequence of three Axes, or None
        A path: draw a new figure, save it there (PNG, PDF, SVG by suffix) and close it.
        A Figure: draw the three panels into it. One Axes: draw the overlay panel only.
        Three Axes: A, B and the overlay. None: a new figure, returned open.
    reference : Pose2, optional
        The reference pose of B in A (e.g. ``ref_a.inverse() @ ref_b``), drawn as a dashed
        triangle in the overlay.
    names : (str, str)
        Names of the scans for the panel titles.

    Returns
    -------
    matplotlib Figure
    """
    import matplotlib.axes
    import matplotlib.figure

    path = None
    fig = None
    axes = None
    if isinstance(path_or_ax, (str, os.PathLike)):
        path = Path(path_or_ax)
    elif isinstance(path_or_ax, matplotlib.figure.Figure):
        fig = path_or_ax
    elif isinstance(path_or_ax, matplotlib.axes.Axes):
        _draw_overlay(path_or_ax, scan_a, scan_b, match, reference)
        _overlay_legend(path_or_ax)
        return path_or_ax.figure
    elif isinstance(path_or_ax, Sequence) and len(path_or_ax) == 3:
        axes = list(path_or_ax)
        fig = axes[0].figure
    elif path_or_ax is not None:
        raise TypeError(
            f"path_or_ax must be a path, Figure, Axes or 3 Axes, got {type(path_or_ax).__name__}"
        )

    if axes is None:
        if fig is None:
            plt = _pyplot()
            fig = plt.figure(figsize=(15, 8.5), layout="constrained")
        gs = fig.add_gridspec(2, 2, width_ratios=(1, 1.9))
        axes = [fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[:, 1])]
    ax_a, ax_b, ax_o = axes
    plot_features(
        scan_a,
        match.features_a,
        ax_a,
        legend=False,
        title=f"A = {names[0]}: {_counts(match.features_a)}",
    )
    plot_features(
        scan_b,
        match.features_b,
        ax_b,
        legend=False,
        title=f"B = {names[1]}: {_counts(match.features_b)}",
    )
    _draw_overlay(ax_o, scan_a, scan_b, match, reference)
    _overlay_legend(ax_o)
    # one legend of the feature kinds for the two feature panels
    handles, labels = {}, []
    for ax in (ax_a, ax_b):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in handles:
                handles[lab] = h
                labels.append(lab)
    ax_b.legend(
        [handles[lab] for lab in labels],
        labels,
        loc="upper center",
        fontsize=7,
        ncol=4,
        bbox_to_anchor=(0.5, -0.13),
        frameon=False,
    )
    text = _pose_text(match)
    if reference is not None and match.pose is not None:
        t_err, r_err = match.pose.distance_to(reference)
        text += f"   |   error vs reference {t_err:.3f} m, {math.degrees(r_err):.2f}°"
    fig.suptitle(text, fontsize=11)
    if path is not None:
        save_figure(fig, path)
        _pyplot().close(fig)
    return fig


def _overlay_legend(ax) -> None:
    seen: dict = {}
    for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
        seen.setdefault(lab, h)
    if seen:
        ax.legend(list(seen.values()), list(seen), loc="best", fontsize=7, framealpha=0.85)


def _counts(features: Features) -> str:
    parts = [f"{v} {k.replace('_', ' ')}" for k, v in features.counts().items() if v]
    return f"{len(features)} features\n{', '.join(parts) or 'none'}"


FIGURE_SUFFIXES = frozenset(
    {".png", ".pdf", ".svg", ".svgz", ".eps", ".ps", ".jpg", ".jpeg", ".tif", ".tiff", ".webp"}
)
"""File name endings :func:`save_figure` writes (matplotlib picks the format from them)."""


def check_figure_path(path: str | os.PathLike, *, create_dirs: bool = False) -> Path:
    """``path`` as a :class:`~pathlib.Path` a figure can be written to, or an error.

    The rules: the name ends in one of :data:`FIGURE_SUFFIXES`; it is not an existing
    directory; its directory exists (it is never created: a typo must not make a new
    directory tree). Cheap, and needs no matplotlib, so commands check ``--plot`` before
    they do any work.

    Raises
    ------
    scanclique.errors.ArgumentError
        Naming the path and the rule it breaks.
    """
    from .errors import ArgumentError

    if not isinstance(path, (str, os.PathLike)):
        raise ArgumentError(f"figure path must be a file path, got {path!r}")
    p = Path(path)
    if p.is_dir():
        raise ArgumentError(f"{p} is a directory: give a file name such as {p / 'figure.png'}")
    suffix = p.suffix.lower()
    if suffix not in FIGURE_SUFFIXES:
        what = f"ends in {p.suffix!r}" if p.suffix else "has no suffix"
        raise ArgumentError(
            f"{p}: {what}; a figure file must end in one of {', '.join(sorted(FIGURE_SUFFIXES))}"
        )
    parent = p.parent if str(p.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise ArgumentError(f"{p}: {parent} is not a directory")
    if not create_dirs and not parent.is_dir():
        raise ArgumentError(f"{p}: directory {parent} does not exist (it is not created)")
    return p


def save_figure(fig, path: str | os.PathLike, dpi: int = 130, *, create_dirs: bool = True) -> Path:
    """Save ``fig`` to ``path`` (format from the suffix, checked by
    :func:`check_figure_path`; missing parent directories are created when
    ``create_dirs``, the default for scripts; the commands check ``--plot`` with
    ``create_dirs=False`` first)."""
    p = check_figure_path(path, create_dirs=create_dirs)
    if create_dirs and not p.parent.exists():
        p.parent.mkdir(parents=True, exist_ok=True)
    try:
        fig.savefig(p, dpi=dpi)
    except OSError as exc:
        from .errors import ArgumentError

        raise ArgumentError(f"{p}: cannot write the figure: {exc.strerror or exc}") from None
    return p


def plot_located(
    path: str | os.PathLike,
    places: Sequence[Pose2],
    located: Sequence[Pose2 | None],
    trajectory: Sequence[Pose2 | None] = (),
    title: str = "",
    tracked: Sequence[bool] = (),
) -> Path:
    """A figure of a log located in a place database's map
    (:func:`scanclique.places.run.run_locate`): the places' map positions (grey), each
    located scan's pose (green, a short tick along its heading; orange for those
    ``tracked`` flags, one flag per pose of ``located``) and, when given, the whole run
    carried into the map (blue line); metres, the map's frame. Returns the path
    written."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 8))
    xy = np.array([[p.x, p.y] for p in places]).reshape(-1, 2)
    ax.plot(xy[:, 0], xy[:, 1], "s", color="0.45", ms=3, zorder=3, label=f"places ({len(xy)})")
    run = np.array([[p.x, p.y] for p in trajectory if p is not None]).reshape(-1, 2)
    if len(run):
        ax.plot(run[:, 0], run[:, 1], "-", color="tab:blue", lw=0.8, label="the run, carried")
    flags = list(tracked) or [False] * len(located)
    size = 0.03 * max(np.ptp(xy[:, 0]) if len(xy) else 1.0, 1.0)
    for kind, colour, label in ((False, "tab:green", "located"), (True, "tab:orange", "tracked")):
        hit = [p for p, f in zip(located, flags, strict=True) if p is not None and f == kind]
        if not hit:
            continue
        q = np.array([[p.x, p.y, p.theta] for p in hit])
        ax.quiver(q[:, 0], q[:, 1], np.cos(q[:, 2]), np.sin(q[:, 2]), color=colour,
                  angles="xy", scale_units="xy", scale=1.0 / size, width=0.003)  # fmt: skip
        ax.plot(q[:, 0], q[:, 1], "o", color=colour, ms=3,
                label=f"{label} scans ({len(hit)} of {len(located)})")  # fmt: skip
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out
