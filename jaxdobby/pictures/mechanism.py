"""Drawing of the lifting mechanism to scale, parts numbered as in the source study.

Parts (numbers of the source study, DESIGN.md §1): eccentric 8, ring link 9, bending arm 10,
link 11, big blade 12, tumbler 13, heald frame 16; ground pivots hatched. Coordinates are the
model's (x horizontal, y up, origin at the arm pivot B0) in millimetres, equal axis scales.

:func:`draw_pose` draws one :class:`~jaxdobby.pictures.pose.Pose` into an axes (solid, or as a
grey ghost) and returns its artists by part, so a caller — the animation, or a test measuring
the drawn link lengths — can reach them. ``element_values`` colours the arm element by element
(one value per finite element, e.g. a stress to come) through ``cmap``/``norm``.
:func:`mechanism_figure` is the labelled picture of a machine at a loom angle with the extreme
positions of the stroke ghosted behind it (``jaxdobby simulate --out`` writes it).
"""

from __future__ import annotations


import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.patches import Circle, Polygon, Rectangle

from ..machine import Machine
from ..plots import plt
from .pose import ArmSampling, Pose, arm_sampling, crank_angle_at, flexible_pose, rigid_pose

MM = 1e3
PARTS = {8: "eccentric", 9: "ring link", 10: "bending arm", 11: "link 11", 12: "big blade",
         13: "tumbler", 16: "heald frame"}
"""Part numbers of the source study and their names."""

DISC_MARGIN = 14.0
"""Radius of the eccentric disc beyond its eccentricity, for the picture only [mm]."""
FRAME_SIZE = (14.0, 160.0)
"""Heald frame seen edge-on (width, height) below its suspension point, picture only [mm]."""


def _segment(ax, a, b, **kw):
    (line,) = ax.plot([a[0], b[0]], [a[1], b[1]], solid_capstyle="round", **kw)
    return line


def _ground(ax, p, colour, size=9.0):
    """A fixed pivot: a small hatched triangle under the point [mm]."""
    tri = Polygon([p, p + (-size, -1.6 * size), p + (size, -1.6 * size)], closed=True,
                  facecolor="none", edgecolor=colour, hatch="///", lw=0.8, zorder=1)
    ax.add_patch(tri)
    return tri


def draw_pose(ax, pose: Pose, sampling: ArmSampling, *, ghost: bool = False,
              element_values=None, cmap="viridis", norm=None, arm_colour: str = "C0",
              joints: bool = True) -> dict[str, object]:
    """Draw ``pose`` (one instant) into ``ax`` in millimetres; returns the artists by part.

    Args:
        ghost: draw in light grey, thin, behind (the rigid mechanism under a flexible one).
        element_values: optional (n_elements,) values colouring the arm per finite element
            (a ``LineCollection`` with ``cmap`` and ``norm``); default one colour.
        arm_colour: colour of the arm without ``element_values``.
        joints: mark the pin joints.

    Returned keys: ``eccentric``, ``crank``, ``ring_link``, ``arm``, ``link11``, ``blade``,
    ``tumbler``, ``heald_frame``, ``guide`` (line artists have their joint-to-joint data in mm).
    """
    p = {k: np.asarray(v, dtype=float) * MM for k, v in pose._asdict().items()}
    grey = "0.72"
    colour = grey if ghost else "0.15"
    lw = 1.0 if ghost else 2.2
    z = 1 if ghost else 3
    kw = dict(color=colour, lw=lw, zorder=z)
    art = {}
    e = float(np.linalg.norm(p["eccentric_pin"] - p["eccentric_axis"]))
    art["eccentric"] = ax.add_patch(Circle(p["eccentric_pin"], e + DISC_MARGIN, fill=False,
                                           edgecolor=colour, lw=0.8 * lw, zorder=z))
    art["crank"] = _segment(ax, p["eccentric_axis"], p["eccentric_pin"], ls=":", **kw)
    art["ring_link"] = _segment(ax, p["eccentric_pin"], p["ring_joint"], **kw)
    if element_values is not None and not ghost:
        pts = p["arm"]
        segs = np.stack([pts[:-1], pts[1:]], axis=1)
        coll = LineCollection(segs, cmap=cmap, norm=norm, lw=2.2 * lw, zorder=z + 1,
                              capstyle="round")
        coll.set_array(np.asarray(element_values, dtype=float)[sampling.element])
        art["arm"] = ax.add_collection(coll)
    else:
        (art["arm"],) = ax.plot(p["arm"][:, 0], p["arm"][:, 1], color=grey if ghost else arm_colour,
                                lw=1.6 * lw, solid_capstyle="round", zorder=z + 1)
    art["link11"] = _segment(ax, p["link11_joint"], p["blade_pin"], **kw)
    art["blade"] = ax.add_patch(Polygon([p["blade_pivot"], p["blade_pin"], p["tumbler_joint"]],
                                        closed=True, facecolor="none" if ghost else "0.88",
                                        edgecolor=colour, lw=0.8 * lw, zorder=z))
    art["blade_input"] = _segment(ax, p["blade_pivot"], p["blade_pin"], **kw)
    art["blade_output"] = _segment(ax, p["blade_pivot"], p["tumbler_joint"], **kw)
    art["tumbler"] = _segment(ax, p["tumbler_joint"], p["heald_frame"], **kw)
    w, h = FRAME_SIZE
    art["heald_frame"] = ax.add_patch(Rectangle(p["heald_frame"] - (0.5 * w, h), w, h,
                                                facecolor="none" if ghost else "C1",
                                                edgecolor=colour, lw=0.8 * lw, zorder=z))
    if joints:
        pins = np.stack([p[k] for k in ("eccentric_pin", "ring_joint", "link11_joint",
                                        "blade_pin", "tumbler_joint", "heald_frame")])
        art["joints"] = ax.scatter(pins[:, 0], pins[:, 1], s=10 if ghost else 18,
                                   facecolor="white", edgecolor=colour, lw=0.8, zorder=z + 2)
    if not ghost:
        for k in ("eccentric_axis", "pivot", "blade_pivot"):
            _ground(ax, p[k], colour)
        fixed = np.stack([p[k] for k in ("eccentric_axis", "pivot", "blade_pivot")])
        ax.scatter(fixed[:, 0], fixed[:, 1], s=22, facecolor="white", edgecolor=colour,
                   lw=1.0, zorder=z + 2)
    return art


def label_parts(ax, pose: Pose) -> None:
    """Number the parts as in the source study, with leader lines, and list their names."""
    p = {k: np.asarray(v, dtype=float) * MM for k, v in pose._asdict().items()}
    arm_mid = p["arm"][len(p["arm"]) // 3]
    anchors = {
        8: (p["eccentric_pin"], (-40, -70)),
        9: (0.5 * (p["eccentric_pin"] + p["ring_joint"]), (-60, 30)),
        10: (arm_mid, (-75, 40)),
        11: (0.5 * (p["link11_joint"] + p["blade_pin"]), (0, 45)),
        12: ((p["blade_pivot"] + p["blade_pin"] + p["tumbler_joint"]) / 3.0, (-80, -40)),
        13: (0.5 * (p["tumbler_joint"] + p["heald_frame"]), (-70, 0)),
        16: (p["heald_frame"] - (0.0, 0.5 * FRAME_SIZE[1]), (-70, 0)),
    }
    for number, (xy, (dx, dy)) in anchors.items():
        ax.annotate(str(number), xy=xy, xytext=(xy[0] + dx, xy[1] + dy), fontsize=10,
                    ha="center", va="center", zorder=6,
                    bbox=dict(boxstyle="circle,pad=0.2", fc="white", ec="0.3", lw=0.7),
                    arrowprops=dict(arrowstyle="-", color="0.3", lw=0.7))
    text = "\n".join(f"{n}  {name}" for n, name in PARTS.items())
    ax.text(0.02, 0.02, text, transform=ax.transAxes, fontsize=8, va="bottom", ha="left",
            family="monospace", bbox=dict(fc="white", ec="0.7", lw=0.6))


def frame_axes(ax, poses) -> None:
    """Equal scales in mm, limits that hold every pose in ``poses`` with a margin."""
    pts = np.concatenate([np.concatenate([np.reshape(np.asarray(v), (-1, 2)) for v in pose])
                          for pose in poses]) * MM
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    lo = lo - (60.0, 60.0 + FRAME_SIZE[1])
    hi = hi + (60.0, 60.0)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]  (origin: arm pivot)")
    ax.set_ylabel("y [mm]")
    ax.grid(alpha=0.2)


def mechanism_figure(machine: Machine, loom_angle_deg: float = 180.0, *,
                     sampling: ArmSampling | None = None, q=None, magnification: float = 1.0,
                     title: str | None = None):
    """The labelled drawing of ``machine`` at a loom angle [deg], to scale.

    Args:
        loom_angle_deg: main-shaft angle from the middle of the bottom dwell (0…720 over a
            heald-frame cycle; the frame is at the top at 360). Default 180: mid-lift.
        sampling: :func:`~jaxdobby.pictures.pose.arm_sampling` of the machine (computed if None).
        q: optional modal coordinates (k,) of the arm at that instant: the arm is drawn deformed
            (× ``magnification``) over the rigid one.
        title: default names the machine's stroke, arm section and loom angle.

    The bottom and top positions of the rigid stroke are ghosted behind the drawing.
    """
    sampling = arm_sampling(machine) if sampling is None else sampling
    cranks = crank_angle_at(machine, np.radians([0.0, 360.0, loom_angle_deg]))
    poses = rigid_pose(machine, cranks, sampling)  # bottom, top and the loom angle's, at once
    ends_list, crank, rigid = [poses.at(0), poses.at(1)], cranks[2], poses.at(2)
    fig, ax = plt.subplots(figsize=(7.2, 7.4), layout="constrained")
    for pose in ends_list:
        draw_pose(ax, pose, sampling, ghost=True, joints=False)
    shown = rigid
    if q is not None:
        draw_pose(ax, rigid, sampling, ghost=True)
        shown = flexible_pose(machine, crank, sampling, q, magnification)
    draw_pose(ax, shown, sampling, arm_colour="C0" if q is None else "C3")
    label_parts(ax, shown)
    frame_axes(ax, ends_list + [shown])
    ax.axvline(float(machine.chain.frame_guide_x) * MM, color="0.6", lw=0.6, ls="--", zorder=0)
    if title is None:
        arm = machine.arm
        title = (f"Lifting mechanism to scale at loom angle {loom_angle_deg:g}° "
                 f"(stroke {float(machine.stroke()) * MM:.0f} mm, arm "
                 f"{float(arm.thickness) * MM:g} × {float(np.max(arm.depth)) * MM:g} mm)\n"
                 "grey: the rigid mechanism at the bottom and the top of the stroke")
    ax.set_title(title, fontsize=9)
    return fig
