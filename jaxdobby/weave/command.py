"""``jaxdobby loom``: the whole frame set of a weave (named, or a WIF file) in one vmapped
batch; a table per frame, ``--json``, ``--out DIR`` with CSV and figures."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ..errors import InputError

from .defaults import DEFAULTS
FRAMES_PER_PICK = 24
"""Images per pick of ``--animate`` (at most :data:`MAX_IMAGES` over the repeat)."""
MAX_IMAGES = 360


def add_arguments(p: argparse.ArgumentParser) -> None:
    from .named import WEAVES

    p.add_argument("wif", nargs="?", metavar="FILE.wif",
                   help="a WIF file with [LIFTPLAN] or [TIEUP] + [TREADLING]")
    p.add_argument("--weave", choices=list(WEAVES), help="a named weave instead of a file")
    p.add_argument("--frames", type=int, metavar="N",
                   help=f"frames of the named weave (default {DEFAULTS['frames']}); with a "
                        "file: the first N of its shafts")
    p.add_argument("--front-stroke", type=float, metavar="MM",
                   help=f"stroke of frame 1, nearest the fell [mm] (default "
                        f"{DEFAULTS['front_stroke']:g})")
    p.add_argument("--frame-pitch", type=float, metavar="MM",
                   help=f"distance between frames [mm] (default {DEFAULTS['frame_pitch']:g})")
    p.add_argument("--fell-distance", type=float, metavar="MM",
                   help=f"frame 1's distance from the cloth fell [mm] (default "
                        f"{DEFAULTS['fell_distance']:g}); H_i = H_1 L_i/L_1")
    p.add_argument("--strokes", type=float, nargs="+", metavar="MM",
                   help="every frame's stroke [mm] instead of the clean-shed rule")
    p.add_argument("--out", metavar="DIR", help="write frames.csv, loom.json and figures")
    p.add_argument("--animate", type=int, metavar="FRAME",
                   help="write an animation of frame FRAME's mechanism over the repeat "
                        f"(loom_frame<FRAME>.gif in --out DIR or here; {FRAMES_PER_PICK} "
                        "images per pick)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def _plan(ns) -> tuple[np.ndarray, str]:
    from .named import named_plan

    if (ns.wif is None) == (ns.weave is None):
        raise InputError("give either a WIF file or --weave (one of the two)")
    if ns.weave is not None:
        frames = DEFAULTS["frames"] if ns.frames is None else ns.frames
        return named_plan(ns.weave, frames), ns.weave
    from .wif import read_wif

    plan = read_wif(ns.wif)
    if ns.frames is not None:
        if not 1 <= ns.frames <= plan.shape[1]:
            raise InputError(f"--frames = {ns.frames}: {ns.wif} has {plan.shape[1]} shafts")
        plan = plan[:, :ns.frames]
    return plan, Path(ns.wif).name


def _strokes_mm(ns, frames: int) -> np.ndarray:
    from .loom import clean_shed_strokes

    if ns.strokes is not None:
        if len(ns.strokes) != frames:
            raise InputError(f"--strokes has {len(ns.strokes)} values for {frames} frames")
        return np.asarray(ns.strokes, dtype=float)
    get = lambda k: DEFAULTS[k] if getattr(ns, k) is None else getattr(ns, k)  # noqa: E731
    return clean_shed_strokes(frames, get("front_stroke"), get("frame_pitch"),
                              get("fell_distance"))


def frame_record(row: dict) -> dict:
    """One frame's JSON record in the users' units."""
    mm = 1e3
    opt = lambda v: None if v is None else float(v) * mm  # noqa: E731
    return {"frame": row["frame"], "stroke_mm": row["stroke"] * mm, "lift_plan": row["lift_plan"],
            "static": row["static"],
            "deviation_pp_mm": float(row["deviation_pp"]) * mm,
            "deviation_max_mm": opt(row["deviation_max"]),
            "deviation_min_mm": opt(row["deviation_min"]),
            "dwell_vibration_max_mm": float(row["dwell_vibration_max"]) * mm,
            "dwell_vibration_pp_mm": [float(v) * mm for v in row["dwell_vibration"]],
            "shed_deviation_mm": [float(v) * mm for v in row["shed_deviation"]],
            "acceleration_amp_m_s2": float(row["acceleration_amp"]),
            "converged": bool(row["converged"]), "warnings": row.get("warnings", [])}


def table(records: list[dict]) -> str:
    """The per-frame table (text)."""
    head = (f"{'frame':>5} {'stroke mm':>9}  {'lift plan':<12} {'dev. pp mm':>10} "
            f"{'dwell vib. max mm':>17} {'accel. pp m/s²':>14}")
    lines = [head, "-" * len(head)]
    for r in records:
        lines.append(f"{r['frame']:>5} {r['stroke_mm']:>9.1f}  {r['lift_plan']:<12} "
                     f"{r['deviation_pp_mm']:>10.3f} {r['dwell_vibration_max_mm']:>17.4f} "
                     f"{r['acceleration_amp_m_s2']:>14.0f}"
                     + ("  (static)" if r["static"] else "")
                     + ("" if r["converged"] else "  NOT CONVERGED"))
    return "\n".join(lines)


def frames_csv(records: list[dict]) -> str:
    keys = ["frame", "stroke_mm", "lift_plan", "deviation_pp_mm", "deviation_min_mm",
            "deviation_max_mm", "dwell_vibration_max_mm", "acceleration_amp_m_s2", "converged"]
    lines = [",".join(keys + ["dwell_vibration_pp_mm_by_pick"])]
    for r in records:
        vals = ["" if r[k] is None else str(r[k]) for k in keys]
        lines.append(",".join(vals + [" ".join(f"{v:.6g}" for v in r["dwell_vibration_pp_mm"])]))
    return "\n".join(lines) + "\n"


def animation_images(picks: int) -> int:
    """Images of ``--animate`` over a repeat of ``picks``: :data:`FRAMES_PER_PICK` per pick,
    at most :data:`MAX_IMAGES`."""
    return min(FRAMES_PER_PICK * picks, MAX_IMAGES)


def _animate(ns, setup, plan: np.ndarray, strokes_mm: np.ndarray) -> Path:
    """``--animate FRAME``: that frame solved alone (its plan and stroke) and its mechanism
    drawn over the repeat by :func:`jaxdobby.pictures.animation.animate` (GIF, Pillow)."""
    from ..pictures.animation import animate
    from .loom import frame_run

    i = ns.animate - 1
    target = Path(ns.out or ".") / f"loom_frame{ns.animate}.gif"
    print(f"animating frame {ns.animate} (solved again alone, for its mode shapes)...",
          file=sys.stderr, flush=True)
    run = frame_run(setup.machine, setup.operating, plan[:, i], strokes_mm[i] * 1e-3)
    path = animate(run, target, n_frames=animation_images(plan.shape[0]))
    print(f"wrote {path}", file=sys.stderr)
    return path


def run(ns: argparse.Namespace, setup_from_args) -> int:
    from ..command_line import programs_dir
    from ..io import write_json, write_text
    from ..validity import tally, tally_lines
    from .loom import run_frames

    setup, _ = setup_from_args(ns)
    plan, source = _plan(ns)
    strokes = _strokes_mm(ns, plan.shape[1])
    for i, h in enumerate(strokes):
        if not np.isfinite(h) or h <= 0:
            raise InputError(f"frame {i + 1}: stroke {h:g} mm must be > 0")
    if ns.animate is not None and not 1 <= ns.animate <= plan.shape[1]:
        raise InputError(f"--animate = {ns.animate} is outside the valid range (a frame "
                         f"1…{plan.shape[1]})")

    def progress(done, total):
        print(f"  frames solved: {done}/{total}", file=sys.stderr, flush=True)

    print(f"solving {plan.shape[1]} frames over a repeat of {plan.shape[0]} picks (one vmapped "
          "batch, compiled in each new process; traced only the first time)...",
          file=sys.stderr, flush=True)
    rows = run_frames(setup.machine, setup.operating, plan, strokes * 1e-3, progress=progress,
                      directory=programs_dir())
    records = [frame_record(r) for r in rows]
    speed_rpm = float(setup.operating.speed) * 60.0 / (2.0 * np.pi)
    warned = tally((r["frame"], r["warnings"]) for r in records)
    result = {"source": source, "speed_rpm": speed_rpm, "picks": int(plan.shape[0]),
              "frames": records, "warnings": warned}
    if ns.out:
        from .figures import deviation_figure, lift_plan_figure
        from ..plots import plt

        out = Path(ns.out)
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / "loom.json", result)
        write_text(out / "frames.csv", frames_csv(records))
        label = f"{source}, {speed_rpm:.0f} r/min"
        for name, fig in (("lift_plan", lift_plan_figure(rows, f"{label}\nlift plan (squares: "
                                                               "up), dwell vibration")),
                          ("deviation", deviation_figure(rows, f"{label}: deviation"))):
            fig.savefig(out / f"{name}.png", dpi=120)
            plt.close(fig)
        print(f"wrote loom.json, frames.csv, lift_plan.png, deviation.png to {out}",
              file=sys.stderr)
    if ns.animate is not None:
        _animate(ns, setup, plan, strokes)
    if ns.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"jaxdobby loom: {source}, {plan.shape[1]} frames, repeat of {plan.shape[0]} "
              f"picks, {speed_rpm:.0f} r/min\n")
        print(table(records))
        if warned:
            print("\nvalidity warnings, by frame (each frame's in --json):\n"
                  + tally_lines(warned, len(records), "frames"))
    return 0 if all(r["converged"] for r in records) else 1
