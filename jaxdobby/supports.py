"""Supports of a beam and its static solution.

Supports are given by node index (static): *clamped* nodes lose all three DOFs, *pinned* nodes
lose their two translations, and *axial springs to ground* act at a node along a given
body-frame direction n with stiffness k (they add k·n nᵀ to the node's translation block; the ring
link of the dobby is one, with k = E·A/L of the link). Constrained DOFs are removed by static
index selection, so every function here stays jittable and differentiable in the float fields.

Example::

    from jaxdobby.supports import Supports, static_deflection
    from jaxdobby.loads import point_load
    clamp_root = Supports(clamped=(0,))
    u = static_deflection(beam, clamp_root, point_load(beam, 1.0, force=(0.0, -100.0)))
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._arrays import as_float
from .beam import DOFS_PER_NODE, Beam


class Supports(eqx.Module):
    """Clamps, pins and axial springs to ground.

    Attributes:
        clamped: node indices with all DOFs fixed (static).
        pinned: node indices with both translations fixed and the rotation free (static).
        spring_nodes: node index of each axial spring (static).
        spring_directions: body-frame direction of each spring, shape (n_springs, 2)
            (normalised internally) [-].
        spring_stiffness: stiffness of each spring [N/m], shape (n_springs,).
    """

    clamped: tuple[int, ...] = eqx.field(static=True, default=())
    pinned: tuple[int, ...] = eqx.field(static=True, default=())
    spring_nodes: tuple[int, ...] = eqx.field(static=True, default=())
    spring_directions: Array = eqx.field(converter=lambda x: as_float(x).reshape(-1, 2),
                                         default=())
    spring_stiffness: Array = eqx.field(converter=lambda x: as_float(x).reshape(-1), default=())

    def free_dofs(self, n_nodes: int) -> np.ndarray:
        """Indices of the unconstrained DOFs (static numpy array)."""
        fixed = set()
        for n in self.clamped:
            fixed.update(DOFS_PER_NODE * n + k for k in range(3))
        for n in self.pinned:
            fixed.update(DOFS_PER_NODE * n + k for k in range(2))
        return np.array([i for i in range(DOFS_PER_NODE * n_nodes) if i not in fixed], dtype=int)

    def spring_matrix(self, n_nodes: int) -> Array:
        """Global stiffness of the springs, Σ k n nᵀ on each spring node's translations [N/m]."""
        out = jnp.zeros((DOFS_PER_NODE * n_nodes,) * 2)
        for i, node in enumerate(self.spring_nodes):
            n = self.spring_directions[i] / jnp.linalg.norm(self.spring_directions[i])
            dofs = DOFS_PER_NODE * node + np.arange(2)
            out = out.at[dofs[:, None], dofs[None, :]].add(self.spring_stiffness[i] * jnp.outer(n, n))
        return out


def supported_stiffness(beam: Beam, supports: Supports) -> Array:
    """Global stiffness of the beam plus its springs (constrained DOFs still present)."""
    return beam.stiffness_matrix() + supports.spring_matrix(beam.n_nodes)


@eqx.filter_jit
def static_deflection(beam: Beam, supports: Supports, loads: Array,
                      stiffness: Array | None = None) -> Array:
    """Static displacements (n_dofs,) of the supported beam under nodal loads (n_dofs,).

    ``loads`` holds forces [N] on translation DOFs and moments [N·m] on rotation DOFs, in the body
    frame; constrained DOFs return zero. Pass ``stiffness`` to reuse an assembled matrix.
    """
    k = supported_stiffness(beam, supports) if stiffness is None else stiffness
    free = supports.free_dofs(beam.n_nodes)
    u_free = jnp.linalg.solve(k[np.ix_(free, free)], loads[free])
    return jnp.zeros(beam.n_dofs, dtype=u_free.dtype).at[free].set(u_free)
