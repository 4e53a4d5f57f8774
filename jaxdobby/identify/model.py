"""The model side of an identification: the fitted parameters, and the steady cycle they give,
sampled at any time by trigonometric interpolation.

The fitted vector is u = (z₁ … z_p, φ, b):

* z_i, one per fitted parameter, dimensionless: z = ln(θ/θ⁰) for a positive parameter (its
  registry range starts at 0: masses, inertias, the damping ratio…), so that the fit cannot
  leave the positive axis and the steps are relative, else z = (θ − θ⁰)/s with the scale
  s = |θ⁰| (or 1 mm / 1 SI unit when θ⁰ = 0); θ⁰ is the starting value. z is clipped to the
  bounds (the registry's validity range, tightened by the user's) before it reaches the model:
  an estimate on a bound is reported as such;
* φ, the shift of the measured time origin as a fraction of the heald-frame cycle T: the
  measured sample at time t_j is compared with the model at t_j + φT;
* b, an offset of the position channel [mm] (the sensor's zero is arbitrary).

The steady cycle of :func:`jaxdobby.simulate.simulate` is given on a uniform grid of N points
over [0, T); the periodic trace through those points with the fewest harmonics is the
trigonometric interpolant (Trefethen, *Spectral Methods in MATLAB*, ch. 3; for even N the
Nyquist term is split evenly)

    g(t) = Σ_{k=0}^{N/2} w_k Re[ĝ_k e^{2πikt/T}],   ĝ = FFT(g)/N,  w_0 = w_{N/2} = 1, w_k = 2,

exact for a trace band-limited below N/2 harmonics and smooth (every order) in t and in ĝ.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..config import RunOptions
from ..errors import InputError
from ..parameters import PARAMETERS, Setup, apply
from ..simulate import resolve_method, simulate

MM = 1e-3
TOLERANCE = 1e-9
"""Relative periodicity asked of the steady state (the optimiser's, :mod:`jaxdobby.optimize`)."""


@dataclasses.dataclass(frozen=True)
class Parameterisation:
    """How the fitted parameters enter the model (static; see the module docstring).

    Attributes:
        names: registry names of the fitted parameters (:data:`jaxdobby.parameters.PARAMETERS`).
        start: their starting values θ⁰ [SI].
        log: whether each is fitted as ln(θ/θ⁰).
        scale: s of the linear ones [SI] (1.0 for the log ones).
        lower, upper: bounds on z.
    """

    names: tuple[str, ...]
    start: tuple[float, ...]
    log: tuple[bool, ...]
    scale: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]

    @property
    def keys(self) -> tuple[str, ...]:
        """The TOML keys of the fitted parameters (``heald_frame_mass_kg``…)."""
        return tuple(PARAMETERS[n].key for n in self.names)

    def values(self, z) -> np.ndarray:
        """θ [SI] from z (clipped to the bounds), shape (p,) (numpy)."""
        z = np.clip(np.asarray(z, float), self.lower, self.upper)
        start = np.asarray(self.start)
        return np.where(self.log, start * np.exp(z), start + np.asarray(self.scale) * z)

    def z_of(self, theta) -> np.ndarray:
        """z of parameter values θ [SI] (numpy; the inverse of :meth:`values`)."""
        theta, start = np.asarray(theta, float), np.asarray(self.start)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.log, np.log(theta / start), (theta - start) / self.scale)

    def dtheta_dz(self, theta) -> np.ndarray:
        """dθ/dz at θ (for the standard errors in SI by the delta method)."""
        return np.where(self.log, np.asarray(theta, float), np.asarray(self.scale))


def by_key(key: str) -> str:
    """Registry name of a fittable parameter given by its TOML key (or its name); raises
    :class:`InputError` for an unknown, integer or list-valued one."""
    names = {p.key: p.name for p in PARAMETERS.values()} | {n: n for n in PARAMETERS}
    if key in ("n_modes", "steps"):
        raise InputError(f"--fit {key}: an integer setting cannot be fitted; fit a float "
                         f"parameter of the configuration (jaxdobby simulate --list-parameters)")
    if key not in names:
        raise InputError(f"--fit {key}: unknown parameter; valid keys are "
                         f"{', '.join(p.key for p in PARAMETERS.values())}")
    return names[key]


def parameterisation(setup: Setup, keys, bounds: dict[str, tuple[float, float]] | None = None
                     ) -> Parameterisation:
    """The :class:`Parameterisation` fitting ``keys`` (TOML keys) from their values in ``setup``.

    ``bounds``: optional (low, high) by key in users' units, within the registry's range.
    """
    names = [by_key(k) for k in keys]
    if "speed" in names:
        raise InputError("--fit speed_rpm: the loom speed is the one the trace was measured at "
                         "(--speed); it is not fitted")
    if len(set(names)) != len(names):
        raise InputError("--fit: a parameter is named twice")
    bounds = bounds or {}
    start, log, scale, lower, upper = [], [], [], [], []
    for name in names:
        p = PARAMETERS[name]
        v = np.asarray(p.get(setup), float)
        if v.ndim:
            raise InputError(f"--fit {p.key}: a list parameter cannot be fitted (scalars only)")
        v = float(v)
        low, high = (x * p.scale for x in bounds.get(p.key, p.limits))
        low, high = max(low, p.limits[0] * p.scale), min(high, p.limits[1] * p.scale)
        is_log = p.limits[0] == 0.0
        if is_log and v <= 0.0:
            raise InputError(f"--fit {p.key}: the starting value must be > 0 (a positive "
                             f"parameter is fitted in log space), got {v / p.scale:g} {p.unit}")
        if not low <= v <= high:
            raise InputError(f"--fit {p.key}: the starting value {v / p.scale:g} {p.unit} lies "
                             f"outside the bounds {low / p.scale:g}…{high / p.scale:g}")
        s = 1.0 if is_log else (abs(v) or p.scale)
        start.append(v), log.append(is_log), scale.append(s)
        if is_log:
            # ln of the range; a closed/open 0 is as far as the optimiser need go (1e-6·θ⁰)
            lower.append(math.log(max(low, 1e-6 * v) / v))
            upper.append(math.log(high / v) if math.isfinite(high) else math.log(1e6))
        else:
            lower.append((low - v) / s if math.isfinite(low) else -1e6)
            upper.append((high - v) / s if math.isfinite(high) else 1e6)
    return Parameterisation(tuple(names), tuple(start), tuple(log), tuple(scale), tuple(lower),
                            tuple(upper))


def solver_settings(setup: Setup, options: RunOptions | None) -> tuple[str, int]:
    """(method, steps) of the steady cycle, fixed before tracing (concrete parameters)."""
    options = options or RunOptions()
    return resolve_method(setup.machine, setup.operating, options.method, options.steps)


def setup_at(setup: Setup, names: tuple[str, ...], log: tuple[bool, ...], z) -> Setup:
    """``setup`` with the parameters ``names`` moved by z from their values in ``setup``
    (θ = θ⁰e^z where ``log``, else θ⁰ + s z; traceable: the starting values are read from
    ``setup`` itself)."""
    values = {}
    for i, (name, is_log) in enumerate(zip(names, log)):
        p = PARAMETERS[name]
        v0 = p.get(setup)
        scale = jnp.where(v0 != 0.0, jnp.abs(v0), p.scale)
        values[name] = v0 * jnp.exp(z[i]) if is_log else v0 + scale * z[i]
    return apply(setup, values)


def cycle_grid(setup: Setup, method: str, steps: int) -> tuple[Array, Array, Array]:
    """(T [s], acceleration [m/s²], height [m]) of the steady cycle on its uniform grid over
    [0, T) (the end point, a repeat of t = 0, dropped); differentiable in ``setup``."""
    run = simulate(setup.machine, setup.operating, method=method, steps=steps,
                   tolerance=TOLERANCE)
    s = run.series
    return run.model.period, s.acceleration_flexible[:-1], s.heald_flexible[:-1]


def fourier(grid: Array) -> Array:
    """ĝ_k·w_k (k = 0 … N/2) of the trigonometric interpolant through ``grid`` (N points)."""
    n = grid.shape[-1]
    coef = jnp.fft.rfft(grid) / n
    w = np.full(n // 2 + 1, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    return coef * w


def interpolate(weighted_coef: Array, phase) -> Array:
    """The trigonometric interpolant(s) at the phases ``phase`` = t/T (shape (m,), any real):
    ``weighted_coef`` (..., K) from :func:`fourier` → values (..., m)."""
    cos, sin = harmonics(phase, weighted_coef.shape[-1])
    return weighted_coef.real @ cos.T - weighted_coef.imag @ sin.T


def harmonics(phase, n_coef: int) -> tuple[Array, Array]:
    """cos and sin of 2πkφ, shape (m, K), for k = 0 … K − 1."""
    k = jnp.arange(n_coef)
    # reduce the phase first: for large φ the product kφ would lose digits
    angle = 2.0 * jnp.pi * jnp.mod(phase, 1.0)[:, None] * k
    return jnp.cos(angle), jnp.sin(angle)


def cycle_grids(setup: Setup, names: tuple[str, ...], log: tuple[bool, ...], method: str,
                steps: int, z, *, directory=None) -> tuple[Array, Array, Array]:
    """The steady cycle and its exact derivatives for a batch of z, shape (B, p) (vmapped):
    (T [s] (B,), grid (B, 2, N), d grid/dz (B, 2, N, p)); grid rows: acceleration [m/s²] and
    height [mm] on the uniform grid over [0, T) (:func:`cycle_grid`). Forward mode through the
    steady state (p tangents). A stored program (:func:`jaxdobby.programs.stored_call`: traced
    once, kept in ``directory``; compiled once per process and configuration)."""
    from ..programs import stored_call

    return stored_call("identify-cycle-grids", _cycle_grids,
                       (setup, tuple(names), tuple(log), method, int(steps), jnp.asarray(z)),
                       directory=directory)


def _cycle_grids(setup, names, log, method, steps, z):
    def one(zi):
        def f(zz):
            period, acc, height = cycle_grid(setup_at(setup, names, log, zz), method, steps)
            grid = jnp.stack([acc, height / MM])
            return grid, (grid, period)

        jac, (grid, period) = jax.jacfwd(f, has_aux=True)(zi)
        return period, grid, jac

    if z.shape[0] == 1:  # one lane (a single start): the unbatched program compiles faster
        return jax.tree.map(lambda a: a[None], one(z[0]))
    return jax.vmap(one)(z)
