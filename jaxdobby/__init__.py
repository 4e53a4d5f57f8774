"""jaxdobby: a differentiable JAX simulator of the rigid-flexible lifting mechanism of a rotary dobby.

float64 is required: switch it on with ``jax.config.update("jax_enable_x64", True)`` before use.
"""

__version__ = "0.1.0"
