"""The whole frame set of a weave in one vmapped batch (``jaxdobby loom``).

Every frame has its own identical lifting unit (DESIGN.md §7); frames differ in their lift
sequence (a column of the weave's lift plan, all of the repeat's length P) and their stroke,
set by the link-11 joint's position on the arm (the differentiable root solve of
:func:`jaxdobby.stroke.arc_length_for_stroke`, done per frame before the batch, where an
unreachable stroke is an :class:`~jaxdobby.errors.InputError`). For a clean shed the stroke
grows with the frame's distance from the cloth fell, H_i = H₁·L_i/L₁ with
L_i = L₁ + (i − 1)·pitch (similar triangles).

:func:`run_frames` runs ``jax.vmap`` of :func:`jaxdobby.simulate.simulate` over (plan, joint
position): one compiled program for the set, whatever the number of frames; a frame whose plan
never moves is static — left out of the batch and answered without dynamics by
:func:`~jaxdobby.simulate.simulate` with its concrete plan (:mod:`jaxdobby.weave.static`: the
equilibrium at the top or bottom of its stroke; its deviation is the constant static
deflection there, its peak-to-peak, dwell vibration and acceleration zero).
Each moving frame carries the validity warnings of a single run (:func:`frame_warnings`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import InputError
from ..machine import Machine, OperatingPoint
from ..programs import ONE_SHOT, call_program, stored_call
from ..simulate import simulate
from ..stroke import arc_length_for_stroke
from ..validity import validity_arrays, warnings_of
from .plan import moves, plan_text

CHUNK = 16
"""Frames per vmapped call (the progress unit of a large set)."""


def clean_shed_strokes(frames: int, front_stroke, frame_pitch, fell_distance) -> np.ndarray:
    """Strokes H_i = H₁·(L₁ + (i − 1)·pitch)/L₁ of frames 1…n [same unit as H₁]."""
    if fell_distance <= 0 or frame_pitch < 0 or front_stroke <= 0:
        raise InputError("--front-stroke and --fell-distance must be > 0 and --frame-pitch >= 0")
    return front_stroke * (fell_distance + frame_pitch * np.arange(frames)) / fell_distance


def joint_positions(machine: Machine, strokes_m) -> np.ndarray:
    """Link-11 arc length [m] of each frame's stroke [m]; an unreachable one: InputError."""
    out = []
    for i, h in enumerate(np.asarray(strokes_m, dtype=float)):
        try:
            out.append(float(arc_length_for_stroke(machine.chain, h)))
        except ValueError as err:
            raise InputError(f"frame {i + 1}: stroke {h * 1e3:.1f} mm: {err}") from None
    return np.array(out)


def frame_run(machine: Machine, operating: OperatingPoint, plan, stroke_m):
    """The :class:`~jaxdobby.simulate.Simulation` of one frame alone: its lift sequence (P,)
    and its stroke [m] (for ``jaxdobby loom --animate``, which needs the whole run)."""
    s = joint_positions(machine, [stroke_m])[0]
    return _simulate_frame(machine, operating, np.asarray(plan, dtype=float), float(s))


def _simulate_frame(machine: Machine, operating: OperatingPoint, plan, joint_position):
    """One frame's run: its lift sequence (P,) on the machine with the link-11 joint at
    ``joint_position`` (arc length on the slot [m]; traced in the batch, concrete alone)."""
    return simulate(machine.with_link11_arc_length(joint_position), operating, lift_plan=plan)


def _row(run) -> dict:
    return dict(run.metrics, **run.pick_metrics, converged=run.converged,
                deviation=run.series.deviation, t=run.series.t, periodicity=run.periodicity,
                **validity_arrays(run))


def _batch(machine, operating, plans, positions):
    def one(plan, s):
        return _row(_simulate_frame(machine, operating, plan, s))

    return jax.vmap(one)(plans, positions)


def _chunks(machine: Machine, operating: OperatingPoint, plan: np.ndarray, positions):
    """(moving frames' indices, and per chunk of :data:`CHUNK` of them: their indices and
    the batch's arguments, padded to a fixed size — one program — by repeating the chunk's
    last frame)."""
    frames = plan.shape[1]
    moving = [i for i in range(frames) if np.any(moves(plan[:, i]))]
    chunks = []
    for start in range(0, len(moving), CHUNK):
        idx = moving[start:start + CHUNK]
        pad = idx + [idx[-1]] * (min(CHUNK, len(moving)) - len(idx))
        chunks.append((idx, (machine, operating, jnp.asarray(plan[:, pad].T),
                             jnp.asarray(positions[pad]))))
    return moving, chunks


def frames_program(machine: Machine, operating: OperatingPoint, plan: np.ndarray, strokes_m,
                   directory=None) -> tuple:
    """(exported program, argument specs, file name) of the first chunk of
    :func:`run_frames`' batch (:func:`jaxdobby.programs.call_program`), without compiling."""
    plan = np.asarray(plan, dtype=float)
    _, chunks = _chunks(machine, operating, plan, joint_positions(machine, strokes_m))
    return call_program("loom-frames", _batch, chunks[0][1], directory=directory)


def run_frames(machine: Machine, operating: OperatingPoint, plan: np.ndarray, strokes_m,
               progress=None, *, directory=None, ship=None) -> list[dict]:
    """Per frame (SI): the metrics of :func:`simulate` over the repeat, the per-pick ones, the
    deviation series; ``plan`` (picks, frames) of 0/1, ``strokes_m`` (frames,) [m].

    ``progress(done, total)`` is called after each chunk of :data:`CHUNK` frames. The batch
    of a chunk is a stored program (:func:`jaxdobby.programs.stored_call`, kept in
    ``directory``: a later run of a weave of as many picks and moving frames skips tracing
    it), compiled once per process — or loaded compiled, for the weaves whose program ships
    with the package (:func:`ship_programs`). ``ship``: where to write the compiled
    executable (``python -m jaxdobby.programs``)."""
    plan = np.asarray(plan, dtype=float)
    frames = plan.shape[1]
    positions = joint_positions(machine, strokes_m)
    moving, chunks = _chunks(machine, operating, plan, positions)
    rows: list[dict] = [dict() for _ in range(frames)]
    done = 0
    for idx, args in chunks:
        out = stored_call("loom-frames", _batch, args, directory=directory,
                          compiler_options=ONE_SHOT, ship=ship)
        out = jax.tree.map(np.asarray, out)
        for j, i in enumerate(idx):
            rows[i] = {k: v[j] for k, v in out.items()}
        done += len(idx)
        if progress is not None:
            progress(done, len(moving))
    for i in range(frames):
        if i not in moving:  # static: the concrete plan takes simulate's equilibrium path
            run = _simulate_frame(machine, operating, plan[:, i], float(positions[i]))
            rows[i] = jax.tree.map(np.asarray, _row(run))
        rows[i].update(frame=i + 1, stroke=float(np.asarray(strokes_m)[i]),
                       lift_plan=plan_text(plan[:, i]), static=i not in moving)
    speed = float(operating.speed)
    for row in rows:
        row["warnings"] = [] if row["static"] else frame_warnings(row, speed)
    return rows


SHIPPED_WEAVE = ("twill22", 8)
"""The named weave and frame count whose batch program ships compiled (:func:`ship_programs`):
a repeat of 4 picks on 8 moving frames, which is also twill31's and basket22's on 8 frames
(the program depends on the number of picks and moving frames, not on the plan, the speed or
the strokes)."""


def shipped_weave_args():
    """(machine, operating, plan, strokes [m]) of ``jaxdobby loom --weave twill22`` with the
    built-in machine and the default clean-shed strokes (:data:`SHIPPED_WEAVE`)."""
    from ..parameters import Setup
    from .defaults import DEFAULTS
    from .named import named_plan

    setup = Setup()
    weave, frames = SHIPPED_WEAVE
    strokes = clean_shed_strokes(frames, DEFAULTS["front_stroke"], DEFAULTS["frame_pitch"],
                                 DEFAULTS["fell_distance"])
    return setup.machine, setup.operating, named_plan(weave, frames), strokes * 1e-3


def ship_programs(directory) -> None:
    """Compile the batch of :data:`SHIPPED_WEAVE` into ``directory`` (the traced program and
    its executable; ``python -m jaxdobby.programs``), running it once."""
    machine, operating, plan, strokes = shipped_weave_args()
    run_frames(machine, operating, plan, strokes, directory=directory, ship=directory)


def frame_warnings(row: dict, speed: float, tolerance: float = 1e-6) -> list[dict]:
    """The validity warnings (:func:`jaxdobby.validity.warnings_of`) of one moving frame's row
    of :func:`run_frames` at ``speed`` [rad/s]; ``tolerance``: simulate's periodicity. The
    arm's stress is not computed in the batch, so there is no stress check."""
    arrays = {k: v for k, v in row.items() if k.startswith("validity.")}
    arrays.update(converged=row["converged"], periodicity=row["periodicity"],
                  stroke=row["stroke"], speed=speed, **{"metric.deviation_pp": row["deviation_pp"]})
    return warnings_of(arrays, tolerance)
