# %% [markdown]
# # 06 · Designing the bending arm with gradients
#
# The source study ends with advice: a thicker bending arm lifts the heald frame more faithfully,
# as long as neighbouring arms still clear each other. That is a design trade-off, and with one
# ADAMS run at a time nobody explores it beyond a few hand-picked plates. jaxdobby differentiates
# the periodic steady state of the coupled mechanism with respect to the arm's design (through
# the finite-element model, its reduction onto the design's own modes, the kinematics and the
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
# shown below. Projected L-BFGS keeps the bounds and the mass budget exactly: the arm's mass is
# linear in the depths (and in the thickness), so every iterate is projected onto the box cut by
# the budget (`jaxdobby.optimize`).

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


# The deviation against thickness has local minima between resonances (notebook 04): a scan of
# ten starting thicknesses in one vmapped batch (--starts) picks the basin first.
thickness, t_dir = optimize("thickness", "--vars", "thickness", "--starts", "10")
depth, d_dir = optimize("depth", "--vars", "depth", "--mass-budget", str(UNIFORM_MASS),
                        *([] if QUICK else ["--steps", "40"]))

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
# The depth profile beats the uniform arm it started from, with the mass on the budget (held by
# projection: every iterate is feasible) and, at full size, at a KKT point: the reduced gradient
# (the gradient with the budget's multiplier, zeroed where a depth sits on its bound) vanishes.
print(f"mass {depth['optimised']['arm_mass_kg']:.6f} kg, multiplier "
      f"{depth['multipliers']['mass']:.3f}, reduced gradient "
      f"{depth['optimality']['projected_gradient']:.1e} after {depth['iterations']} iterations")
assert depth["optimised"]["arm_mass_kg"] <= UNIFORM_MASS * (1 + 1e-9)
assert d_gain > (0.3 if not QUICK else 0.0)
if not QUICK:
    assert depth["converged"] and depth["optimality"]["projected_gradient"] < 1e-4

# %% [markdown]
# ## Stress: the default arm fails in fatigue, and a design that does not
#
# **The default 6 mm arm is far above its fatigue limit at 800 r/min.** The link-11 force bends
# the lever about the ring-link joint (s = 80 mm), where the stress swings from −680 to
# +464 MPa over a cycle: its Goodman safety factor is 0.84 against a polished specimen's
# endurance limit (500 MPa) and 0.56 for a machined arm (surface factor k_a = 0.72, size factor
# k_b = 0.91: σ_e ≈ 328 MPa) — it would not survive 10⁹ cycles. At 1200 r/min the peak
# (2190 MPa) is three times the yield strength.
#
# `jaxdobby optimize --fatigue-floor N` holds the Goodman factor as a constraint (smooth
# surrogate, exact gradients through the steady cycle and the stress recovery). The problem
# below designs the thickness **and** the depth profile together (six variables) at the default
# arm's mass, for a machined arm, minimising the deviation at 800 r/min: without a stress
# constraint, and with n ≥ 1.5, n ≥ 1.75 and n ≥ 2. These runs take minutes each on two
# cores (most of it compiling the constraint's gradient), so the notebook **does not
# re-optimise**: it reads the results that
# `python benchmarks/optimize_stress.py` wrote to `benchmarks/results/optimize_stress.json`
# (every design re-run there by `jaxdobby.simulate` on its own modes, at 800 and 1200 r/min,
# with its stress recovered), and shows and checks them.

# %%
import matplotlib.pyplot as plt
import numpy as np

RESULTS = next(p / "benchmarks" / "results" for p in [Path.cwd(), *Path.cwd().parents]
               if (p / "benchmarks" / "results" / "optimize_stress.json").exists())
stress = json.loads((RESULTS / "optimize_stress.json").read_text())
display(Markdown((RESULTS / "optimize_stress.md").read_text().split("\n", 2)[2]))

default = stress["default"]["at"]["800"]
print(f"default arm at 800 r/min: peak stress {default['stress_max_mpa']:.0f} MPa at "
      f"s = {default['stress_max_position_mm']:.0f} mm, Goodman factor "
      f"{default['fatigue_safety_factor']:.2f} machined, "
      f"{default['fatigue_safety_factor_polished']:.2f} polished")
# the default arm fails the fatigue check at 800 r/min, even as a polished specimen
assert default["fatigue_safety_factor_polished"] < 1.0 and default["fatigue_safety_factor"] < 0.6

# %%
positions = np.array([0.0, 80.0, 153.0, 201.0, 226.0])  # the depth control points [mm]
fig, ax = plt.subplots(figsize=(7, 3.2))
ax.plot([0, 226], [40, 40], "k--", label="default: t = 6 mm, uniform 40 mm")
for name, row in stress["rows"].items():
    depth = [v for k, v in row["design"].items() if k.startswith("depth")]
    a = row["at"]["800"]
    ax.plot(positions, depth, "o-", label=f"{name}: t = {row['design']['thickness_mm']:.2f} mm, "
            f"n = {a['fatigue_safety_factor']:.2f}, dev. {a['deviation_pp_mm']:.2f} mm")
ax.axvline(80.0, color="0.7", lw=0.8)
ax.text(81, 22, "ring-link joint", fontsize=8, color="0.4")
ax.set(xlabel="arc length from the pivot s [mm]", ylabel="in-plane depth d [mm]",
       title="Arm designs at the default arm's mass, 800 r/min")
ax.legend(fontsize=7, loc="upper right")
fig.tight_layout()
plt.show()

# %%
default_mass = stress["default"]["arm_mass_kg"]
for name, row in stress["rows"].items():
    a = row["at"]["800"]
    floor = row["fatigue_floor"]
    smooth = (floor / (1.0 + row["final_constraints"]["c_fatigue"]) if floor else float("nan"))
    print(f"{name}: t = {row['design']['thickness_mm']:.2f} mm, mass {row['arm_mass_kg']:.4f} kg, "
          f"deviation {a['deviation_pp_mm']:.3f} mm, peak stress {a['stress_max_mpa']:.0f} MPa "
          f"at s = {a['stress_max_position_mm']:.0f} mm, n = {a['fatigue_safety_factor']:.3f} "
          f"(surrogate {smooth:.3f}; polished {a['fatigue_safety_factor_polished']:.2f}), "
          f"multipliers {', '.join(f'{k} {v:.3g}' for k, v in row['multipliers'].items())}, "
          f"{row['iterations']} iterations, reduced gradient "
          f"{row['optimality']['projected_gradient']:.1e}")
    met = all(v <= 1e-3 for v in row["final_constraints"].values())
    # every design beats the default arm's deviation
    assert a["deviation_pp_mm"] < default["deviation_pp_mm"]
    if floor:
        # the smooth surrogate of 1/n lies above the true largest 1/n (a soft maximum), so the
        # factor the optimiser sees is at or below the true one simulate gives
        assert smooth <= a["fatigue_safety_factor"] * (1 + 1e-3)
    if met:  # the mass budget and the floor hold on the design's own modes
        assert row["arm_mass_kg"] <= default_mass * (1 + 2e-3)
        assert not floor or a["fatigue_safety_factor"] >= floor * (1 - 2e-3)

free, rows = stress["rows"]["mass"], stress["rows"]
# Without a stress constraint the deviation optimum is already safe to n = 1.6 at 800 r/min:
# n >= 1.5 is inactive (multiplier 0) and leaves the deviation within 0.2 %.
assert free["at"]["800"]["fatigue_safety_factor"] > 1.5
assert rows["mass+fatigue>=1.5"]["multipliers"]["fatigue"] == 0.0
assert abs(rows["mass+fatigue>=1.5"]["at"]["800"]["deviation_pp_mm"]
           / free["at"]["800"]["deviation_pp_mm"] - 1) < 2e-3
# n >= 1.75 binds: the fatigue multiplier is positive, the plate thicker, the floor held to
# the run's last 0.2 %, and the deviation pays a little for it (+1.7 % measured).
tight = rows["mass+fatigue>=1.75"]
assert tight["multipliers"]["fatigue"] > 0.0
assert tight["design"]["thickness_mm"] > free["design"]["thickness_mm"] + 0.1
assert tight["at"]["800"]["fatigue_safety_factor"] > 1.74
assert 1.0 < (tight["at"]["800"]["deviation_pp_mm"] / free["at"]["800"]["deviation_pp_mm"]) < 1.05
# n >= 2 was not met at this mass: the run ends over both the budget and the floor.
assert max(rows["mass+fatigue>=2"]["final_constraints"].values()) > 0.01
# At 1200 r/min no design at this mass passes the machined arm's fatigue check.
assert all(r["at"]["1200"]["fatigue_safety_factor"] < 1.0 for r in rows.values())

# %% [markdown]
# ## Conclusions
#
# * **Thickness.** Over 6–8 mm the deviation falls as the plate thickens, but not
#   monotonically: narrow resonance peaks (the first coupled mode meeting a harmonic of the pick
#   rate, at 6.25 and 7.35 mm for 800 r/min) stand on the trend, and a gradient method started
#   at 6 mm stops in the local minimum at 7.15 mm. A batched scan of ten starts (one vmapped
#   solve) finds the basin of the largest thickness the pitch between arms allows: 8 mm, −20.8 %
#   at 800 r/min
#   (2.709 → 2.146 mm; −26.5 % at 1200 r/min, the README's "Designing the arm"); the source
#   study found −14 % and −24 % for 7 and 8 mm. The arm is then 33 % heavier
#   (0.423 → 0.564 kg), which is what the next problem avoids.
# * **Shape within the mass budget.** Moving material along the arm — deep around the ring-link
#   joint at 80 mm, where the heald frame's inertia bends it most, shallow at the pivot and at
#   the link-11 end — lowers the deviation without adding mass: the profile ends at about
#   21/64/38/20/20 mm (two depths on their 20 mm bound), on the budget, 37 % better than the
#   uniform arm (2.709 → 1.700 mm at 800 r/min), with the first coupled mode up from 107 to
#   132 Hz. It is a KKT point (reduced gradient 2e-5), but a local one: the objective is bumpy
#   (resonances of the frame-on-arm mode with the pick rate's harmonics, notebook 04).
# * **Stress.** The default arm is far above its fatigue limit at 800 r/min (n = 0.84 polished,
#   0.56 machined; 680 MPa at the ring-link joint). The thickness-and-depth design at the
#   default arm's mass — a 4.1 mm plate, 80 mm deep at the ring-link joint — lowers the
#   deviation by 57 % (2.709 → 1.172 mm) and the peak stress from 680 to 248 MPa: n = 1.61
#   machined, so a floor n ≥ 1.5 does not bind (multiplier 0, the same design). A floor
#   n ≥ 1.75 binds: the plate thickens to 4.37 mm and the depth moves inboard (43/80/58/20/23
#   mm), the peak falls to 227 MPa (n = 1.75) for 1.7 % more deviation (1.192 mm). n ≥ 2 was not
#   reached at this mass: after 30 iterations the run is 5.0 % over the mass budget at n = 1.91,
#   its multipliers growing (a 100-iteration rerun stalled at the same point), which suggests
#   n ≥ 2 needs more material than the default arm's in these bounds — the optimiser from one
#   start does not prove it. At 1200 r/min none of these designs passes the machined arm's
#   check (n ≈ 0.64–0.74).
# * **The model the optimiser uses.** Every design is reduced on its own first four modes —
#   the model `jaxdobby simulate` runs — and differentiated as the subspace those modes span
#   (`jaxdobby.modal.mode_subspace`), so two modes crossing inside the kept set cause no NaN and
#   the optimum is an optimum of the model a designer will check it with. A fixed reduction
#   basis (the default arm's modes) looked attractive but stiffens designs far from the default
#   one: an arm 20 mm deep everywhere but at 80 mm, where an optimiser on that basis went, has
#   its first coupled mode at 176 Hz on the default arm's modes and at 70 Hz on its own, and a
#   true deviation of 8.9 mm where that optimiser believed 1.0 mm.
# * **Limits.** The objective is the modal model's peak-to-peak at one speed; a design for a
#   loom should use `--speeds 800,1000,1200 --aggregate worst` (one vmapped batch), and check
#   the optimised machine with `jaxdobby simulate --config OUT/design.toml`, which reproduces
#   the reported deviation (tested). Only the bending arm is designed; the clearance to
#   neighbouring arms enters through the thickness bound alone.
