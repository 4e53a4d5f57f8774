# %% [markdown]
# # 06 · Designing the bending arm with gradients
#
# The source study ends with advice: a thicker bending arm lifts the heald frame more faithfully,
# as long as neighbouring arms still clear each other. That is a design trade-off, and with one
# ADAMS run at a time nobody explores it beyond a few hand-picked plates. jaxdobby differentiates
# the periodic steady state of the coupled mechanism with respect to the arm's design (through
# the finite-element model, its reduction onto a fixed Ritz basis, the kinematics and the
# collocation cycle), so an optimiser can walk downhill on the heald-frame deviation directly.
#
# Two problems, both minimising the peak-to-peak deviation of the heald frame (flexible − rigid
# height) at 800 r/min:
#
# 1. **thickness alone** (6–8 mm; the 12 mm pitch between arms less a 4 mm clearance allows up
#    to 8 mm): the study's own question;
# 2. **the depth profile** d(s) — the arm's in-plane depth at five control points along its
#    length, 20–80 mm — at the default 6 mm thickness, with the arm's **mass held to that of the
#    default uniform 40 mm arm**: shape, not material, is what changes.
#
# Both run the command a designer would (`jaxdobby optimize`), which writes the history, the
# optimised design as a configuration file `jaxdobby simulate --config` reads, and the figures
# shown below. Projected L-BFGS keeps the bounds; the mass budget enters through an augmented
# Lagrangian (`jaxdobby.optimize`).

# %%
import json
import os
import tempfile
from pathlib import Path

from IPython.display import Image, Markdown, display

from jaxdobby.cli import main

QUICK = os.environ.get("JAXDOBBY_NOTEBOOK_QUICK") == "1"
OUT = Path(tempfile.mkdtemp(prefix="jaxdobby-design-"))
STEPS = ["--steps", "2"] if QUICK else ["--steps", "8"]
UNIFORM_MASS = 0.42304  # kg: the default arm (6 mm plate, 40 mm deep), jaxdobby beam / ArmDesign


def optimize(name, *args):
    """Run `jaxdobby optimize` and return its result summary and output directory.

    At full size the run goes to ``runs/design-NAME`` (git-ignored) and a finished run with the
    same arguments there is read back instead of repeated (minutes of gradients each)."""
    argv = ["optimize", "--speeds", "800", *STEPS, *args]
    out = OUT / name if QUICK else Path("runs") / f"design-{name}"
    stored = out / "argv.json"
    if QUICK or not ((out / "result.json").exists() and stored.exists()
                     and json.loads(stored.read_text()) == argv):
        assert main([*argv, "--out", str(out)]) == 0
        stored.write_text(json.dumps(argv))
    return json.loads((out / "result.json").read_text()), out


def show(out, name):
    display(Image(filename=str(out / name), width=560))


thickness, t_dir = optimize("thickness", "--vars", "thickness")
# A stiff penalty (ρ = 100) makes the mass budget bind within the iterations run here.
depth, d_dir = optimize("depth", "--vars", "depth", "--mass-budget", str(UNIFORM_MASS),
                        "--penalty", "100", *([] if QUICK else ["--steps", "20"]))

# %% [markdown]
# ## Thickness alone

# %%
def summary_table(results):
    rows = ["| problem | design | arm mass [kg] | deviation p-p at 800 r/min: start → optimised [mm] "
            "| change | projected gradient |", "|---|---|---|---|---|---|"]
    for name, s in results.items():
        sp = s["per_speed"][0]
        a, b = sp["start"]["deviation_pp_mm"], sp["optimised"]["deviation_pp_mm"]
        design = ", ".join(f"{k} {v:.2f}" if not isinstance(v, list) else
                           f"{k} [{', '.join(f'{x:.1f}' for x in v)}]"
                           for k, v in s["optimised"]["design"].items())
        rows.append(f"| {name} | {design} | {s['start']['arm_mass_kg']:.4f} → "
                    f"{s['optimised']['arm_mass_kg']:.4f} | {a:.3f} → {b:.3f} | "
                    f"{100 * (b / a - 1):+.1f} % | {s['optimality']['projected_gradient']:.1e} |")
    return "\n".join(rows)


display(Markdown(summary_table({"thickness": thickness})))
show(t_dir, "history.png")
show(t_dir, "deviation.png")

# %% [markdown]
# ## Depth profile at equal mass

# %%
display(Markdown(summary_table({"depth profile, mass ≤ uniform arm": depth})))
show(d_dir, "depth_profile.png")
show(d_dir, "history.png")
show(d_dir, "deviation.png")

# %%
t_sp, d_sp = thickness["per_speed"][0], depth["per_speed"][0]
t_gain = 1 - t_sp["optimised"]["deviation_pp_mm"] / t_sp["start"]["deviation_pp_mm"]
d_gain = 1 - d_sp["optimised"]["deviation_pp_mm"] / d_sp["start"]["deviation_pp_mm"]
print(f"thickness: {thickness['optimised']['design']['thickness_mm']:.3f} mm, deviation "
      f"{100 * t_gain:.1f} % lower; depth profile at equal mass: {100 * d_gain:.1f} % lower, "
      f"mass {depth['optimised']['arm_mass_kg']:.5f} kg (budget {UNIFORM_MASS} kg)")
# The deviation falls with the thickness (notebook 04; the study's finding): the optimiser
# moves t up, all the way to the 8 mm bound at full size (measured there: 2.709 → 2.146 mm).
assert thickness["optimised"]["design"]["thickness_mm"] > 6.0
assert t_gain > (0.15 if not QUICK else 0.0)
# The depth profile beats the uniform arm it started from (on its own modes). The augmented
# Lagrangian does not settle on the budget within these iterations (the history's c_mass swings
# across zero), so what is asserted is the state reached — within 5 % of the budget at most
# (below it at full size) — and the violation is printed; issue 5 keeps this open.
violation = depth["optimised"]["arm_mass_kg"] / UNIFORM_MASS - 1
print(f"mass budget violation after {depth['iterations']} iterations: {100 * violation:+.2f} %")
assert depth["optimised"]["arm_mass_kg"] <= UNIFORM_MASS * 1.05
assert d_gain > 0.0

# %% [markdown]
# ## Conclusions
#
# * **Thickness.** Over 6–8 mm the deviation only falls as the plate thickens, so the optimum
#   is the largest thickness the pitch between arms allows: 8 mm, −20.8 % at 800 r/min
#   (2.709 → 2.146 mm) and −26.5 % at 1200 r/min (8.388 → 6.169 mm,
#   `benchmarks/results/optimize_designs.md`); the source study found −14 % and −24 % for 7 and
#   8 mm. The arm is then 33 % heavier (0.423 → 0.564 kg), which is what the next problem avoids.
# * **Shape within the mass budget.** Moving material along the arm — deeper around 80 mm from
#   the pivot, where the heald frame's inertia bends it most, shallower at the ends — lowers the
#   deviation without adding mass. In the full run (20 iterations) the profile ended at
#   29/52/33/26/35 mm, 6 % *lighter* than the uniform arm (0.397 against 0.423 kg) and 9 % better
#   on its own modes (2.709 → 2.463 mm at 800 r/min): better and lighter than the uniform arm of
#   the budget's mass. The augmented Lagrangian swung across the budget on the way (the history's
#   c_mass changes sign) and stopped on the feasible side, not on the budget; the projected
#   gradient there is 0.03 of the start's 1.4, so this is near a local stationary point but
#   not a converged KKT point — a tighter optimum on the budget is likely better still (issue
#   5: an exact projection onto the linear mass constraint would remove the swinging). The
#   objective is bumpy (resonances of the frame-on-arm mode with the pick rate's harmonics,
#   notebook 04), so any optimum is local.
# * **The fixed basis.** The optimiser's model projects every design onto one fixed Ritz basis
#   (the default arm's modes and static shapes), so that no eigen-decomposition lies on the
#   gradient's path; `result.json` also reports each design re-run on *its own* modes, the
#   model `jaxdobby simulate` runs, and the table above uses those. For large changes of the
#   profile the two differ (after 8 iterations in a trial run: 1.08 mm on the fixed basis,
#   1.82 mm on its own modes): the improvement is real but smaller than the optimiser believes,
#   and a designer should re-centre the basis on the new design and continue.
# * **Limits.** The objective is the modal model's peak-to-peak at one speed; a design for a
#   loom should use `--speeds 800,1000,1200 --aggregate worst` (one vmapped batch), and check
#   the optimised machine with `jaxdobby simulate --config OUT/design.toml`, which reproduces
#   the reported deviation (tested).
