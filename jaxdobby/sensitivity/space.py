"""The parameter space of a Sobol study: names, bounds and units of the varied parameters.

A :class:`ParameterSpace` lists the model parameters a study varies, in order, each with its
bounds in the users' units (r/min, N, mm, …) and the factor that turns that unit into SI. It
gives SALib its problem dict, draws Saltelli/Sobol' sample matrices, and maps one sample row to
named SI values for the model.

Which names a space may hold, their units and their default bounds come from a *registry*: a
mapping from name to :class:`ParameterSpec`, supplied by the model (see ``models.py``). A space
built without a registry accepts any names (unit "1").

Problem files are TOML::

    # bounds in the parameter's unit (the registry's; a unit given here must match it)
    [parameters]
    speed = [400, 1200]
    stroke = { bounds = [80, 140], unit = "mm" }

Bad input raises ``ValueError`` naming the field and its valid range.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping, Sequence
from os import PathLike

import numpy as np
from jax import Array


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """One parameter a study may vary.

    Attributes:
        name: the parameter's name, as used on the command line and in problem files.
        unit: the users' unit of its bounds and sample values, e.g. ``"r/min"``.
        bounds: default (lower, upper) bounds [unit].
        si_scale: one ``unit`` in SI, e.g. 1e-3 for mm → m (so SI value = value · si_scale).
        limits: the physically valid open interval (low, high) [unit]; bounds must lie inside.
        description: a few words for help texts.
    """

    name: str
    unit: str = "1"
    bounds: tuple[float, float] | None = None
    si_scale: float = 1.0
    limits: tuple[float, float] = (-math.inf, math.inf)
    description: str = ""


def check_base_samples(n: int) -> int:
    """Validate the number of base samples N of a Sobol' design.

    Args:
        n: base samples; the Sobol' sequence keeps its balance properties only for powers of two.

    Returns:
        ``n`` as an ``int``.

    Raises:
        ValueError: unless ``n`` is an integer power of two, ≥ 2.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2 or n & (n - 1):
        raise ValueError("n (base samples) must be a power of two >= 2 (2, 4, …, 1024, …); "
                         f"got {n!r}")
    return int(n)


@dataclasses.dataclass(frozen=True)
class ParameterSpace:
    """Ordered parameters of a study with their bounds in the users' units.

    Attributes:
        names: parameter names, in the order of the sample matrix columns.
        bounds: (lower, upper) per parameter [its unit], lower < upper, finite.
        units: unit label per parameter.
        si_scales: one unit in SI per parameter (SI value = value · scale).
    """

    names: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    units: tuple[str, ...]
    si_scales: tuple[float, ...]

    def __post_init__(self):
        if not self.names:
            raise ValueError("parameters: a study needs at least one parameter; got none")
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"parameters: names must be unique; got {list(self.names)}")
        if not len(self.bounds) == len(self.units) == len(self.si_scales) == len(self.names):
            raise ValueError("parameters: names, bounds, units and si_scales differ in length")
        for name, (lo, hi), unit in zip(self.names, self.bounds, self.units):
            if not (math.isfinite(lo) and math.isfinite(hi)):
                raise ValueError(f"parameter {name!r}: bounds must be finite numbers [{unit}]; "
                                 f"got [{lo}, {hi}]")
            if not lo < hi:
                raise ValueError(f"parameter {name!r}: lower bound must be < upper bound [{unit}]; "
                                 f"got [{lo}, {hi}]")

    @classmethod
    def from_specs(cls, specs: Sequence[ParameterSpec]) -> "ParameterSpace":
        """A space over ``specs``, each with its own bounds, checked against its limits."""
        for s in specs:
            if s.bounds is None:
                raise ValueError(f"parameter {s.name!r}: no bounds given and no default bounds")
            _check_limits(s, s.bounds)
        return cls(
            names=tuple(s.name for s in specs),
            bounds=tuple((float(s.bounds[0]), float(s.bounds[1])) for s in specs),
            units=tuple(s.unit for s in specs),
            si_scales=tuple(float(s.si_scale) for s in specs),
        )

    @classmethod
    def from_names(cls, names: Sequence[str], registry: Mapping[str, ParameterSpec]
                   ) -> "ParameterSpace":
        """A space over a subset of the registry's parameters, with their default bounds.

        Args:
            names: parameter names, in the order wanted.
            registry: the allowed parameters with their units and default bounds.
        """
        return cls.from_specs([_lookup(n, registry) for n in names])

    @classmethod
    def from_mapping(cls, data: Mapping, registry: Mapping[str, ParameterSpec] | None = None,
                     source: str = "problem") -> "ParameterSpace":
        """A space from a parsed problem file (see the module docstring for the layout)."""
        unknown = set(data) - {"parameters"}
        if unknown:
            raise ValueError(f"{source}: unknown top-level key(s) {sorted(unknown)}; the only key "
                             "is [parameters]")
        params = data.get("parameters")
        if not isinstance(params, Mapping) or not params:
            raise ValueError(f"{source}: needs a non-empty [parameters] table mapping names to "
                             "[lower, upper] or { bounds = [lower, upper], unit = \"…\" }")
        specs = []
        for name, entry in params.items():
            spec = _lookup(name, registry) if registry is not None else ParameterSpec(name)
            unit = None
            if isinstance(entry, Mapping):
                extra = set(entry) - {"bounds", "unit"}
                if extra:
                    raise ValueError(f"parameter {name!r}: unknown key(s) {sorted(extra)}; "
                                     "allowed: bounds, unit")
                unit, entry = entry.get("unit"), entry.get("bounds")
            bounds = _parse_bounds(name, entry, spec.unit)
            if unit is not None and registry is not None and unit != spec.unit:
                raise ValueError(f"parameter {name!r}: unit must be {spec.unit!r} (bounds are not "
                                 f"converted); got {unit!r}")
            specs.append(dataclasses.replace(spec, bounds=bounds,
                                             unit=spec.unit if unit is None else unit))
        return cls.from_specs(specs)

    @classmethod
    def from_toml(cls, path: str | PathLike, registry: Mapping[str, ParameterSpec] | None = None
                  ) -> "ParameterSpace":
        """A space from a TOML problem file (see the module docstring for the layout).

        Raises:
            ValueError: malformed TOML, unknown names or keys, or bad bounds, naming the field.
            FileNotFoundError: no such file.
        """
        with open(path, "rb") as f:
            try:
                data = tomllib.load(f)
            except tomllib.TOMLDecodeError as e:
                raise ValueError(f"problem file {str(path)!r} is not valid TOML: {e}") from None
        return cls.from_mapping(data, registry, source=f"problem file {str(path)!r}")

    @property
    def dim(self) -> int:
        """Number of parameters D."""
        return len(self.names)

    @property
    def problem(self) -> dict:
        """SALib's problem dict ``{"num_vars", "names", "bounds"}``, bounds in the users' units."""
        return {"num_vars": self.dim, "names": list(self.names),
                "bounds": [list(b) for b in self.bounds]}

    def to_dict(self) -> dict:
        """A JSON-ready description: names, bounds, units, SI scales."""
        return {"names": list(self.names), "bounds": [list(b) for b in self.bounds],
                "units": list(self.units), "si_scales": list(self.si_scales)}

    def rows_per_base_sample(self, second_order: bool) -> int:
        """Rows of the Saltelli design per base sample: 2D + 2 with second order, else D + 2."""
        return 2 * self.dim + 2 if second_order else self.dim + 2

    def sample(self, n: int, *, second_order: bool, seed: int) -> np.ndarray:
        """The Saltelli/Sobol' design for SALib's ``sobol.analyze``.

        Args:
            n: base samples N, a power of two ≥ 2.
            second_order: include the B_A^i blocks needed for second-order indices.
            seed: seed of the Owen scrambling of the Sobol' sequence.

        Returns:
            float64 array (N · rows_per_base_sample, D) [users' units], grouped by base sample.
        """
        from SALib.sample import sobol  # SALib imports pandas: keep it off the import path

        n = check_base_samples(n)
        x = sobol.sample(self.problem, n, calc_second_order=second_order, scramble=True, seed=seed)
        return np.ascontiguousarray(x, dtype=np.float64)

    def to_si(self, x: Array) -> dict[str, Array]:
        """Map one sample row to named SI values: ``{name: x[i] · si_scale[i]}``.

        Args:
            x: one sample row, shape (D,) [users' units]; may be traced.
        """
        return {n: x[i] * s for i, (n, s) in enumerate(zip(self.names, self.si_scales))}


def _lookup(name: str, registry: Mapping[str, ParameterSpec]) -> ParameterSpec:
    if name not in registry:
        raise ValueError(f"parameter {name!r}: unknown name; valid names are {sorted(registry)}")
    return registry[name]


def _parse_bounds(name: str, entry, unit: str) -> tuple[float, float]:
    ok = (isinstance(entry, Sequence) and not isinstance(entry, str) and len(entry) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in entry))
    if not ok:
        raise ValueError(f"parameter {name!r}: bounds must be two numbers [lower, upper] [{unit}]; "
                         f"got {entry!r}")
    return float(entry[0]), float(entry[1])


def _check_limits(spec: ParameterSpec, bounds) -> None:
    lo, hi = spec.limits
    b_lo, b_hi = bounds
    if math.isfinite(b_lo) and math.isfinite(b_hi) and not (lo < b_lo and b_hi < hi):
        raise ValueError(f"parameter {spec.name!r}: bounds must lie in ({lo}, {hi}) [{spec.unit}]; "
                         f"got [{b_lo}, {b_hi}]")
