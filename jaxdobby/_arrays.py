"""Field converters for parameter modules.

``jnp.asarray(0.03)`` is *weakly* typed; a weak leaf and a strong one (from a NumPy value, or a
traced batch) have different abstract types and make a jitted function retrace. Every float field
of a jaxdobby parameter module is therefore converted with an explicit dtype.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array


def as_float(x) -> Array:
    """A strongly typed float array (float64 when x64 is on)."""
    return jnp.asarray(x, dtype=float)


def as_float_1d(x) -> Array:
    """A strongly typed float array of at least one dimension."""
    return jnp.atleast_1d(jnp.asarray(x, dtype=float))
