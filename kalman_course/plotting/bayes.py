"""Chapter 01 figures: beliefs of the histogram filter."""

from __future__ import annotations

import numpy as np

from kalman_course.plotting.vocabulary import COLORS, _vector, plot_belief

__all__ = ["plot_belief_sequence"]


def plot_belief_sequence(beliefs, *, titles=None, true_cells=None, doors=None, figsize=None):
    """Chapter 01: one bar chart per belief, stacked, with the true cell and the doors.

    Parameters
    ----------
    beliefs : sequence of array_like, each shape (n,)
        The beliefs to show, top to bottom.
    titles : sequence of str, optional
        One title per panel.
    true_cells : sequence of int, optional
        The robot's true cell in each panel (a red line).
    doors : array_like of bool, shape (n,), optional
        Which cells have a door (shaded grey in every panel).
    figsize : tuple, optional
        Figure size; default ``(8, 1.8 * len(beliefs))``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    if isinstance(beliefs, (str, bytes)) or not np.iterable(beliefs):
        raise ValueError(f"beliefs must be a sequence of beliefs (1-D arrays of cell weights), "
                         f"got {type(beliefs).__name__}: {beliefs!r:.60}")
    beliefs = [_vector(b, f"beliefs[{i}]") for i, b in enumerate(beliefs)]
    if not beliefs:
        raise ValueError("beliefs must contain at least one belief")
    n = beliefs[0].size
    for i, b in enumerate(beliefs):
        if b.size != n:
            raise ValueError(f"beliefs[{i}] has {b.size} cells, beliefs[0] has {n}")
    k = len(beliefs)
    for name, seq in (("titles", titles), ("true_cells", true_cells)):
        if seq is not None and len(seq) != k:
            raise ValueError(f"{name} must have one entry per belief ({k}), got {len(seq)}")
    door_mask = None
    if doors is not None:
        door_mask = np.asarray(doors, dtype=bool)
        if door_mask.shape != (n,):
            raise ValueError(f"doors must have shape ({n},), got {door_mask.shape}")
    fig, axes = plt.subplots(k, 1, figsize=figsize or (8, 1.8 * k), sharex=True, squeeze=False)
    axes = axes[:, 0]
    top = max(float(np.max(b)) for b in beliefs) * 1.1 or 1.0
    for i, (ax, b) in enumerate(zip(axes, beliefs)):
        if door_mask is not None:
            for c in np.flatnonzero(door_mask):
                ax.axvspan(c - 0.5, c + 0.5, color="0.9", lw=0,
                           label="door" if c == np.flatnonzero(door_mask)[0] else None)
        plot_belief(ax, b, label="belief")
        if true_cells is not None:
            ax.axvline(true_cells[i], color=COLORS["marker"], lw=2, label="true cell")
        if titles is not None:
            ax.set_title(titles[i], fontsize=10)
        ax.set_ylim(0, top)
        ax.set_ylabel("p")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("cell")
    axes[-1].xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    return fig
