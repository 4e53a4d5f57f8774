"""Test configuration: float64 on, as every jaxdobby user is told to do (see README)."""

import jax

jax.config.update("jax_enable_x64", True)
