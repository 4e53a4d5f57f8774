"""Is a run's answer trustworthy? Named warnings when a result leaves the model's validity.

The model (DESIGN §2) is linear-elastic and small-deformation in the arm's floating frame, its
modes reduced about the undeformed arm, the chain driven through exact closures of the rigid
linkage. A number it returns outside those assumptions is still a number, so every result
carries a list of warnings, each a dict ``{"code", "message", "value", "limit"}``:

* ``arm_deflection`` — the link-11 joint's elastic displacement |Φ_P q| against its distance
  from the pivot |p|, max over the cycle, above :data:`DEFLECTION_LIMIT` (1 %): the model
  neglects the arm's foreshortening (second order, ≈ δ²/(2L), i.e. δ/(2L) of the deflection
  itself) and reduces with the modes of the undeformed arm; at δ/L = 1 % those errors reach
  ~0.5 % of the deviation and grow linearly beyond.
* ``deviation_of_stroke`` — the heald-frame deviation (peak to peak) above
  :data:`DEVIATION_LIMIT` (5 %) of the stroke: the warp force, the chain's inertia and the
  modes are all evaluated about the rigid motion (DESIGN §2 items 4–6); a deviation that is a
  sizeable part of the motion itself is outside that linearisation.
* ``workspace`` — the deformed arm takes the link-11 joint where link 11 cannot reach the big
  blade (the double-rocker loop does not close; the chain is then clamped, not solved).
* ``transmission_angle`` — the double rocker 10–11–12's transmission angle μ (between link 11
  and the blade's input arm) on the *flexible* motion drops below :data:`TRANSMISSION_LIMIT`
  (20°; design practice asks μ ≥ 30–40°, Norton, *Design of Machinery*, §4.10): the joint
  force's useful component ∝ sin μ collapses and the closure's sensitivity ∝ 1/sin μ explodes.
* ``resonance`` — a harmonic k·n/120 Hz of the heald-frame cycle (n in r/min; a cycle is two
  picks, so the pick-rate harmonics k·n/60 are among them), k ≤ :data:`HARMONICS`, lies within
  :data:`RESONANCE_BAND` (3 %) of a coupled natural frequency at some phase of the cycle (the
  frequencies vary with the configuration: min…max over :data:`PHASES` phases): near a
  resonance the response is damping-controlled (2 % modal damping: half-power half-width 2 %)
  and sensitive to every parameter.
* ``not_converged`` — the periodic steady state was not found to the required periodicity.
* ``yield_exceeded`` (peak stress above the arm's yield strength: the elastic model no longer
  holds) and ``fatigue_limit_exceeded`` (Goodman factor < 1) — the arm's stress checks, made by
  :func:`jaxdobby.stress.summary.warning_entries` and added to the same list by
  :func:`jaxdobby.simulate.summary_of`.

:func:`validity_arrays` computes, inside the traced run, the arrays these checks need (they are
part of :func:`jaxdobby.simulate.report_arrays`, so the stored program returns them);
:func:`warnings_of` turns them into warnings on the host; :func:`setup_warnings` runs them for a
machine another command found (optimize, identify). A batched evaluator counts them per sample
(:mod:`jaxdobby.sensitivity.validity`).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from .dobby import rigid_joint_position
from .eigen import MAX_MODES, generalized_eigvalsh_small
from .kinematics import blade_angle
from .linkage import intersection_margin
from .outputs import coupled_frequencies, coupled_matrices, frequencies_of

DEFLECTION_LIMIT = 0.01
"""Largest elastic displacement of the link-11 joint over its distance from the pivot [-]."""
DEVIATION_LIMIT = 0.05
"""Largest heald-frame deviation (peak to peak) over the stroke [-]."""
TRANSMISSION_LIMIT = 20.0
"""Smallest transmission angle of the double rocker on the flexible motion [deg]."""
RESONANCE_BAND = 0.03
"""Relative distance of a cycle harmonic from a coupled frequency that counts as resonance."""
HARMONICS = 12
"""Cycle harmonics k·n/120 checked for resonance, k = 1…HARMONICS (six pick harmonics): above
the 12th, each harmonic of the rigid heald-frame acceleration over a cycle is below 1 % of the
largest (measured on the default machine: 1.2 % at k = 12, 0.4 % at 13, at most 0.7 % beyond;
the rigid motion's shape does not depend on the speed)."""
PHASES = 24
"""Phases of the cycle at which the coupled frequencies are evaluated."""

CODES = ("not_converged", "arm_deflection", "deviation_of_stroke", "workspace",
         "transmission_angle", "resonance", "yield_exceeded", "fatigue_limit_exceeded")
"""Every warning code, in the order tallies report them (the last two are the arm's stress
checks, :mod:`jaxdobby.stress.summary`)."""


@eqx.filter_jit
def validity_arrays(run) -> dict[str, Array]:
    """Arrays of a :class:`~jaxdobby.simulate.Simulation` that :func:`warnings_of` needs, keyed
    ``validity.*``: the link joint's deflection ratio (max over the cycle), the double rocker's
    reach margin [m²] and sin of its transmission angle (min over the cycle, flexible motion),
    and the coupled natural frequencies at :data:`PHASES` phases [Hz], shape (PHASES, k).

    One compiled program (inlined where a caller traces it, as the command line's report
    does): run eagerly, its vmapped kinematics and eigenvalue problems compiled operation by
    operation, it took 15 s of a first :func:`~jaxdobby.simulate.summary` in a new process
    (measured 2026-12-04, 2 cores, empty cache)."""
    model, series = run.model, run.series
    chain = model.chain
    radius = jnp.linalg.norm(model.link_joint)
    deflection = jnp.max(jnp.linalg.norm(series.link_point_deviation, axis=-1)) / radius
    joint = jax.vmap(lambda t: rigid_joint_position(model, t))(series.t)
    joint = joint + series.link_point_deviation
    margin = intersection_margin(chain.blade_pivot, chain.blade_input_arm, joint,
                                 chain.link11_length)
    beta = blade_angle(chain, joint)
    pin = chain.blade_pivot + chain.blade_input_arm * jnp.stack([jnp.cos(beta), jnp.sin(beta)], -1)
    link, arm = joint - pin, chain.blade_pivot - pin
    cross = link[:, 0] * arm[:, 1] - link[:, 1] * arm[:, 0]
    sin_mu = jnp.abs(cross) / (chain.link11_length * chain.blade_input_arm)
    phases = model.period * jnp.arange(PHASES) / PHASES
    freqs = jax.vmap(lambda t: coupled_frequencies(model, t))(phases)
    return {"validity.deflection_ratio": deflection,
            "validity.reach_margin": jnp.min(margin),
            "validity.sin_transmission": jnp.min(sin_mu),
            "validity.frequencies": freqs}


def _warning(code: str, message: str, value: float, limit: float) -> dict:
    return {"code": code, "message": message, "value": float(value), "limit": float(limit)}


def warnings_of(arrays: dict, tolerance: float = 1e-6) -> list[dict]:
    """The warnings of a run from its :func:`jaxdobby.simulate.report_arrays` (numpy or JAX
    arrays; SI): a list of ``{"code", "message", "value", "limit"}``, empty when the run is
    inside every limit. Values and limits are in the message's units."""
    out = []
    converged = bool(np.asarray(arrays["converged"]))
    residual = float(np.asarray(arrays["periodicity"]))
    if not converged:
        out.append(_warning("not_converged", "the periodic steady state did not converge "
                            f"(periodicity residual {residual:.1e} > {tolerance:.0e}): the "
                            "numbers are not a steady state", residual, tolerance))
    ratio = float(np.asarray(arrays["validity.deflection_ratio"]))
    if not ratio <= DEFLECTION_LIMIT:
        out.append(_warning(
            "arm_deflection", f"the arm's elastic deflection at the link-11 joint is "
            f"{100 * ratio:.2g} % of its distance from the pivot (limit {100 * DEFLECTION_LIMIT:g} "
            "%): beyond the small-deformation model (DESIGN §2)", 100 * ratio,
            100 * DEFLECTION_LIMIT))
    stroke = float(np.asarray(arrays["stroke"]))
    pp = float(np.asarray(arrays["metric.deviation_pp"]))
    share = pp / stroke if stroke > 0 else math.inf
    if not share <= DEVIATION_LIMIT:
        out.append(_warning(
            "deviation_of_stroke", f"the heald-frame deviation ({1e3 * pp:.3g} mm) is "
            f"{100 * share:.2g} % of the stroke (limit {100 * DEVIATION_LIMIT:g} %): outside the "
            "model's linearisation about the rigid motion (DESIGN §2)", 100 * share,
            100 * DEVIATION_LIMIT))
    margin = float(np.asarray(arrays["validity.reach_margin"]))
    if not margin >= 0.0:
        out.append(_warning(
            "workspace", "the deformed arm moves the link-11 joint out of link 11's reach of "
            "the big blade: the chain is clamped, not solved", margin, 0.0))
    sin_mu = float(np.clip(np.asarray(arrays["validity.sin_transmission"]), 0.0, 1.0))
    mu = math.degrees(math.asin(sin_mu)) if math.isfinite(sin_mu) else math.nan
    if margin >= 0.0 and not mu >= TRANSMISSION_LIMIT:
        out.append(_warning(
            "transmission_angle", f"the transmission angle of link 11 on the big blade falls to "
            f"{mu:.1f}° on the flexible motion (limit {TRANSMISSION_LIMIT:g}°): the double "
            "rocker is near its dead centre", mu, TRANSMISSION_LIMIT))
    out.extend(_resonances(arrays))
    return out


def resonant(cycle_hz, low, high):
    """Which cycle harmonics are resonant: a (:data:`HARMONICS`, modes) boolean mask, True where
    harmonic k·``cycle_hz`` [Hz] (k = 1…HARMONICS) lies within :data:`RESONANCE_BAND` of mode
    m's frequency range [``low[m]``, ``high[m]``] [Hz] over the cycle. numpy or JAX arrays (the
    same condition on the host for one run and traced for a batch's samples)."""
    f = cycle_hz * np.arange(1, HARMONICS + 1, dtype=float)[:, None]
    return (low * (1 - RESONANCE_BAND) <= f) & (f <= high * (1 + RESONANCE_BAND))


def _resonances(arrays: dict) -> list[dict]:
    """``resonance`` warnings: cycle harmonics within the band of a coupled frequency."""
    cycle_hz = float(np.asarray(arrays["speed"])) / (4.0 * math.pi)  # ω/(2π)/2: two picks
    freqs = np.asarray(arrays["validity.frequencies"])
    lows, highs = np.min(freqs, axis=0), np.max(freqs, axis=0)
    mask = resonant(cycle_hz, lows, highs)
    out = []
    for mode in range(freqs.shape[1]):
        low, high = float(lows[mode]), float(highs[mode])
        for k in range(1, HARMONICS + 1):
            f = k * cycle_hz
            if mask[k - 1, mode]:
                near = min(max(f, low), high)
                out.append(_warning(
                    "resonance", f"cycle harmonic {k} ({f:.1f} Hz"
                    f"{', pick harmonic ' + str(k // 2) if k % 2 == 0 else ''}) is within "
                    f"{100 * RESONANCE_BAND:g} % of coupled mode {mode + 1} ({low:.1f}…{high:.1f} "
                    "Hz over the cycle): the response is resonant, sensitive to damping",
                    f, near))
    return out


def phase_frequencies(model) -> Array:
    """The coupled natural frequencies [Hz] at :data:`PHASES` phases of the cycle of a
    :class:`~jaxdobby.dobby.DobbyModel`, shape (PHASES, k): :func:`frequencies_hz` of
    :func:`phase_matrices`. Vmappable without a batched LAPACK call (see
    :func:`jaxdobby.periodic.steady.model_terms`)."""
    return frequencies_hz(*phase_matrices(model))


def phase_matrices(model) -> tuple[Array, Array]:
    """(mass, stiffness) of :func:`jaxdobby.outputs.coupled_frequencies` at the
    :data:`PHASES` phases, each (PHASES, k, k), all phases at once (no LAPACK call)."""
    phases = model.period * jnp.arange(PHASES) / PHASES
    return jax.vmap(lambda t: coupled_matrices(model, t))(phases)


def frequencies_hz(mass: Array, stiffness: Array) -> Array:
    """Natural frequencies [Hz] of the undamped systems (mass, stiffness), (..., k, k) →
    (..., k), ascending.

    Up to :data:`jaxdobby.eigen.MAX_MODES` modes by the unrolled Cholesky and Jacobi
    iterations of :mod:`jaxdobby.eigen`, every matrix of the batch at once; more modes by
    LAPACK (:func:`jaxdobby.outputs.frequencies_of`), one matrix at a time (``lax.map``).
    Measured for the default Sobol design's model terms with the frequencies (4 modes, 24
    phases, 128 samples, one pinned core, 2026-12-07): 0.16 ms per sample with LAPACK one
    phase at a time, 0.15 with the linearisations of all phases at once, 0.08 with this
    (the model's own part built once per distinct machine in all three); eigenvalues within
    2e-14 of LAPACK's relative to the largest (``tests/test_eigen.py``)."""
    k = mass.shape[-1]
    if k <= MAX_MODES:
        lam = generalized_eigvalsh_small(mass, stiffness)
        return jnp.sqrt(jnp.clip(lam, 0.0)) / (2.0 * jnp.pi)
    lead = mass.shape[:-2]
    flat = jax.lax.map(lambda m: frequencies_of(*m),
                       (mass.reshape((-1, k, k)), stiffness.reshape((-1, k, k))))
    return flat.reshape(lead + (k,))


def setup_warnings(setup, options, *, directory=None) -> list[dict]:
    """The warnings ``jaxdobby simulate`` reports for ``setup`` (a
    :class:`~jaxdobby.parameters.Setup`) run with ``options`` (a
    :class:`~jaxdobby.config.RunOptions`): its summary's ``warnings`` (the checks above and the
    arm's stress), through the command line's stored program (``directory``: where programs
    are stored; :func:`jaxdobby.simulate.stored_report`). For commands whose own solver is
    another (optimize, identify): their resulting machine, checked as simulate would. A run
    that fails (non-finite numbers) is one ``not_converged`` warning naming why (value and
    limit None)."""
    from .simulate import stored_report

    summary = stored_report(setup, options, directory=directory)[0]
    reason = failure(summary)
    if reason is not None:
        return [{"code": "not_converged", "message": reason, "value": None, "limit": None}]
    return summary["warnings"]


def warning_lines(warnings: list[dict]) -> str:
    """The warnings as text lines for a summary (empty string if none)."""
    return "\n".join(f"  warning [{w['code']}]: {w['message']}" for w in warnings)


def failure(summary: dict) -> str | None:
    """Why a run's summary cannot be shown, or None: the names of its non-finite numbers (a
    solver failure — the steady state diverged), as one line."""
    bad = [k for k, v in summary.items()
           if isinstance(v, float) and not math.isfinite(v)
           or isinstance(v, list) and any(isinstance(x, float) and not math.isfinite(x)
                                          for x in v)]
    if not bad:
        return None
    return (f"the solver failed: the steady-state iteration diverged after "
            f"{summary.get('newton_iterations', '?')} Newton iterations and left non-finite "
            f"{', '.join(bad[:3])}{' …' if len(bad) > 3 else ''} (the input is outside what the "
            "solver handles: see the README's Limits)")


def tally(labelled) -> dict[str, dict]:
    """Warnings of many runs, by code: ``{code: {"count", "samples"}}`` from ``(label,
    warnings)`` pairs (a label per run: a swept value, a sample row), in :data:`CODES` order.
    Each run counts once per code (a run with two resonant harmonics is one resonant run)."""
    out: dict[str, dict] = {}
    for label, warnings in labelled:
        for code in dict.fromkeys(w["code"] for w in warnings):
            entry = out.setdefault(code, {"count": 0, "samples": []})
            entry["count"] += 1
            entry["samples"].append(label)
    order = {c: i for i, c in enumerate(CODES)}
    return dict(sorted(out.items(), key=lambda kv: order.get(kv[0], len(order))))


def tally_lines(counts: dict[str, dict], total: int, what: str = "runs", limit: int = 12) -> str:
    """:func:`tally` as text lines: ``warning [code]: k of n runs: a, b, c …``."""
    lines = []
    for code, entry in counts.items():
        shown = ", ".join(str(s) for s in entry["samples"][:limit])
        more = " …" if len(entry["samples"]) > limit else ""
        lines.append(f"  warning [{code}]: {entry['count']} of {total} {what}: {shown}{more}")
    return "\n".join(lines)
