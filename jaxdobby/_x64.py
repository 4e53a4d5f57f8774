"""float64 guard.

jaxdobby computes in float64 throughout: the modal equations span three decades of frequency and
the heald-frame deviation is ~1e-3 of the stroke, so float32 (≈1e-7 relative, ≈1e-5 after a
solve) is not enough. JAX defaults to float32; the library never changes global JAX settings
itself. The command line and the examples switch float64 on with::

    import jax
    jax.config.update("jax_enable_x64", True)

(or the environment variable ``JAX_ENABLE_X64=1``), and library entry points call
:func:`require_x64`, which fails with a clear message when it is off.
"""

from __future__ import annotations

import jax


class Float64Required(RuntimeError):
    """Raised when a jaxdobby entry point is called with float64 switched off."""


def require_x64() -> None:
    """Raise :class:`Float64Required` unless JAX runs in float64 mode."""
    if not jax.config.jax_enable_x64:
        raise Float64Required(
            "jaxdobby needs float64: call jax.config.update('jax_enable_x64', True) before "
            "using it (or set the environment variable JAX_ENABLE_X64=1)."
        )
