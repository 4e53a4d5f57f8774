"""Animation of one steady heald-frame cycle: the flexible arm over the rigid mechanism's ghost.

The cycle is the run's: two picks in plain weave, the repeat of P picks of a run with a lift
plan (the crank follows the plan, :func:`~jaxdobby.pictures.pose.crank_angle_at`).

Each frame draws, at loom angle ψ = speed·t, the rigid mechanism as a grey ghost and the
mechanism with the arm deformed by the run's modal coordinates q(t) (``Simulation.series.modal``
through the model's mode shapes, :func:`~jaxdobby.pictures.pose.flexible_pose`), the deformation
magnified by a factor shown in the frame (the blade, tumbler and heald frame follow the
magnified arm, so the frame's offset from its ghost is the magnified deviation). Beside it the
heald frame's true deviation (flexible − rigid) over the cycle, with the current instant marked.

Frames are evenly spaced over one cycle, t_i = T·i/n (the animation loops seamlessly); the
frame count and the pixel size (``figsize``·``dpi``) are fixed by the arguments, so two runs give
files of the same shape. GIFs are written by matplotlib's Pillow writer (no external program);
an ``.mp4`` path needs an ffmpeg binary (on the PATH, or from the optional ``imageio-ffmpeg``
package) and raises :class:`~jaxdobby.errors.InputError` without one.

Hook for a per-element colour (e.g. the arm's stress, once computed): ``element_values`` of
shape (n_frames, n_elements) colours the flexible arm element by element, with a colour bar
labelled ``colour_label``.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..kinematics import blade_reachable
from ..plots import plt
from .mechanism import MM, draw_pose, frame_axes
from .pose import arm_sampling, crank_angle_at, flexible_pose, rigid_pose

N_FRAMES = 48
FIGSIZE = (8.0, 4.6)
DPI = 80
TARGET_DEFLECTION = 0.2
"""Largest drawn arm deflection, as a fraction of the arm's length, that sets the automatic
magnification (rounded down to 1, 2 or 5 times a power of ten)."""


def frame_times(period: float, n_frames: int) -> np.ndarray:
    """t_i = T·i/n, i = 0…n−1 [s]: one cycle without repeating its first instant."""
    return period * np.arange(n_frames) / n_frames


def _periodic_interp(t, ts, values):
    """Values (n, ...) of a periodic series sampled at ``ts`` (first to last = one period),
    linearly interpolated at ``t``."""
    values = np.asarray(values, dtype=float)
    flat = values.reshape(values.shape[0], -1)
    out = np.stack([np.interp(t, ts, flat[:, j], period=ts[-1] - ts[0])
                    for j in range(flat.shape[1])], axis=-1)
    return out.reshape((len(t),) + values.shape[1:])


def auto_magnification(deflection_max: float, arm_length: float) -> float:
    """1, 2 or 5·10ⁿ, the largest not above TARGET_DEFLECTION·arm_length/deflection_max."""
    if deflection_max <= 0.0:
        return 1.0
    raw = TARGET_DEFLECTION * arm_length / deflection_max
    decade = 10.0 ** math.floor(math.log10(raw))
    return max(1.0, max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= raw))


def animation_frames(run, n_frames: int = N_FRAMES, magnification: float | None = None):
    """The poses of an animation: (loom angles [deg], rigid poses, flexible poses,
    magnification, deviation at the frames [m], sampling).

    ``run`` is a :class:`~jaxdobby.simulate.Simulation`; q and the deviation are interpolated
    linearly from its output times to the frame times.
    """
    model = run.model
    machine = model.machine
    sampling = arm_sampling(machine, model)
    ts = np.asarray(run.series.t)
    t = frame_times(float(model.period), n_frames)
    q = _periodic_interp(t, ts, run.series.modal)
    deviation = _periodic_interp(t, ts, run.series.deviation)
    psi = float(model.operating.speed) * t
    crank = crank_angle_at(machine, psi, model.lift_plan)
    factors = [magnification]
    if magnification is None:
        u = np.einsum("nik,fk->fni", sampling.modal_rows, q)
        top = auto_magnification(float(np.abs(u).max()), float(machine.arm.total_length))
        factors = [f for f in (top, top / 2, top / 5, top / 10) if f >= 1.0] or [1.0]
    rigid = rigid_pose(machine, crank, sampling)
    for factor in factors:  # the largest automatic factor that keeps the linkage closed
        flexible = flexible_pose(machine, crank, sampling, q, factor)
        closed = (np.all(np.asarray(blade_reachable(machine.chain, flexible.link11_joint)))
                  and np.all(np.isfinite(flexible.heald_frame)))
        if closed:
            break
    else:
        raise InputError(f"the arm's deformation magnified ×{factors[-1]:g} opens the linkage "
                         "(link 11 cannot reach the blade): choose a smaller factor")
    magnification = factor
    return np.degrees(psi), rigid, flexible, magnification, deviation, sampling


def animate(run, path, *, n_frames: int = N_FRAMES, magnification: float | None = None,
            fps: int = 12, element_values=None, colour_label: str = "", cmap="viridis",
            norm=None) -> Path:
    """Write the animation of ``run``'s steady cycle to ``path`` (``.gif`` or ``.mp4``).

    Args:
        run: a :class:`~jaxdobby.simulate.Simulation`.
        n_frames: frames over one cycle (the file has exactly this many).
        magnification: factor on the arm's deformation; default: automatic
            (:func:`auto_magnification`), written in each frame.
        fps: frames per second of the file.
        element_values: optional (n_frames, n_elements) values colouring the arm per element.
        colour_label, cmap, norm: their colour bar, colour map and normalisation (default: the
            values' range).
    Returns the path written.
    """
    from matplotlib import animation, colors

    path = Path(path)
    writer = _writer(path, fps)
    psi, rigid, flexible, mag, deviation, sampling = animation_frames(run, n_frames, magnification)
    series = run.series
    span = 360.0 * run.model.picks  # loom angle of the cycle (the repeat of a lift plan) [deg]
    cycle_angle = np.asarray(series.t) / float(run.model.period) * span
    fig, (ax, ax_dev) = plt.subplots(1, 2, figsize=FIGSIZE, dpi=DPI, layout="constrained",
                                     width_ratios=(3, 2))
    if element_values is not None:
        element_values = np.asarray(element_values, dtype=float)
        if element_values.shape != (n_frames, sampling.node_arc_lengths.size - 1):
            raise ValueError(f"element_values has shape {element_values.shape}; expected "
                             f"(n_frames, n_elements) = "
                             f"{(n_frames, sampling.node_arc_lengths.size - 1)}")
        norm = norm or colors.Normalize(element_values.min(), element_values.max())
        fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.7,
                     label=colour_label)
    frames = [rigid.at(i) for i in range(n_frames)]
    bent = [flexible.at(i) for i in range(n_frames)]
    ax_dev.plot(cycle_angle, np.asarray(series.deviation) * MM, color="C3", lw=1.0)
    ax_dev.axhline(0.0, color="k", lw=0.6)
    ax_dev.set_xlim(0.0, span)
    ax_dev.set_xticks(np.arange(0.0, span + 1.0, 180.0 if span <= 720.0 else 360.0))
    ax_dev.set_xlabel("loom angle [deg]  (0: bottom dwell)" if run.model.lift_plan is None
                      else "loom angle [deg]  (0: the last pick's dwell)")
    ax_dev.set_ylabel("heald-frame deviation [mm]\n(flexible − rigid, true size)")
    ax_dev.grid(alpha=0.3)
    (marker,) = ax_dev.plot([], [], "o", color="C3", ms=6)
    arm_points = np.concatenate([np.asarray(p.arm) for p in (rigid, flexible)]).reshape(-1, 2)
    arm_box = np.stack([arm_points.min(axis=0), arm_points.max(axis=0)]) * MM
    arm_box += np.array([[-15.0], [15.0]])
    speed_rpm = float(run.model.operating.speed) * 60.0 / (2.0 * math.pi)

    def draw(i):
        ax.cla()
        draw_pose(ax, frames[i], sampling, ghost=True)
        values = None if element_values is None else element_values[i]
        draw_pose(ax, bent[i], sampling, arm_colour="C3", element_values=values, cmap=cmap,
                  norm=norm)
        frame_axes(ax, frames + bent)
        ax.set_title(f"{speed_rpm:.0f} r/min, loom angle {psi[i]:5.1f}°, heald-frame deviation "
                     f"{deviation[i] * MM:+.3f} mm\ngrey: rigid; arm deformation ×{mag:g} (the "
                     "chain follows it)", fontsize=8)
        zoom = ax.inset_axes([0.02, 0.03, 0.5, 0.5])  # the empty lower left (cla removed it)
        draw_pose(zoom, frames[i], sampling, ghost=True)
        draw_pose(zoom, bent[i], sampling, arm_colour="C3", element_values=values, cmap=cmap,
                  norm=norm)
        zoom.set_xlim(*arm_box[:, 0])
        zoom.set_ylim(*arm_box[:, 1])
        zoom.set_aspect("equal")
        zoom.set_xticks([])
        zoom.set_yticks([])
        zoom.set_title("the arm, enlarged", fontsize=7, pad=2)
        marker.set_data([psi[i] % span], [deviation[i] * MM])
        return []

    anim = animation.FuncAnimation(fig, draw, frames=n_frames, blit=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(path, writer=writer, dpi=DPI)
    plt.close(fig)
    return path


def ffmpeg_binary() -> str | None:
    """Path of an ffmpeg binary: on the PATH, else the optional ``imageio-ffmpeg`` one."""
    found = shutil.which("ffmpeg")
    if found:
        return found
    try:
        import imageio_ffmpeg
    except ImportError:
        return None
    return imageio_ffmpeg.get_ffmpeg_exe()


def _writer(path: Path, fps: int):
    from matplotlib import animation

    suffix = path.suffix.lower()
    if suffix == ".gif":
        return animation.PillowWriter(fps=fps)
    if suffix == ".mp4":
        binary = ffmpeg_binary()
        if binary is None:
            raise InputError(f"--animate {path}: an .mp4 needs an ffmpeg binary (install ffmpeg "
                             "or `pip install imageio-ffmpeg`); a .gif needs nothing")
        plt.rcParams["animation.ffmpeg_path"] = binary
        return animation.FFMpegWriter(fps=fps)
    raise InputError(f"--animate {path}: the file must end in .gif or .mp4")
