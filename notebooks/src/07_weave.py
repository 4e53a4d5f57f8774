# %% [markdown]
# # 07 · Weaving a pattern: a 2/2 twill and a 5-end satin on 8 frames
#
# A dobby's frames do not all move every pick. In a weave each frame has its own lift sequence
# over the repeat (1 = up in that pick's open shed; DESIGN.md §7) and its own stroke — the
# clean-shed rule H_i = H₁·L_i/L₁ gives the frames further from the cloth fell longer strokes.
# What a weaver wants to know is how still each frame is while the weft flies: the **dwell
# vibration**, the peak-to-peak deviation over a pick's dwell. Here a 2/2 twill (`1100`, a
# move every other pick) and a 5-end satin (`10000`: up one pick in five, then four still
# picks) run on 8 frames (strokes 100–134 mm) at 800 and 1200 r/min, each frame set as one
# vmapped batch (`jaxdobby loom` does the same from the command line).

# %%
import os

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np

from jaxdobby import Machine, OperatingPoint
from jaxdobby.plots import show
from jaxdobby.weave.figures import deviation_figure, lift_plan_figure
from jaxdobby.weave.loom import clean_shed_strokes, run_frames
from jaxdobby.weave.named import named_plan

QUICK = os.environ.get("JAXDOBBY_NOTEBOOK_QUICK") == "1"
FRAMES = 4 if QUICK else 8
SPEEDS = [1200.0] if QUICK else [800.0, 1200.0]
machine = Machine.default()
strokes = clean_shed_strokes(FRAMES, 100.0, 12.0, 250.0) * 1e-3  # [m]
results = {}
for weave in ("twill22", "satin5"):
    plan = named_plan(weave, FRAMES)
    for rpm in SPEEDS:
        results[weave, rpm] = run_frames(machine, OperatingPoint.from_users_units(speed_rpm=rpm),
                                         plan, strokes)
print("strokes [mm]:", np.round(strokes * 1e3, 1))

# %% [markdown]
# ## Per frame: deviation over the repeat and the largest dwell vibration

# %%
for (weave, rpm), rows in results.items():
    print(f"### {weave}, {rpm:.0f} r/min")
    print("frame  plan    dev. pp [mm]  dwell vib. max [mm]  worst pick  moves there")
    for r in rows:
        k = int(np.argmax(r["dwell_vibration"]))
        print(f"{r['frame']:>5}  {r['lift_plan']:<6} {float(r['deviation_pp']) * 1e3:>13.3f}"
              f" {float(r['dwell_vibration_max']) * 1e3:>20.4f} {k + 1:>11}"
              f"  {'yes' if r['moves'][k] > 0.5 else 'no'}")
    assert all(bool(r["converged"]) for r in rows)

# %%
for weave in ("twill22", "satin5"):
    rows = results[weave, SPEEDS[-1]]
    show(lift_plan_figure(rows, f"{weave}, {SPEEDS[-1]:.0f} r/min: lift plan (squares: up), "
                                "dwell vibration"))
    show(deviation_figure(rows, f"{weave}, {SPEEDS[-1]:.0f} r/min: deviation"))

# %% [markdown]
# ## Which frames and picks are worst, and why
#
# * **The back frames.** A longer stroke puts the link-11 joint further out on the arm: more
#   bending for the same heald-frame inertia, so deviation and dwell vibration grow steeply
#   with the frame number (the stroke grows only linearly).
# * **The first mode barely damps.** The arm's 2 % modal damping is shared with the heald
#   frame's inertia, so the coupled first mode (≈ 109 Hz) keeps only ≈ 0.23 % (measured in a
#   long dwell, `tests/test_weave_slow.py`): a time constant of ≈ 0.64 s, 8.5 picks at
#   800 r/min and 13 at 1200. The ringing of a move lasts through the following dwells; a pick
#   rings with what the last moves left, and the next move adds to it or partly cancels it.
# * **Speed.** The excitation of a move grows with speed² (the modulator's accelerations) and
#   the dwell gets shorter: 1200 r/min is far worse than 800.
# * **The picks with a move.** Every frame's worst pick above is one where it moves: the
#   dwell right after the index, with the fresh ringing of that move (DESIGN §7). The satin's
#   frames move twice in a row (up for one pick, then down): at 1200 r/min the second move
#   comes 50 ms — 5.5 periods of the 109 Hz mode — after the first and can add to its
#   ringing, so the satin's back frame rings twice as much as the twill's.

# %%
worst = {}
for key, rows in results.items():
    vib = np.array([float(r["dwell_vibration_max"]) for r in rows])
    worst[key] = (int(np.argmax(vib)) + 1, float(vib.max()) * 1e3)
    print(f"{key[0]:>8} {key[1]:>5.0f} r/min: worst frame {worst[key][0]} "
          f"({worst[key][1]:.3f} mm)")
for weave in ("twill22", "satin5"):
    # the worst frame is one of the back half (longest strokes)
    assert worst[weave, SPEEDS[-1]][0] > FRAMES // 2
    if not QUICK:
        assert worst[weave, 1200.0][1] > worst[weave, 800.0][1]
for (weave, rpm), rows in results.items():  # every frame's worst pick is a pick with a move
    assert all(r["moves"][int(np.argmax(r["dwell_vibration"]))] > 0.5 for r in rows), weave
