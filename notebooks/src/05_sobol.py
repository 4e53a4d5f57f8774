# %% [markdown]
# # 05 · Which parameter matters most? Sobol indices of the dobby
#
# The one-at-a-time studies of notebook 04 move one parameter around the default machine. A
# designer asks a global question: over the whole operating range, *how much of the variation*
# of the heald frame's deviation is due to the speed, how much to the warp force, the stroke,
# the arm's thickness? Sobol's method answers it by decomposing the variance of a metric Y over
# independent uniform inputs X₁…X_D (Sobol 2001; Saltelli et al. 2010):
#
# * **first-order index** S1ᵢ = Var(E[Y | Xᵢ]) / Var(Y): the share of the variance Xᵢ explains
#   alone;
# * **total index** STᵢ = E[Var(Y | X₋ᵢ)] / Var(Y): its share including every interaction with
#   the others (STᵢ ≥ S1ᵢ; Σ S1 = 1 and Σ ST = 1 when the model is additive);
# * **second-order index** S2ᵢⱼ: the share of the pair's interaction alone.
#
# The source study's problem (its Table 1) is jaxdobby's default: speed 400–1200 r/min, peak
# warp force 345–1035 N, stroke 80–140 mm, arm thickness 6–8 mm. The Saltelli design draws N
# base points from a scrambled Sobol' sequence and evaluates the model at N·(2D + 2) = 10 N
# points (second order, D = 4); jaxdobby runs them as vmapped batches of periodic steady states
# (`jaxdobby sobol`), and SALib estimates the indices with bootstrap 95 % intervals.
#
# **The source study reports** (its §6, figs. 29–30): the displacement deviation is most
# sensitive to the **speed**, then the **warp tension** and the **stroke**; the acceleration is
# most sensitive to the **warp tension**, then the speed and the stroke. Its force law always
# opposed the lift; jaxdobby's default law restores the frame towards mid-shed (see notebook
# 04). Both are run here.

# %%
import dataclasses
import os
import tempfile
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display

from jaxdobby import sensitivity as sa
from jaxdobby.parameters import Setup
from jaxdobby.plots import show
from jaxdobby.sensitivity.plots import bar_figure

QUICK = os.environ.get("JAXDOBBY_NOTEBOOK_QUICK") == "1"
N = 32 if QUICK else 1024
NS = [16, 32] if QUICK else [64, 128, 256, 512, 1024]  # prefixes of the one design
SCRATCH = Path(tempfile.mkdtemp(prefix="jaxdobby-sobol-"))


def sobol(model, n, second_order, tag):
    """Run (or, at full size, resume from ``runs/``) a Sobol study of ``model``."""
    out = SCRATCH / tag if QUICK else Path("runs") / f"sobol-{tag}-{n}"
    config = sa.SobolConfig(n=n, second_order=second_order, seed=0, out=out, figures=False,
                            chunk_size=128, resume=(out / "manifest.json").exists())
    return sa.run_sobol(config, model)


restoring = sobol(sa.DOBBY, N, True, "restoring")
result = restoring.result
print(f"{len(restoring.evaluation.outputs['ok'])} steady states, "
      f"{restoring.result.failures.summary}")
print(result.table())

# %% [markdown]
# ## The indices of the two metrics the study analysed
# Deviation = peak-to-peak of the heald frame's height, flexible − rigid, over one cycle;
# acceleration = peak-to-peak of the flexible heald frame's acceleration. Intervals are the
# bootstrap's 95 % half-widths.

# %%
NAMES = result.space.names
METRICS = {"deviation_pp_mm": "displacement deviation (p-p)",
           "acceleration_amp_m_s2": "acceleration (p-p)"}


def index_table(res):
    rows = ["| metric | parameter | S1 | ST |", "|---|---|---|---|"]
    for metric in METRICS:
        ix = res.metrics[metric]
        for i, name in enumerate(NAMES):
            rows.append(f"| {metric} | {name} | {ix.S1[i]:.3f} ± {ix.S1_conf[i]:.3f} "
                        f"| {ix.ST[i]:.3f} ± {ix.ST_conf[i]:.3f} |")
        rows.append(f"| {metric} | **sum** | {ix.S1.sum():.3f} | {ix.ST.sum():.3f} |")
    return "\n".join(rows)


display(Markdown(index_table(result)))
for metric in METRICS:
    show(bar_figure(result, metric))

# %% [markdown]
# ## Shares of total sensitivity (the study's figures 29 and 30)

# %%
def pies(results, titles):
    fig, axes = plt.subplots(len(results), len(METRICS), figsize=(7.5, 3.6 * len(results)),
                             squeeze=False, layout="constrained")
    for row, (res, title) in enumerate(zip(results, titles)):
        for col, (metric, label) in enumerate(METRICS.items()):
            st = np.clip(res.metrics[metric].ST, 0.0, None)
            axes[row, col].pie(st / st.sum(), labels=NAMES, autopct="%1.0f%%", startangle=90,
                               counterclock=False)
            axes[row, col].set_title(f"{label}\n{title}", fontsize=9)
    fig.suptitle("share of total sensitivity ST / ΣST", fontsize=10)
    return fig


show(pies([result], ["warp law: restoring (default)"]))

# %% [markdown]
# ## Interactions
# Σ S1 close to 1 means the metric is nearly additive in the four parameters; the pair
# indices S2 show which interactions carry the rest.

# %%
for metric in METRICS:
    ix = result.metrics[metric]
    pairs = sorted(ix.pairs(), key=lambda jk: -ix.S2[jk])
    print(f"{metric}: ΣS1 = {ix.S1.sum():.3f}, ΣST = {ix.ST.sum():.3f}; largest pairs: "
          + ", ".join(f"{NAMES[j]}×{NAMES[k]} {ix.S2[j, k]:+.3f} ± {ix.S2_conf[j, k]:.3f}"
                      for j, k in pairs[:3]))

# %% [markdown]
# ## Convergence with N
# A scrambled Sobol' design of N = 2ᵐ base points is the first N points of any longer one,
# so the first N · 10 rows of the run above are themselves a Saltelli design of size N. The
# indices re-estimated on those prefixes show how they settle and how the intervals shrink
# (roughly as 1/√N).

# %%
rows = result.space.rows_per_base_sample(True)
outputs = restoring.evaluation.outputs
conv = {n: sa.analyze(result.space, {k: v[:n * rows] for k, v in outputs.items()}, n=n,
                      second_order=True, seed=0) for n in NS}
fig, axes = plt.subplots(1, len(METRICS), figsize=(10, 3.6), layout="constrained")
for ax, (metric, label) in zip(axes, METRICS.items()):
    for i, name in enumerate(NAMES):
        st = [conv[n].metrics[metric].ST[i] for n in NS]
        ci = [conv[n].metrics[metric].ST_conf[i] for n in NS]
        ax.errorbar(NS, st, yerr=ci, marker="o", capsize=3, label=name)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("base samples N")
    ax.set_ylabel("total index ST [-]")
    ax.set_title(label, fontsize=10)
axes[0].legend(frameon=False, fontsize=8)
show(fig)
print("mean 95 % half-width of ST (all five metrics):")
for n in NS:
    widths = np.concatenate([m.ST_conf for m in conv[n].metrics.values()])
    print(f"  N = {n:5d} ({n * rows:6d} runs): {widths.mean():.4f}")
q = np.percentile(outputs["deviation_pp_mm"], [50, 90, 99, 100])
print("deviation p-p over the design [mm]: median {:.2f}, 90 % {:.2f}, 99 % {:.2f}, max {:.2f}"
      .format(*q))

# %% [markdown]
# ## The study's force law
# With `warp_law = "opposing"` the warp force always acts against the current pick's lift, as
# the source study's force curve does (notebook 04). The same study under that law (first and
# total indices only):

# %%
if not QUICK:
    opposing_setup = dataclasses.replace(
        Setup(), machine=Setup().machine.replace(warp_law="opposing"))
    opposing_model = sa.ModelSpec("dobby-opposing", sa.DOBBY_PARAMETERS, sa.DOBBY.default_names,
                                  sa.dobby_model(opposing_setup))
    opposing = sobol(opposing_model, N, False, "opposing").result
    display(Markdown(index_table(opposing)))
    show(pies([result, opposing], ["warp law: restoring (default)", "warp law: opposing (study)"]))

# %% [markdown]
# ## Ranking beside the source study's

# %%
study = {"deviation_pp_mm": ["speed", "warp_force", "stroke"],
         "acceleration_amp_m_s2": ["warp_force", "speed", "stroke"]}
laws = {"restoring": result} | ({} if QUICK else {"opposing": opposing})


def ranking(res, metric):
    st = res.metrics[metric].ST
    return [NAMES[i] for i in np.argsort(-st)]


for metric in METRICS:
    print(f"{metric}\n  source study: {' > '.join(study[metric])}")
    for law, res in laws.items():
        st = res.metrics[metric].ST
        print(f"  jaxdobby, {law:9s}: " + " > ".join(
            f"{name} ({st[NAMES.index(name)]:.2f})" for name in ranking(res, metric)))

# %%
for metric, ix in result.metrics.items():
    assert ix.S1.sum() <= 1.0 + ix.S1_conf.sum(), metric            # shares of one variance
    assert np.all(ix.ST >= ix.S1 - ix.S1_conf - ix.ST_conf), metric  # total ≥ first order
dev, acc = result.metrics["deviation_pp_mm"], result.metrics["acceleration_amp_m_s2"]
i = {name: NAMES.index(name) for name in NAMES}
# the deviation: speed and stroke lead, warp force and thickness far behind (clear of the
# intervals at full size; the quick run's intervals are too wide for that, its estimates are not)
margin = 0.0 if QUICK else 1.0
for lead in ("speed", "stroke"):
    for minor in ("warp_force", "thickness"):
        assert (dev.ST[i[lead]] - margin * dev.ST_conf[i[lead]]
                > dev.ST[i[minor]] + margin * dev.ST_conf[i[minor]]), (lead, minor)
# the acceleration: speed first, clear of every other parameter
for other in ("warp_force", "stroke", "thickness"):
    assert (acc.ST[i["speed"]] - margin * acc.ST_conf[i["speed"]]
            > acc.ST[i[other]] + margin * acc.ST_conf[i[other]]), other
# the intervals shrink as the design grows
mean_width = [np.mean(np.concatenate([m.ST_conf for m in conv[n].metrics.values()])) for n in NS]
assert mean_width[-1] < mean_width[0]
if not QUICK:  # the study's force law gives the warp force a share of the deviation
    assert (opposing.metrics["deviation_pp_mm"].ST[i["warp_force"]]
            > 10 * dev.ST[i["warp_force"]])

# %% [markdown]
# ## Conclusions
# *(Numbers of the full run, N = 1024 with second order: 10 240 periodic steady states.)*
#
# * **The deviation** is governed by the **stroke** (ST ≈ 0.58 ± 0.15) and the **speed**
#   (ST ≈ 0.50 ± 0.13), ranked within their intervals of each other; ΣS1 ≈ 0.71, so about 30 %
#   of its variance lies in interactions, mostly speed × stroke (S2 ≈ 0.17): a long stroke
#   costs most at high speed, where the pick rate's harmonics approach the 107 Hz frame-on-arm
#   mode. Thickness 6–8 mm carries ≈ 3 %; the warp force nothing (ST < 0.001).
# * **The acceleration** (peak to peak of the flexible heald frame) is the rigid mechanism's
#   acceleration, ∝ speed² × stroke, plus the ringing of the flexible mode: **speed** ST ≈ 0.83,
#   stroke ≈ 0.17, thickness ≈ 0.02, warp force ≈ 0.
# * **Beside the source study.** It, too, finds the speed the first lever of the deviation, and
#   its one-at-a-time results (notebook 04: stroke 140 → 80 mm takes the deviation × 0.14) say
#   the stroke is a strong one. It ranks the warp tension second for the deviation and *first*
#   for the acceleration; ours does not, for two reasons we can name:
#   1. *The force law.* With the default restoring law the warp force pulls the frame towards
#      mid-shed from both sides; it hardly changes the peak-to-peak deviation. The study's
#      opposing law (above) raises the warp force's share of the deviation about elevenfold
#      (ST 0.0003 → 0.004) and the thickness's (0.03 → 0.06), yet stroke (0.65) and speed
#      (0.44) still carry nearly all of it: the force changes the level the frame rings about
#      more than the ringing itself.
#   2. *Magnitudes.* 1035 N on a 12 kg heald frame is at most ≈ 86 m/s², against 300–4000 m/s²
#      peak to peak from the motion itself over this box; in a model whose acceleration
#      includes the rigid motion, the warp force cannot lead the acceleration's variance. The
#      study's ranking would need an acceleration metric dominated by the force (e.g. the
#      acceleration *deviation* at low speed) or warp forces far above its Table 1.
# * **Convergence.** The rankings (stroke and speed ≫ thickness ≫ warp force for the
#   deviation; speed ≫ stroke for the acceleration) hold at every N shown; the values settle
#   by N ≈ 256–512 (speed's ST for the deviation: 0.68, 0.56, 0.52, 0.50 at N = 128 … 1024).
#   The intervals shrink roughly as 1/√N from N = 64 to 512 (mean half-width 0.36 → 0.07)
#   but stay wide for the deviation (± 0.13 at N = 1024): its distribution over the box is
#   heavy-tailed (median 0.6 mm, 99th percentile 5.5 mm, maximum 18 mm — the fast, long-stroke
#   corner near resonance), and a bootstrap of a heavy tail converges slowly.
