"""Readable tables and files of a run (used by the command line)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from .io import write_json, write_text

SUMMARY_ROWS = [
    ("speed_rpm", "loom speed", "r/min", "{:.0f}"),
    ("warp_force_n", "peak warp force", "N", "{:.0f}"),
    ("stroke_mm", "heald-frame stroke (rigid)", "mm", "{:.2f}"),
    ("thickness_mm", "arm thickness", "mm", "{:.2f}"),
    ("n_modes", "modes kept", "", "{}"),
    ("coupling", "coupling", "", "{}"),
    ("warp_law", "warp-force law", "", "{}"),
    ("deviation_min_mm", "displacement deviation, min", "mm", "{:+.3f}"),
    ("deviation_max_mm", "displacement deviation, max", "mm", "{:+.3f}"),
    ("deviation_pp_mm", "displacement deviation, peak to peak", "mm", "{:.3f}"),
    ("link_point_deviation_x_mm", "link-11 joint deviation, horizontal (p-p)", "mm", "{:.3f}"),
    ("link_point_deviation_y_mm", "link-11 joint deviation, vertical (p-p)", "mm", "{:.3f}"),
    ("velocity_deviation_amp_m_s", "velocity deviation (p-p)", "m/s", "{:.3f}"),
    ("acceleration_amp_m_s2", "acceleration, flexible (p-p)", "m/s²", "{:.0f}"),
    ("acceleration_rigid_amp_m_s2", "acceleration, rigid (p-p)", "m/s²", "{:.0f}"),
    ("ring_link_force_max_n", "ring-link force, max", "N", "{:.0f}"),
    ("link11_force_max_n", "link-11 force, max", "N", "{:.0f}"),
    ("stress_max_mpa", "arm stress, largest |σ| over the cycle", "MPa", "{:.0f}"),
    ("stress_max_position_mm", "  at arc length (edge below)", "mm", "{:.1f}"),
    ("stress_max_edge", "  edge (looking from the pivot)", "", "{}"),
    ("stress_range_mpa", "  stress range there (max − min)", "MPa", "{:.0f}"),
    ("stress_mean_mpa", "  mean stress there", "MPa", "{:+.0f}"),
    ("fatigue_safety_factor", "fatigue safety factor (Goodman, min)", "", "{:.2f}"),
    ("natural_frequencies_hz", "coupled natural frequencies", "Hz", None),
    ("converged", "periodic steady state", "", None),
]


def summary_table(summary: dict) -> str:
    """The summary as an aligned two-column table."""
    lines = []
    for key, label, unit, fmt in SUMMARY_ROWS:
        if key not in summary:
            continue
        v = summary[key]
        if key == "natural_frequencies_hz":
            text = ", ".join(f"{f:.0f}" for f in v)
        elif key == "converged" and summary.get("static"):  # a plan that never moves
            label, text = "static equilibrium (the frame never moves)", "yes" if v else "NO"
        elif key == "converged":
            text = (f"{'yes' if v else 'NO'} (periodicity residual "
                    f"{summary['periodicity_residual']:.1e})")
        else:
            text = fmt.format(v)
        lines.append(f"  {label:<44} {text:>14} {unit}")
    if "lift_plan" in summary:
        lines.append(f"  {'dwell vibration, max over the repeat':<44} "
                     f"{summary['dwell_vibration_max_mm']:>14.3f} mm")
        lines.append("  pick  lift  moves  shed-open deviation [mm]  dwell vibration pp [mm]")
        for k, (b, mv, dev, vib) in enumerate(zip(summary["lift_plan"], summary["moves"],
                                                 summary["shed_deviation_mm"],
                                                 summary["dwell_vibration_pp_mm"])):
            lines.append(f"  {k + 1:>4}  {b:>4}  {'yes' if mv else 'no':>5}  {dev:>24.3f}  "
                         f"{vib:>23.3f}")
    return "\n".join(lines)


TIMESERIES_COLUMNS = [
    ("t_s", lambda s: s.t, 1.0),
    ("heald_rigid_mm", lambda s: s.heald_rigid, 1e3),
    ("heald_flexible_mm", lambda s: s.heald_flexible, 1e3),
    ("deviation_mm", lambda s: s.deviation, 1e3),
    ("velocity_rigid_m_s", lambda s: s.velocity_rigid, 1.0),
    ("velocity_flexible_m_s", lambda s: s.velocity_flexible, 1.0),
    ("velocity_deviation_m_s", lambda s: s.velocity_deviation, 1.0),
    ("acceleration_rigid_m_s2", lambda s: s.acceleration_rigid, 1.0),
    ("acceleration_flexible_m_s2", lambda s: s.acceleration_flexible, 1.0),
    ("acceleration_deviation_m_s2", lambda s: s.acceleration_deviation, 1.0),
    ("link_point_deviation_x_mm", lambda s: s.link_point_deviation[:, 0], 1e3),
    ("link_point_deviation_y_mm", lambda s: s.link_point_deviation[:, 1], 1e3),
    ("ring_link_force_n", lambda s: s.ring_link_force, 1.0),
    ("link11_force_x_n", lambda s: s.link11_force[:, 0], 1.0),
    ("link11_force_y_n", lambda s: s.link11_force[:, 1], 1.0),
]


def timeseries_csv(series, pick=None, stress=None) -> str:
    """The time series as CSV text, one row per output time (columns named with their units);
    ``pick``: the pick (1…P) of each row of a lift plan's repeat, a ``pick`` column; with
    ``stress`` (:class:`~jaxdobby.stress.cycle.CycleStress`) also the stress at the arm's
    critical point, ``stress_critical_mpa``."""
    cols = [(name, np.asarray(fn(series)) * scale) for name, fn, scale in TIMESERIES_COLUMNS]
    if pick is not None:
        cols.insert(1, ("pick", np.asarray(pick) + 1))
    if stress is not None:
        cols.append(("stress_critical_mpa", np.asarray(stress.critical) * 1e-6))
    modal = np.asarray(series.modal)
    cols += [(f"q{i + 1}", modal[:, i]) for i in range(modal.shape[1])]
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([c for _, c in cols]), delimiter=",",
               header=",".join(n for n, _ in cols), comments="", fmt="%.15g")
    return buf.getvalue()


def write_run(directory: str | Path, summary: dict, series, figures: bool = True,
              pick=None, stress=None) -> list[Path]:
    """Write ``summary.json``, ``timeseries.csv`` (``pick``: its pick column, see
    :func:`timeseries_csv`) and the figures into ``directory`` (with ``stress``, a
    :class:`~jaxdobby.stress.cycle.CycleStress`, also its CSV column and the stress-envelope
    figure ``arm_stress.png``)."""
    from .plots import save_figures

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = [write_json(directory / "summary.json", summary),
             write_text(directory / "timeseries.csv", timeseries_csv(series, pick, stress))]
    if figures:
        label = f"{summary['speed_rpm']:.0f} r/min, {summary['warp_force_n']:.0f} N"
        paths += save_figures(series, directory, label=label)
        if stress is not None:
            from .plots import plt
            from .stress.plots import envelope_figure

            fig = envelope_figure(stress, summary, label=label)
            fig.savefig(directory / "arm_stress.png", dpi=120)
            plt.close(fig)
            paths.append(directory / "arm_stress.png")
    return paths


def beam_report(n_modes: int = 8) -> str:
    """Natural frequencies of the default arm, bare (pinned + ring link) and in the mechanism."""
    import jax.numpy as jnp

    from .dobby import build_model
    from .machine import Machine, OperatingPoint
    from .outputs import coupled_frequencies

    import equinox as eqx

    machine = Machine.default(n_modes=n_modes)
    model = eqx.filter_jit(build_model)(machine, OperatingPoint())
    coupled = eqx.filter_jit(coupled_frequencies)(model)
    arm = machine.arm
    lines = [
        "Default bending arm (DESIGN.md §6): 105 mm straight + R400 arc over 13.75° + 25 mm tip,",
        f"  {float(arm.thickness) * 1e3:.1f} mm × {float(arm.depth[0]) * 1e3:.1f} mm steel section, "
        "11 nodes / 10 elements, pinned at the pivot,",
        f"  ring link k9 = {float(machine.ring_link_stiffness):.3g} N/m at node 4 (mid-lift "
        "direction)",
        "",
        f"  {'mode':>4}  {'arm alone [Hz]':>15}  {'in the mechanism [Hz]':>22}",
    ]
    for i, (f_arm, f_mech) in enumerate(zip(jnp.asarray(model.body.frequencies_hz),
                                             jnp.asarray(coupled))):
        lines.append(f"  {i + 1:>4}  {float(f_arm):>15.1f}  {float(f_mech):>22.1f}")
    lines.append("")
    lines.append("  'in the mechanism': with the heald frame and blade inertia coupled through "
                 "the linkage,\n  at mid-stroke (see jaxdobby.outputs.coupled_frequencies).")
    return "\n".join(lines)


def dumps(summary: dict) -> str:
    """The summary as JSON text."""
    return json.dumps(summary, indent=2)
