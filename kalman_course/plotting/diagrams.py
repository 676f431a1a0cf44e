"""Block diagrams drawn with Matplotlib: the Bayes filter's loop (chapter 01) and the ESKF's
(chapter 08).

:func:`draw_block_diagram` draws boxes with text and the arrows between them on an axes
whose data coordinates are the layout's; :func:`plot_bayes_filter_diagram` and
:func:`plot_eskf_diagram` are the course's two diagrams built from it. Each returns a
:class:`Diagram` that names its boxes and arrows, so that a test can check what is
connected to what, that every text fits in its box and that no arrow runs through a box.

Box kinds and their colours: ``"state"`` (a belief or estimate, light blue),
``"process"`` (a step of the filter, white), ``"sensor"`` (data coming in, grey),
``"output"`` (what leaves the filter, light green). Nothing here changes global
Matplotlib state.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from kalman_course.plotting.vocabulary import COLORS

__all__ = ["Box", "Arrow", "Diagram", "draw_block_diagram", "plot_bayes_filter_diagram", "plot_eskf_diagram"]

_FILL = {"state": "#dcecf7", "process": "white", "sensor": "0.9", "output": "#dff2d8"}
_EDGE = {"state": COLORS["estimate"], "process": "0.15", "sensor": "0.45", "output": COLORS["likelihood"]}
_SIDES = ("left", "right", "top", "bottom")


@dataclass(frozen=True)
class Box:
    """One box of a diagram: centre, size, text and kind.

    Attributes
    ----------
    x, y : float
        Centre, in the diagram's data coordinates.
    width, height : float
        Size, same units.
    text : str
        The text, lines separated by ``\\n``; Matplotlib mathtext (``$...$``) allowed.
    kind : {"state", "process", "sensor", "output"}
        Sets the colours.
    """

    x: float
    y: float
    width: float
    height: float
    text: str
    kind: str = "process"

    def side(self, name: str, offset: float = 0.0) -> tuple[float, float]:
        """The point on side ``name`` (left/right/top/bottom), moved by ``offset`` along it."""
        if name == "left":
            return self.x - self.width / 2, self.y + offset
        if name == "right":
            return self.x + self.width / 2, self.y + offset
        if name == "top":
            return self.x + offset, self.y + self.height / 2
        return self.x + offset, self.y - self.height / 2


@dataclass(frozen=True)
class Arrow:
    """One arrow of a diagram, from the box ``src`` to the box ``dst``.

    Attributes
    ----------
    src, dst : str
        Names of the boxes.
    label : str
        Text written beside the arrow ("" for none).
    src_side, dst_side : str, optional
        Where it leaves and enters (left/right/top/bottom); default: facing each other.
    src_offset, dst_offset : float
        Shift of the two ends along their sides.
    connection : str
        Matplotlib ``connectionstyle`` (``"arc3"`` is straight); ignored when ``via`` is given.
    via : sequence of (float, float)
        Corner points between the two ends: the arrow runs straight from corner to
        corner (for routes around other boxes).
    label_xy : (float, float), optional
        Where the label goes; default the midpoint of the two ends.
    label_ha : str
        Horizontal alignment of the label.
    dashed : bool
        Dashed line (a branch taken only sometimes).
    """

    src: str
    dst: str
    label: str = ""
    src_side: str | None = None
    dst_side: str | None = None
    src_offset: float = 0.0
    dst_offset: float = 0.0
    connection: str = "arc3"
    via: tuple = ()
    label_xy: tuple[float, float] | None = None
    label_ha: str = "center"
    dashed: bool = False


@dataclass
class Diagram:
    """A drawn block diagram.

    Attributes
    ----------
    figure : matplotlib.figure.Figure
    ax : matplotlib.axes.Axes
    boxes : dict of str to Box
        The layout.
    patches : dict of str to matplotlib.patches.FancyBboxPatch
        The drawn boxes, by name.
    texts : dict of str to matplotlib.text.Text
        The text of each box, by name.
    arrows : list of (Arrow, matplotlib.patches.FancyArrowPatch, matplotlib.text.Text or None)
        Each arrow, its patch and its label.
    """

    figure: object
    ax: object
    boxes: dict
    patches: dict = field(default_factory=dict)
    texts: dict = field(default_factory=dict)
    arrows: list = field(default_factory=list)

    def edges(self) -> set[tuple[str, str]]:
        """The (src, dst) pairs the arrows connect."""
        return {(a.src, a.dst) for a, _, _ in self.arrows}


def _facing(a: Box, b: Box) -> tuple[str, str]:
    dx, dy = b.x - a.x, b.y - a.y
    if abs(dx) >= abs(dy):
        return ("right", "left") if dx > 0 else ("left", "right")
    return ("top", "bottom") if dy > 0 else ("bottom", "top")


def draw_block_diagram(ax, boxes: Mapping[str, Box], arrows: Sequence[Arrow], *, fontsize=9,
                       limits=None) -> Diagram:
    """Draw boxes and arrows on ``ax`` (its axis lines are turned off).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw; its data coordinates are the layout's, with equal aspect.
    boxes : mapping of str to Box
        The boxes, by name (at least one).
    arrows : sequence of Arrow
        Arrows between named boxes.
    fontsize : float
        Size of the box texts (labels are one point smaller).
    limits : ((float, float), (float, float)), optional
        x and y limits; default the boxes' extent plus a margin.

    Returns
    -------
    Diagram
    """
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch
    from matplotlib.path import Path

    if not isinstance(boxes, Mapping) or not boxes:
        raise ValueError("boxes must be a non-empty mapping of name -> Box")
    for name, box in boxes.items():
        if not isinstance(box, Box):
            raise ValueError(f"boxes[{name!r}] must be a Box, got {type(box).__name__}")
        if box.kind not in _FILL:
            raise ValueError(f"boxes[{name!r}].kind must be one of {tuple(_FILL)}, got {box.kind!r}")
        if not (np.isfinite([box.x, box.y, box.width, box.height]).all() and box.width > 0 and box.height > 0):
            raise ValueError(f"boxes[{name!r}] needs a finite centre and a positive size")
    diagram = Diagram(figure=ax.figure, ax=ax, boxes=dict(boxes))
    pad = 0.08
    for name, box in boxes.items():
        patch = FancyBboxPatch((box.x - box.width / 2 + pad, box.y - box.height / 2 + pad),
                               box.width - 2 * pad, box.height - 2 * pad,
                               boxstyle=f"round,pad={pad},rounding_size=0.15", facecolor=_FILL[box.kind],
                               edgecolor=_EDGE[box.kind], lw=1.4 if box.kind == "process" else 1.0, zorder=2)
        ax.add_patch(patch)
        diagram.patches[name] = patch
        diagram.texts[name] = ax.text(box.x, box.y, box.text, ha="center", va="center", fontsize=fontsize,
                                      zorder=3, linespacing=1.35)
    for arrow in arrows:
        if not isinstance(arrow, Arrow):
            raise ValueError(f"arrows must hold Arrow objects, got {type(arrow).__name__}")
        for end in (arrow.src, arrow.dst):
            if end not in boxes:
                raise ValueError(f"arrow {arrow.src!r} -> {arrow.dst!r}: no box named {end!r}")
        a, b = boxes[arrow.src], boxes[arrow.dst]
        src_side, dst_side = _facing(a, b)
        src_side = arrow.src_side or src_side
        dst_side = arrow.dst_side or dst_side
        for side in (src_side, dst_side):
            if side not in _SIDES:
                raise ValueError(f"arrow {arrow.src!r} -> {arrow.dst!r}: side must be one of {_SIDES}, got {side!r}")
        start, end = a.side(src_side, arrow.src_offset), b.side(dst_side, arrow.dst_offset)
        style = dict(arrowstyle="-|>", mutation_scale=14, lw=1.3, color="0.2",
                     linestyle="--" if arrow.dashed else "-", shrinkA=0, shrinkB=0, zorder=1)
        if arrow.via:
            corners = np.asarray(arrow.via, dtype=float)
            if corners.ndim != 2 or corners.shape[1] != 2 or not np.all(np.isfinite(corners)):
                raise ValueError(f"arrow {arrow.src!r} -> {arrow.dst!r}: via must be finite (x, y) points")
            points = np.vstack([start, corners, end])
            patch = FancyArrowPatch(path=Path(points, [Path.MOVETO] + [Path.LINETO] * (len(points) - 1)),
                                    **style)
        else:
            patch = FancyArrowPatch(start, end, connectionstyle=arrow.connection, **style)
        ax.add_patch(patch)
        label = None
        if arrow.label:
            xy = arrow.label_xy or ((start[0] + end[0]) / 2, (start[1] + end[1]) / 2)
            label = ax.text(*xy, arrow.label, ha=arrow.label_ha, va="center", fontsize=fontsize - 1,
                            color="0.25", style="italic", zorder=3)
        diagram.arrows.append((arrow, patch, label))
    if limits is None:
        x0 = min(b.x - b.width / 2 for b in boxes.values()) - 0.4
        x1 = max(b.x + b.width / 2 for b in boxes.values()) + 0.4
        y0 = min(b.y - b.height / 2 for b in boxes.values()) - 0.4
        y1 = max(b.y + b.height / 2 for b in boxes.values()) + 0.4
        limits = ((x0, x1), (y0, y1))
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])
    ax.set_aspect("equal")
    ax.axis("off")
    return diagram


def _new_axes(ax, figsize):
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=figsize)
        fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.99)
    return ax


def plot_bayes_filter_diagram(ax=None, *, figsize=(12, 3.9)) -> Diagram:
    """Chapter 01: the Bayes filter as a loop: predict with the motion model, update with
    the measurement model by Bayes' rule, hand the posterior on, repeat.

    The conditioning on the initial estimate x̌₀ is left out of the densities for space.

    Parameters
    ----------
    ax : matplotlib.axes.Axes, optional
        Where to draw; default a new figure of size ``figsize``.
    figsize : tuple
        Size of the new figure.

    Returns
    -------
    Diagram
    """
    ax = _new_axes(ax, figsize)
    boxes = {
        "posterior_prev": Box(1.45, 3.0, 2.7, 1.3, "posterior at $k-1$\n$p(x_{k-1} \\mid v_{1:k-1}, y_{0:k-1})$",
                              "state"),
        "predict": Box(5.15, 3.0, 3.5, 1.7, "PREDICT\nmotion model $p(x_k \\mid x_{k-1}, v_k)$\n"
                       "total probability: $\\int \\ldots\\, dx_{k-1}$"),
        "prior": Box(8.55, 3.0, 2.5, 1.3, "prior at $k$\n$p(x_k \\mid v_{1:k}, y_{0:k-1})$", "state"),
        "update": Box(12.0, 3.0, 3.6, 1.7, "UPDATE\nmeasurement model $p(y_k \\mid x_k)$\n"
                      "Bayes' rule: $\\eta\\, p(y_k \\mid x_k)\\, \\times$ prior"),
        "posterior": Box(15.4, 3.0, 2.4, 1.3, "posterior at $k$\n$p(x_k \\mid v_{1:k}, y_{0:k})$", "state"),
        "input": Box(5.15, 5.6, 3.3, 1.0, "input $v_k$\n(odometry, IMU, a step command)", "sensor"),
        "start": Box(8.55, 5.6, 2.5, 1.0, "start: $p(x_0)$ from x̌₀\n(step 0: update only)", "state"),
        "observation": Box(12.0, 5.6, 3.0, 1.0, "observation $y_k$\n(GNSS, lidar, a door sensor)", "sensor"),
        "output": Box(15.4, 5.6, 2.4, 1.0, "output: the belief\nabout $x_k$", "output"),
    }
    arrows = [
        Arrow("posterior_prev", "predict"),
        Arrow("predict", "prior"),
        Arrow("prior", "update"),
        Arrow("update", "posterior"),
        Arrow("input", "predict"),
        Arrow("start", "prior"),
        Arrow("observation", "update"),
        Arrow("posterior", "output"),
        Arrow("posterior", "posterior_prev", "next step: $k \\leftarrow k + 1$, the posterior becomes the one "
              "the prediction starts from", src_side="bottom", dst_side="bottom",
              via=((15.4, 1.6), (1.45, 1.6)), label_xy=(8.45, 1.25)),
    ]
    return draw_block_diagram(ax, boxes, arrows, limits=((-0.05, 16.85), (0.85, 6.3)))


def plot_eskf_diagram(ax=None, *, figsize=(11, 7.6)) -> Diagram:
    """Chapter 08: the error-state Kalman filter's loop as a block diagram.

    The IMU drives the nominal state (mechanisation) and the error covariance; a pose
    (lidar) or position (GNSS) measurement triggers the update, whose estimated error is
    injected into the nominal state and then reset to zero; the corrected nominal state
    is the output, and the start of the next IMU step. Without a measurement, the prior
    is the posterior.

    Parameters
    ----------
    ax : matplotlib.axes.Axes, optional
        Where to draw; default a new figure of size ``figsize``.
    figsize : tuple
        Size of the new figure.

    Returns
    -------
    Diagram
    """
    ax = _new_axes(ax, figsize)
    cx, ox = 7.2, 12.4        # the filter's column; the output's
    boxes = {
        "imu": Box(1.9, 11.0, 3.2, 1.2, "IMU, 100 Hz\nspecific force f, rate ω", "sensor"),
        "nominal": Box(cx, 11.0, 5.2, 1.3, "nominal propagation (lecture 07)\n"
                       "p̂, v̂, R̂, b̂  →  p̌, v̌, Ř, b̌"),
        "covariance": Box(cx, 8.7, 5.2, 1.3, "error-covariance propagation\n"
                          "P̌ = F P̂ Fᵀ + B Q Bᵀ,  δx̌ = 0"),
        "sensor": Box(1.9, 6.4, 3.2, 1.2, "lidar pose, 10 Hz\nor GNSS position, 1 Hz", "sensor"),
        "update": Box(cx, 6.4, 5.2, 1.6, "update\nresidual y from x̌ and the measurement\n"
                      "K = P̌ Gᵀ (G P̌ Gᵀ + R)⁻¹,  δx̂ = K y"),
        "injection": Box(cx, 4.1, 5.2, 1.3, "injection (error = nominal − true)\n"
                         "p̂ = p̌ − δp̂,  R̂ = Ř Exp(−δθ̂),  …"),
        "reset": Box(cx, 2.0, 5.2, 1.2, "reset\nδx̂ ← 0  (P̂ kept, or Gᵣ P̂ Gᵣᵀ)"),
        "output": Box(ox, 2.0, 3.0, 1.2, "output\npose p̂, R̂ and velocity v̂", "output"),
    }
    arrows = [
        Arrow("imu", "nominal"),
        Arrow("imu", "covariance", "f, ω in F", src_side="bottom", dst_side="left", via=((1.9, 8.7),),
              label_xy=(2.05, 9.35), label_ha="left"),
        Arrow("nominal", "covariance", "Ř, b̌ in F and B", label_xy=(cx + 0.15, 9.85), label_ha="left"),
        Arrow("covariance", "update", "P̌  (when a measurement arrives)", label_xy=(cx + 0.15, 7.55),
              label_ha="left"),
        Arrow("sensor", "update"),
        Arrow("update", "injection", "δx̂, P̂", label_xy=(cx + 0.15, 5.25), label_ha="left"),
        Arrow("injection", "reset"),
        Arrow("reset", "output"),
        Arrow("covariance", "output", "no measurement:\nx̂ = x̌,  P̂ = P̌", src_side="right", dst_side="top",
              dst_offset=-0.6, via=((ox - 0.6, 8.7),), dashed=True,
              label_xy=(ox - 0.45, 5.6), label_ha="left"),
        Arrow("output", "nominal", "next IMU sample:\nstart from x̂, P̂", src_side="right", dst_side="right",
              via=((ox + 2.0, 2.0), (ox + 2.0, 11.0)), label_xy=(ox - 0.45, 10.1), label_ha="left"),
    ]
    return draw_block_diagram(ax, boxes, arrows, limits=((0.1, 14.9), (1.1, 11.9)))
