"""Configuration files: any parameter of the model in the users' units, as TOML.

A configuration file overrides the default machine (DESIGN.md §6) table by table; every key is
optional, unknown tables and keys are errors. Example (all values are the defaults)::

    [operating]
    speed_rpm = 800.0          # loom speed [r/min]
    warp_force_n = 690.0       # peak warp force [N]
    lift_plan = "10"           # the frame's lift sequence, one 0/1 per pick (DESIGN §7)

    [stroke]
    stroke_mm = 140.0          # or link11_position_mm = 201.0 (one of the two)

    [arm]
    thickness_mm = 6.0
    depth_mm = 40.0            # or a list, with depth_positions_mm = [0.0, 113.0, 226.0]
    youngs_modulus_pa = 2.07e11

    [model]
    n_modes = 4
    n_elements = 10            # elements of the arm's mesh (4…200)
    damping_ratio = 0.02
    coupling = "two-way"       # or "one-way"
    warp_law = "restoring"     # or "opposing"

    [solver]
    method = "collocation"     # or "rk4", "adaptive" (default: collocation; rk4 for one-way)

Every key of every table is listed by ``jaxdobby simulate --list-parameters`` and in the README.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path

import jax.numpy as jnp

from .errors import InputError
from .machine import COUPLINGS, WARP_LAWS
from .motion_laws import MOTION_LAWS
from .parameters import PARAMETERS, Parameter, Setup, apply
from .simulate import METHODS

MAX_MODES = 30
MIN_ELEMENTS, MAX_ELEMENTS = 4, 200

OPTIONS: dict[str, dict[str, str]] = {
    "operating": {"lift_plan": "the frame's lift sequence over the repeat, one 0/1 per pick "
                               "(1 = up in that pick's shed), at least 2 picks, e.g. \"1100\""},
    "model": {"n_modes": f"modes of the arm kept, integer 1…{MAX_MODES}",
              "n_elements": f"elements of the arm's mesh, integer {MIN_ELEMENTS}…{MAX_ELEMENTS} "
                            "(key points stay nodes; 10 = the source study's 11 nodes)",
              "coupling": f"one of {', '.join(COUPLINGS)}",
              "warp_law": f"one of {', '.join(WARP_LAWS)}"},
    "linkage": {"motion_law": f"modulator law, one of {', '.join(sorted(MOTION_LAWS))}"},
    "solver": {"method": f"one of {', '.join(METHODS)}",
               "steps": "steps per cycle of collocation or RK4, integer >= 72 (default: 432 for "
                        "collocation, from the highest mode for RK4)"},
}
"""Non-float settings by table: key → what is valid."""


@dataclasses.dataclass
class RunOptions:
    """Settings of a run that are not float parameters of the model."""

    method: str | None = None  # None: collocation for two-way coupling, RK4 for one-way
    steps: int | None = None
    lift_plan: str | None = None  # None: plain weave ("10")


def keys_by_section() -> dict[str, dict[str, str]]:
    """Every valid key of every table with a description (for help and error texts)."""
    out: dict[str, dict[str, str]] = {}
    for p in PARAMETERS.values():
        out.setdefault(p.section, {})[p.key] = (
            f"{p.description} [{p.unit or '-'}], {p.range_text()}")
    for section, keys in OPTIONS.items():
        out.setdefault(section, {}).update(keys)
    return out


def check_value(p: Parameter, value, where: str) -> list[float]:
    """Validate a parameter value (a number or, for list parameters, a list) in users' units."""
    values = value if isinstance(value, list) else [value]
    if not values:
        raise InputError(f"{where} must not be an empty list")
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{where} must be a number [{p.unit}], got {v!r}")
        low, high = p.limits
        ok = (math.isfinite(v) and (v >= low if p.low_closed else v > low)
              and (v <= high if p.high_closed else v < high))
        if not ok:
            raise InputError(f"{where} = {v:g} {p.unit} is outside the valid range "
                             f"({p.range_text()} {p.unit})".replace(" )", ")"))
        out.append(float(v))
    return out


def _check_option(section: str, key: str, value, options: RunOptions, setup: Setup) -> Setup:
    where = f"[{section}] {key}"
    if key == "lift_plan":
        from .weave.plan import parse_plan

        if not isinstance(value, str):
            raise InputError(f'{where} must be a text of 0/1 characters, e.g. "1100"')
        parse_plan(value, field=where)
        options.lift_plan = value.strip()
        return setup
    if key == "n_elements":
        return with_elements(setup, value, where)
    if key in ("n_modes", "steps"):
        low = 1 if key == "n_modes" else 72
        high = MAX_MODES if key == "n_modes" else 10_000_000
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise InputError(f"{where} = {value!r} is outside the valid range "
                             f"(an integer {low}…{high})")
        if key == "steps":
            options.steps = value
            return setup
        return dataclasses.replace(setup, machine=setup.machine.replace(n_modes=value))
    valid = {"coupling": COUPLINGS, "warp_law": WARP_LAWS, "motion_law": tuple(MOTION_LAWS),
             "method": METHODS}[key]
    if value not in valid:
        raise InputError(f"{where} = {value!r} is not valid: use one of {', '.join(valid)}")
    if key == "method":
        options.method = value
        return setup
    if key == "motion_law":
        linkage = setup.machine.linkage.replace(motion_law=value)
        return dataclasses.replace(setup, machine=setup.machine.replace(linkage=linkage))
    return dataclasses.replace(setup, machine=setup.machine.replace(**{key: value}))


def with_elements(setup: Setup, value, where: str) -> Setup:
    """``setup`` with the arm meshed into ``value`` elements (validated; ``where`` names the
    field in the error)."""
    if (isinstance(value, bool) or not isinstance(value, int)
            or not MIN_ELEMENTS <= value <= MAX_ELEMENTS):
        raise InputError(f"{where} = {value!r} is outside the valid range "
                         f"(an integer {MIN_ELEMENTS}…{MAX_ELEMENTS})")
    arm = dataclasses.replace(setup.machine.arm, n_elements=value)
    return dataclasses.replace(setup, machine=setup.machine.replace(arm=arm))


def from_mapping(data: Mapping, setup: Setup | None = None,
                 options: RunOptions | None = None) -> tuple[Setup, RunOptions]:
    """Apply a parsed configuration (tables of users'-unit values) to ``setup``."""
    setup = Setup() if setup is None else setup
    options = RunOptions() if options is None else options
    valid = keys_by_section()
    by_key = {(p.section, p.key): p for p in PARAMETERS.values()}
    values_si = {}
    for section, table in data.items():
        if section not in valid:
            raise InputError(f"unknown table [{section}] in the configuration: valid tables are "
                             f"{', '.join('[' + s + ']' for s in valid)}")
        if not isinstance(table, Mapping):
            raise InputError(f"[{section}] must be a table of key = value pairs")
        for key, value in table.items():
            if key not in valid[section]:
                raise InputError(f"unknown key '{key}' in [{section}]: valid keys are "
                                 f"{', '.join(valid[section])}")
            if (section, key) in by_key:
                p = by_key[(section, key)]
                checked = check_value(p, value, f"[{section}] {key}")
                v = jnp.asarray(checked if isinstance(value, list) else checked[0]) * p.scale
                values_si[p.name] = v
            else:
                setup = _check_option(section, key, value, options, setup)
    if "stroke" in values_si and "link11_position" in values_si:
        raise InputError("[stroke] give either stroke_mm or link11_position_mm, not both")
    return apply_checked(setup, values_si), options


def apply_checked(setup: Setup, values_si: Mapping) -> Setup:
    """:func:`jaxdobby.parameters.apply`, with an unreachable stroke as an :class:`InputError`."""
    try:
        return apply(setup, values_si)
    except ValueError as err:
        raise InputError(str(err)) from None


def load(path: str | Path, setup: Setup | None = None) -> tuple[Setup, RunOptions]:
    """Read a TOML configuration file and apply it to ``setup`` (default machine)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"configuration file {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read configuration file {path}: {err}") from None
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"configuration file {path} is not valid TOML: {err}") from None
    return from_mapping(data, setup)


def to_toml(setup: Setup, options: RunOptions | None = None) -> str:
    """A configuration file reproducing ``setup`` (the float parameters and model options)."""
    sections: dict[str, list[str]] = {}
    for p in PARAMETERS.values():
        if p.name == "stroke":  # the joint position pins the stroke exactly
            continue
        v = jnp.asarray(p.get(setup)) / p.scale
        text = (repr(float(v)) if v.ndim == 0
                else "[" + ", ".join(repr(float(x)) for x in v) + "]")
        sections.setdefault(p.section, []).append(f"{p.key} = {text}")
    m = setup.machine
    sections["linkage"].append(f'motion_law = "{m.linkage.motion_law}"')
    sections["model"] += [f"n_modes = {m.n_modes}", f"n_elements = {m.arm.n_elements}",
                          f'coupling = "{m.coupling}"',
                          f'warp_law = "{m.warp_law}"']
    if options is not None:
        if options.lift_plan is not None:
            sections["operating"].append(f'lift_plan = "{options.lift_plan}"')
        solver = ([f'method = "{options.method}"'] if options.method is not None else []) + (
            [f"steps = {options.steps}"] if options.steps is not None else [])
        if solver:
            sections["solver"] = solver
    return "\n".join(f"[{name}]\n" + "\n".join(lines) + "\n" for name, lines in sections.items())


def keys_markdown() -> str:
    """Every table and key of the configuration file as a markdown table (for the README)."""
    from .parameters import Setup as _Setup

    defaults = _Setup()
    lines = ["| table | key | meaning, unit, valid range | default |", "|---|---|---|---|"]
    by_key = {(p.section, p.key): p for p in PARAMETERS.values()}
    option_defaults = {"n_modes": defaults.machine.n_modes,
                       "n_elements": defaults.machine.arm.n_elements,
                       "coupling": defaults.machine.coupling,
                       "warp_law": defaults.machine.warp_law,
                       "motion_law": defaults.machine.linkage.motion_law,
                       "method": "collocation (rk4 for one-way)",
                       "lift_plan": '"10" (plain weave)',
                       "steps": "432 (collocation), from the highest mode (rk4)"}
    for section, keys in keys_by_section().items():
        for key, text in keys.items():
            p = by_key.get((section, key))
            if p is not None:
                v = jnp.asarray(p.get(defaults)) / p.scale
                default = (f"{float(v):.6g}" if v.ndim == 0
                           else ", ".join(f"{float(x):.6g}" for x in v))
            else:
                default = option_defaults[key]
            lines.append(f"| [{section}] | `{key}` | {text} | {default} |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    import jax

    jax.config.update("jax_enable_x64", True)
    print(keys_markdown())
