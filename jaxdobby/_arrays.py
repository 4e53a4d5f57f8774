"""Field converters for parameter modules.

``jnp.asarray(0.03)`` is *weakly* typed; a weak leaf and a strong one (from a NumPy value, or a
traced batch) have different abstract types and make a jitted function retrace. Every float field
of a jaxdobby parameter module is therefore converted with an explicit dtype.

A concrete value is converted by NumPy and put on the device as it is: ``jnp.asarray(0.03,
dtype=float)`` would compile a small XLA program (a conversion) the first time, and a machine's
few dozen fields cost a command-line run a second of such programs.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array


def is_traced(*values) -> bool:
    """Whether any of ``values`` (pytrees) holds a JAX tracer (inside jit, grad, vmap)."""
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(values))


def as_float(x) -> Array:
    """A strongly typed float array (float64 when x64 is on)."""
    if is_traced(x):
        return jnp.asarray(x, dtype=float)
    return jax.device_put(np.asarray(x, dtype=float))


def as_float_1d(x) -> Array:
    """A strongly typed float array of at least one dimension."""
    if is_traced(x):
        return jnp.atleast_1d(jnp.asarray(x, dtype=float))
    return jax.device_put(np.atleast_1d(np.asarray(x, dtype=float)))
