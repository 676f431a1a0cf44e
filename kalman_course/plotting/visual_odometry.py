"""Chapter 10 figures: real visual odometry, alone and fused with the IMU (and GNSS).

Built from the vocabulary, from plain arrays so that this layer needs nothing from the
chapters: :meth:`kalman_course.chapters.visual_odometry.VoComparison.tracks` and
``.drift_curves`` give exactly the mappings these functions take.
"""

from __future__ import annotations

from kalman_course.plotting.vocabulary import CURVE_COLORS, _points, _vector, plot_curves, plot_truth

__all__ = ["plot_vo_tracks", "plot_drift_by_length"]


def _mapping(value, name: str) -> dict:
    if not hasattr(value, "items") or len(value) == 0:
        raise ValueError(f"{name} must be a non-empty mapping of label -> values")
    if len(value) > len(CURVE_COLORS):
        raise ValueError(f"{name} can hold at most {len(CURVE_COLORS)} entries (one colour each), got {len(value)}")
    return dict(value)


def plot_vo_tracks(truth_xy, tracks, *, title="", ax=None, figsize=(7, 6)):
    """The drive seen from above: the truth and each estimate (VO alone, fused, ...).

    Parameters
    ----------
    truth_xy : array_like, shape (N, 2) or (N, 3)
        True positions (east, north[, up]), navigation frame, m.
    tracks : mapping of str to array_like, shape (M, 2) or (M, 3)
        Legend label -> positions of one estimate, m (e.g. ``comparison.tracks("ORB-SLAM2")``);
        drawn in :data:`~kalman_course.plotting.vocabulary.CURVE_COLORS` order, at most six.
    title : str
        Axes title.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new figure).
    figsize : tuple
        Size of the new figure.

    Returns
    -------
    matplotlib.figure.Figure
        Equal aspect, axes in metres, the legend under the axes (the tracks fill them).
    """
    truth_xy = _points(truth_xy, "truth_xy")
    tracks = {label: _points(xy, f"tracks[{label!r}]") for label, xy in _mapping(tracks, "tracks").items()}
    if ax is None:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=figsize)
    else:
        fig = ax.figure
    plot_truth(ax, truth_xy[:, 0], truth_xy[:, 1], lw=1.5)
    for (label, xy), color in zip(tracks.items(), CURVE_COLORS):
        ax.plot(xy[:, 0], xy[:, 1], color=color, lw=1.0, label=label)
    ax.plot(*truth_xy[0, :2], "o", color="black", ms=5, label="start (anchor)")
    ax.set(xlabel="east [m]", ylabel="north [m]", title=title)
    ax.set_aspect("equal")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize="small", frameon=False)
    return fig


def plot_drift_by_length(curves, *, title="", figsize=(12, 4)):
    """KITTI's drift metric per segment length: translational (%) and rotational (°/100 m).

    Parameters
    ----------
    curves : mapping of str to (array_like (L,), array_like (L,), array_like (L,))
        Legend label -> (segment lengths m, translational error %, rotational error °/100 m)
        of one estimate (e.g. ``comparison.drift_curves("ORB-SLAM2")``); at most six. NaN
        (a length without segments) is skipped.
    title : str
        Figure title.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the length axis; the legend on the right one.
    """
    import matplotlib.pyplot as plt

    curves = _mapping(curves, "curves")
    translation, rotation = {}, {}
    for label, triple in curves.items():
        if len(triple) != 3:
            raise ValueError(f"curves[{label!r}] must be (lengths, translational %, rotational °/100 m)")
        lengths = _vector(triple[0], f"curves[{label!r}] lengths")
        translation[label] = (lengths, _vector(triple[1], f"curves[{label!r}] translational", allow_nan=True,
                                               n=lengths.shape[0]))
        rotation[label] = (lengths, _vector(triple[2], f"curves[{label!r}] rotational", allow_nan=True,
                                            n=lengths.shape[0]))
    fig, (ax_t, ax_r) = plt.subplots(1, 2, figsize=figsize, sharex=True)
    for ax, data in ((ax_t, translation), (ax_r, rotation)):
        for line in plot_curves(ax, data, lw=1.5):
            line.set_marker("o")
            line.set_markersize(4)
        ax.set_xlabel("segment length [m]")
        ax.set_ylim(bottom=0.0)
    ax_t.set(ylabel="translational error [%]", title="translation")
    ax_r.set(ylabel="rotational error [°/100 m]", title="rotation")
    ax_r.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize="small")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig

