"""Model-form error budget of jaxdobby against the co-rotational reference (issue 21).

    python3 benchmarks/model_form_budget.py            # 400, 800, 1000, 1200 r/min
    python3 benchmarks/model_form_budget.py --quick    # 800 r/min, few variants
    ... --only "VARIANT" ...; ... --jaxdobby-only; ... --merge A.json B.json   # in pieces
    ... --figure-only                                   # redraw the figure, print docs' table

The reference (``tests/reference/dobby_nonlinear.py``: every FE DOF of the arm, co-rotational
strain energy, ring link 9 a two-force member whose direction follows the motion, section rotary
inertia, 2 % damping in every mode of the supported arm) is run with one of jaxdobby's
assumptions put back at a time, then with all of them (which must give jaxdobby with all 31
modes), and jaxdobby itself with 31, 8 and 4 modes and with stiffness-proportional damping. For
each: heald-frame deviation peak-to-peak, min, max [mm] and the first coupled frequency at
mid-lift [Hz] (the linearisation about the steady cycle, time frozen, speed terms included —
:func:`tests.reference.dobby_nonlinear.frozen_frequencies`; jaxdobby's own speed-free
``natural_frequencies`` is 106.64 Hz at every speed). Writes
``benchmarks/results/model_form_budget{_quick}.json`` and ``.md`` and
``docs/figures/model_form_budget.png``. A full run is ~40 reference cycles of 4000 implicit
steps (about 15 min on one free core); rows are saved as they come
(``model_form_budget_partial.json``), and runs in pieces are merged with ``--merge``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import RESULTS, configure_jax, environment, write_json  # noqa: E402

jax = configure_jax()

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from jaxdobby import Machine, OperatingPoint, simulate  # noqa: E402
from jaxdobby.dobby import equations_at, rigid_state  # noqa: E402
from jaxdobby.outputs import mid_lift_time  # noqa: E402
from tests.reference.dobby_nonlinear import (Options, Reference, frozen_frequencies,  # noqa: E402
                                             metrics, reference_frequency)

FIGURE = Path(__file__).resolve().parent.parent / "docs" / "figures" / "model_form_budget.png"
SPEEDS = (400.0, 800.0, 1000.0, 1200.0)
STEPS = 4000
VARIANTS = {
    "reference": {},
    "ring link along the rigid direction": dict(ring="fixed"),
    "stiffening linearised (rigid preload)": dict(elastic="linear"),
    "preload without gravity and warp force": dict(elastic="linear-inertia"),
    "no geometric stiffening": dict(elastic="linear-none"),
    "no rotary inertia": dict(rotary_inertia=False),
    "stiffness-proportional damping": dict(damping="stiffness"),
    "all of jaxdobby's (full FE)": dict(ring="fixed", elastic="linear", rotary_inertia=False),
    "fix: stiffening from the actual link-11 force": dict(elastic="linear-actual"),
    "all of jaxdobby's with the fix (full FE)": dict(ring="fixed", elastic="linear-actual",
                                                     rotary_inertia=False),
}
QUICK_VARIANTS = ("reference", "all of jaxdobby's (full FE)")


def jaxdobby_row(machine, rpm):
    """jaxdobby's metrics [mm] and frozen first frequency [Hz] at ``rpm``."""
    run = simulate(machine, OperatingPoint.from_users_units(speed_rpm=rpm))
    model, s = run.model, run.series
    t_star = float(mid_lift_time(model))
    k = int(np.argmin(np.abs(np.asarray(s.t) - t_star)))
    t = np.asarray(s.t)
    q = np.asarray(s.modal)
    qd = (q[k + 1] - q[k - 1]) / (t[k + 1] - t[k - 1])

    def residual(qq, vv, aa, tt):
        mass, force = equations_at(model, rigid_state(model, tt), qq, vv)
        return mass @ aa - force

    f1 = frozen_frequencies(residual, jnp.asarray(q[k]), jnp.asarray(qd), jnp.asarray(t[k]))[0]
    m = run.metrics
    return dict(deviation_pp=1e3 * float(m["deviation_pp"]),
                deviation_min=1e3 * float(m["deviation_min"]),
                deviation_max=1e3 * float(m["deviation_max"]), f1_frozen=float(f1),
                f1_speed_free=float(run.natural_frequencies[0]))


def reference_row(machine, rpm, options, x0=None):
    ref = Reference(machine, OperatingPoint.from_users_units(speed_rpm=rpm), options)
    t0 = time.perf_counter()
    res = ref.steady_state(x0=x0)
    wall = time.perf_counter() - t0
    t_star = float(mid_lift_time(ref.model))
    row = {k: 1e3 * v for k, v in metrics(res).items()}
    row.update(f1_frozen=float(reference_frequency(ref, res, t_star)), wall_s=wall,
               shooting_iterations=res["iterations"], periodicity=res["periodicity"],
               newton_residual_n=res["newton_residual"])
    return row, res["x0"]


JAXDOBBY_ROWS = ("jaxdobby, 31 modes (all)", "jaxdobby, 8 modes", "jaxdobby, 4 modes (default)",
                 "jaxdobby, 4 modes, stiffness-proportional damping")


def _rank(name):
    """Table order: reference variants (fix last), then jaxdobby's rows."""
    names = [n for n in VARIANTS if not n.startswith(("fix", "all of jaxdobby's with"))]
    names += [n for n in VARIANTS if n not in names] + list(JAXDOBBY_ROWS)
    return names.index(name) if name in names else len(names)


def _save_partial(rows):
    """Rows so far, in case a long run is stopped (results/model_form_budget_partial.json)."""
    write_json(RESULTS / "model_form_budget_partial.json",
               dict(rows=[dict(variant=n, speed_rpm=rpm, **{k: v for k, v in r.items()
                                                            if k != "_x0"})
                          for (n, rpm), r in rows.items()]))


def stiffness_damping_ratios(machine):
    """Per-mode ratios ζᵢ = ζ ωᵢ/ω₁ of stiffness-proportional damping, 2 % at the first mode."""
    from jaxdobby.dobby import arm_modes
    w = np.asarray(arm_modes(machine).frequencies)
    return float(machine.damping_ratio) * w / w[0]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--steps", type=int, default=STEPS)
    parser.add_argument("--only", nargs="+", metavar="VARIANT",
                        help="run these reference variants only, into model_form_budget_only.json")
    parser.add_argument("--jaxdobby-only", action="store_true",
                        help="run jaxdobby's rows only, into model_form_budget_jaxdobby.json")
    parser.add_argument("--merge", nargs="+", metavar="JSON",
                        help="write the main results from the rows of these result files")
    parser.add_argument("--figure-only", action="store_true",
                        help="redraw docs/figures/model_form_budget.png from the JSON")
    args = parser.parse_args(argv)
    if args.figure_only:
        out = json.loads((RESULTS / "model_form_budget.json").read_text())
        figure(out)
        print(compact_table(out))
        return
    if args.merge:
        rows = {}
        for name in args.merge:
            for r in json.loads(Path(name).read_text())["rows"]:
                rows[(r["variant"], r["speed_rpm"])] = r
        out = dict(environment=environment(), steps_per_cycle=args.steps,
                   speeds_rpm=list(SPEEDS), rows=sorted(
                       rows.values(), key=lambda r: (_rank(r["variant"]), r["speed_rpm"])))
        out.update(benchmark="model_form_budget", markdown=markdown(out))
        write_json(RESULTS / "model_form_budget.json", out)
        (RESULTS / "model_form_budget.md").write_text(markdown(out))
        figure(out)
        return
    speeds = (800.0,) if args.quick else SPEEDS
    names = (QUICK_VARIANTS if args.quick else () if args.jaxdobby_only
             else tuple(args.only or VARIANTS))
    machine = Machine.default()
    rows = {}
    for name in names:
        options = Options(steps=args.steps, **VARIANTS[name])
        for rpm in speeds:
            x0 = rows.get(("reference", rpm), {}).get("_x0")
            x0 = None if options.refine != 1 else x0
            row, x = reference_row(machine, rpm, options, x0)
            row["_x0"] = x
            rows[(name, rpm)] = row
            print(f"{name:42s} {rpm:6.0f}  pp {row['deviation_pp']:.4f} mm  "
                  f"f1 {row['f1_frozen']:.3f} Hz  ({row['wall_s']:.0f} s)", flush=True)
            _save_partial(rows)
    jax_variants = {} if args.only else {"jaxdobby, 31 modes (all)": dict(n_modes=31),
                    "jaxdobby, 8 modes": dict(n_modes=8),
                    "jaxdobby, 4 modes (default)": {}}
    if not (args.quick or args.only):
        jax_variants["jaxdobby, 4 modes, stiffness-proportional damping"] = dict(
            damping_ratio=stiffness_damping_ratios(Machine.default()))
    for name, changes in jax_variants.items():
        m = Machine.default(**changes)
        for rpm in speeds:
            rows[(name, rpm)] = jaxdobby_row(m, rpm)
            print(f"{name:42s} {rpm:6.0f}  pp {rows[(name, rpm)]['deviation_pp']:.4f} mm",
                  flush=True)
    out = dict(environment=environment(), steps_per_cycle=args.steps,
               speeds_rpm=list(speeds), rows=[
                   dict(variant=n, speed_rpm=rpm, **{k: v for k, v in r.items()
                                                     if k not in ("_x0", "variant", "speed_rpm")})
                   for (n, rpm), r in rows.items()])
    stem = ("model_form_budget_quick" if args.quick else
            "model_form_budget_only" if args.only else
            "model_form_budget_jaxdobby" if args.jaxdobby_only else "model_form_budget")
    write_json(RESULTS / f"{stem}.json", out)
    if args.only or args.jaxdobby_only:
        return
    (RESULTS / f"{stem}.md").write_text(markdown(out))
    print(markdown(out))
    if not (args.quick or args.only):
        figure(json.loads(json.dumps(out, default=float)))


def figure(out, path=FIGURE):
    """Deviation p-p against speed (reference, jaxdobby) and each variant's change [%]."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = out["rows"]
    speeds = out["speeds_rpm"]
    names = list(dict.fromkeys(r["variant"] for r in rows))

    def series(name, key="deviation_pp"):
        return np.array([next(r[key] for r in rows if r["variant"] == name and
                              r["speed_rpm"] == s) for s in speeds])

    ref = series("reference")
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, style in (("reference", "k-o"), ("jaxdobby, 4 modes (default)", "C0--s"),
                        ("jaxdobby, 31 modes (all)", "C1:^"),
                        ("all of jaxdobby's (full FE)", "C2-.v")):
        if name in names:
            a.plot(speeds, series(name), style, label=name)
    a.set_xlabel("loom speed [r/min]")
    a.set_ylabel("heald-frame deviation p-p [mm]")
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    for i, name in enumerate(n for n in names if n != "reference"):
        b.plot(speeds, 100 * (series(name) / ref - 1), marker="os^vD<>p*hx"[i % 11],
               label=name)
    b.axhspan(-2, 2, color="0.9", zorder=0)
    b.set_xlabel("loom speed [r/min]")
    b.set_ylabel("deviation p-p: change from the reference [%]")
    b.legend(fontsize=6.5)
    b.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def compact_table(out) -> str:
    """docs/model.md's table: deviation p-p [mm] of the reference and each variant's change [%],
    and the first frozen coupled frequency [Hz] at 1200 r/min."""
    rows, speeds = out["rows"], out["speeds_rpm"]
    get = {(r["variant"], r["speed_rpm"]): r for r in rows}
    lines = ["| variant | " + " | ".join(f"p-p {s:.0f}" for s in speeds) + " | f₁ at 1200 |",
             "|---|" + "---:|" * (len(speeds) + 1)]
    for name in dict.fromkeys(r["variant"] for r in rows):
        cells = []
        for s in speeds:
            r, ref = get[(name, s)], get[("reference", s)]
            cells.append(f"{r['deviation_pp']:.3f} mm" if name == "reference" else
                         f"{100 * (r['deviation_pp'] / ref['deviation_pp'] - 1):+.2f} %")
        f1 = get[(name, speeds[-1])].get("f1_frozen")
        cells.append("–" if f1 is None else f"{f1:.2f} Hz")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def markdown(out) -> str:
    """The budget table: each variant's metrics and its change from the reference [%]."""
    rows = out["rows"]
    ref = {r["speed_rpm"]: r for r in rows if r["variant"] == "reference"}
    lines = [f"Heald-frame deviation p-p [mm] and change from the reference [%]; min…max [mm] "
             f"(– where only p-p and f₁ were recorded); first frozen coupled frequency at "
             f"mid-lift [Hz] and its change; reference: "
             f"{out['steps_per_cycle']} midpoint steps per cycle.", "",
             "| variant | " + " | ".join(f"{s:.0f} r/min" for s in out["speeds_rpm"]) + " |",
             "|---|" + "---|" * len(out["speeds_rpm"])]
    for name in dict.fromkeys(r["variant"] for r in rows):
        cells = []
        for s in out["speeds_rpm"]:
            r = next(x for x in rows if x["variant"] == name and x["speed_rpm"] == s)
            d = 100 * (r["deviation_pp"] / ref[s]["deviation_pp"] - 1)
            f1 = r.get("f1_frozen")
            df = None if f1 is None else 100 * (f1 / ref[s]["f1_frozen"] - 1)
            span = ("–" if r.get("deviation_min") is None else
                    f"{r['deviation_min']:.3f}…{r['deviation_max']:.3f}")
            freq = "–" if f1 is None else f"{f1:.2f} Hz ({df:+.2f} %)"
            cells.append(f"{r['deviation_pp']:.3f} ({d:+.2f} %); {span}; {freq}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
