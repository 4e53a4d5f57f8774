"""Independent reference, part 1: the bending arm as co-rotational planar beam elements.

Written for the model-form error budget of issue 21, without jaxdobby's beam code (no
``jaxdobby.beam``, ``elements``, ``modal``, ``flexible_body``): element matrices, the nonlinear
strain energy and the supports are re-derived here. Only the arm's *geometry* (node arc lengths,
centre line) is read from :class:`jaxdobby.arm.ArmDesign`.

Elements (Crisfield, *Non-linear Finite Element Analysis of Solids and Structures*, vol. 1, 1991,
§7.3–7.4, the co-rotational beam with a shallow-arch local strain): node i has body-frame
displacements (uᵢ, vᵢ) [m] and a section rotation ψᵢ [rad]. With the current chord
c = (Xⱼ + uⱼ) − (Xᵢ + uᵢ) of length l, its turn β from the initial chord c₀ (length L, exact,
by atan2 of cross and dot — any rigid rotation) and the local end rotations θ₁ = ψᵢ − β,
θ₂ = ψⱼ − β, the local transverse field is the Hermite cubic w = L(ξ − 2ξ² + ξ³)θ₁ +
L(ξ³ − ξ²)θ₂ and the strain energy

    ε̄ = (l² − L²)/(L (l + L)) + (2θ₁² − θ₁θ₂ + 2θ₂²)/30      (= u_l/L + (1/2L)∫w'² dx),
    U = ½ EA L ε̄² + (2EI/L)(θ₁² + θ₁θ₂ + θ₂²).

Its second derivative at rest with an axial force N is K + N K_σ with the consistent geometric
stiffness (so on the same mesh the reference and a linearised model differ only by what the
linearisation drops). Large rigid rotations of an element are exact; the local strain is shallow
(valid for local rotations ≪ 1 rad — here ~1e-3).

Inertia: the displacement field is interpolated by the same shape functions (axial linear,
transverse Hermite) — consistent mass M_t = ∫ρA NᵀN; the section's rotary inertia
M_r = ∫ρI ψ'ᵀψ' (ψ = dw/dx) is a switch (Euler–Bernoulli: off; Rayleigh beam: on).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

_GX, _GW = np.polynomial.legendre.leggauss(5)
_GX, _GW = 0.5 * (_GX + 1.0), 0.5 * _GW
_S = np.array([[0.0, -1.0], [1.0, 0.0]])


def _shapes(xi, L):
    """Axial/transverse translation rows (2, 6) and section rotation row (6,) in element axes."""
    h = [1 - 3 * xi**2 + 2 * xi**3, L * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3,
         L * (xi**3 - xi**2)]
    dh = [(-6 * xi + 6 * xi**2) / L, 1 - 4 * xi + 3 * xi**2, (6 * xi - 6 * xi**2) / L,
          3 * xi**2 - 2 * xi]
    n = np.array([[1 - xi, 0, 0, xi, 0, 0], [0, h[0], h[1], 0, h[2], h[3]]])
    r = np.array([0, dh[0], dh[1], 0, dh[2], dh[3]])
    return n, r


def _rotation(angle):
    """6×6 body → element-axes rotation of a two-node element's DOFs."""
    c, s = np.cos(angle), np.sin(angle)
    r = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]])
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = r
    return out


class Arm:
    """A planar chain of straight co-rotational elements and its constant matrices (numpy, body
    frame, all 3·n DOFs). Build the dobby's arm with :func:`arm_from_design`.

    Args:
        s: arc lengths of the nodes [m], (n,); X: their body-frame positions [m], (n, 2).
        thickness, depth: rectangular section t × d [m]; youngs_modulus [Pa], density [kg/m³].
        rotary_inertia: include the section's rotary inertia ρI (Rayleigh beam).

    Attributes (SI): L, angle (n_el,) chord lengths and angles; EA [N], EI [N·m²], rhoA [kg/m],
    rhoI [kg·m]; M_t, M_r, G, K (3n, 3n), K_sigma (n_el, 3n, 3n) per unit axial force; the
    nodal vectors ``position`` (rigid field X), ``rotation`` (rigid-rotation field S·X, ψ = 1),
    ``x``, ``y`` (unit translations).
    """

    def __init__(self, s, X, thickness, depth, youngs_modulus, density,
                 rotary_inertia: bool = True):
        self.s, self.X = np.asarray(s, float), np.asarray(X, float)
        s = self.s
        chord = self.X[1:] - self.X[:-1]
        self.L = np.linalg.norm(chord, axis=1)
        self.angle = np.arctan2(chord[:, 1], chord[:, 0])
        t, d, e, rho = (float(x) for x in (thickness, depth, youngs_modulus, density))
        self.EA, self.EI = e * t * d, e * t * d**3 / 12.0
        self.rhoA, self.rhoI = rho * t * d, rho * t * d**3 / 12.0 * float(rotary_inertia)
        self.n_nodes = s.size
        self.n_dofs = 3 * s.size
        self.dofs = np.array([np.r_[3 * e_ + np.arange(3), 3 * e_ + 3 + np.arange(3)]
                              for e_ in range(s.size - 1)])
        self.M_t, self.M_r, self.G, self.K, self.K_sigma = self._assemble()
        n = self.n_nodes
        self.position = np.zeros(3 * n)
        self.position[0::3], self.position[1::3] = self.X[:, 0], self.X[:, 1]
        self.rotation = np.zeros(3 * n)
        self.rotation[0::3], self.rotation[1::3] = -self.X[:, 1], self.X[:, 0]
        self.rotation[2::3] = 1.0
        self.x = np.zeros(3 * n)
        self.x[0::3] = 1.0
        self.y = np.zeros(3 * n)
        self.y[1::3] = 1.0

    def node(self, arc_length) -> int:
        """Index of the node at ``arc_length`` [m] (must be a node: loads act at nodes)."""
        i = int(np.argmin(np.abs(self.s - float(arc_length))))
        if abs(self.s[i] - float(arc_length)) > 1e-9:
            raise ValueError(f"no node at arc length {arc_length}")
        return i

    def _assemble(self):
        n = self.n_dofs
        out = [np.zeros((n, n)) for _ in range(4)]
        k_sigma = np.zeros((self.L.size, n, n))
        for e_, (L, a) in enumerate(zip(self.L, self.angle)):
            mt, mr, g, ks = (np.zeros((6, 6)) for _ in range(4))
            for xi, w in zip(_GX, _GW):
                nn, r = _shapes(xi, L)
                mt += w * L * self.rhoA * nn.T @ nn
                mr += w * L * self.rhoI * np.outer(r, r)
                g += w * L * self.rhoA * nn.T @ _S @ nn
                ks += w * L * np.outer(r, r)  # ∫ w'ᵀw' dx: the slope is the section rotation
            kl = np.zeros((6, 6))
            kl[np.ix_([0, 3], [0, 3])] = self.EA / L * np.array([[1, -1], [-1, 1]])
            kl[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = self.EI / L**3 * np.array(
                [[12, 6 * L, -12, 6 * L], [6 * L, 4 * L**2, -6 * L, 2 * L**2],
                 [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L**2, -6 * L, 4 * L**2]])
            t_ = _rotation(a)
            ix = np.ix_(self.dofs[e_], self.dofs[e_])
            for acc, mat in zip(out, (mt, mr, g, kl)):
                acc[ix] += t_.T @ mat @ t_
            k_sigma[e_][ix] += t_.T @ ks @ t_
        return (*out, k_sigma)

    # -- nonlinear elasticity (JAX) -------------------------------------------------------------
    def strain_energy(self, u):
        """Co-rotational strain energy U(u) [J] of the full displacement vector u (3n,)."""
        un = u.reshape(-1, 3)
        x = jnp.asarray(self.X) + un[:, :2]
        c = x[1:] - x[:-1]
        c0 = jnp.asarray(self.X[1:] - self.X[:-1])
        L = jnp.asarray(self.L)
        l2 = jnp.sum(c**2, axis=1)
        beta = jnp.arctan2(c0[:, 0] * c[:, 1] - c0[:, 1] * c[:, 0], jnp.sum(c0 * c, axis=1))
        th1, th2 = un[:-1, 2] - beta, un[1:, 2] - beta
        eps = (l2 - L**2) / (L * (jnp.sqrt(l2) + L)) + (2 * th1**2 - th1 * th2 + 2 * th2**2) / 30
        return jnp.sum(0.5 * self.EA * L * eps**2
                       + 2 * self.EI / L * (th1**2 + th1 * th2 + th2**2))

    def axial_forces(self, u):
        """Element axial forces [N, tension +] of the linear theory for displacements u (3n,)."""
        un = np.asarray(u).reshape(-1, 3)
        du = un[1:, :2] - un[:-1, :2]
        return self.EA / self.L * (du[:, 0] * np.cos(self.angle) + du[:, 1] * np.sin(self.angle))


def arm_from_design(design, refine: int = 1, rotary_inertia: bool = True) -> Arm:
    """The dobby's bending arm (:class:`jaxdobby.arm.ArmDesign`, uniform depth) on jaxdobby's
    11-node mesh, each element split into ``refine`` equal parts (nodes on the centre line)."""
    s0 = np.asarray(design.node_arc_lengths(), float)
    s = np.concatenate([np.linspace(a, b, refine + 1)[:-1] for a, b in zip(s0[:-1], s0[1:])]
                       + [s0[-1:]])
    depth = np.asarray(design.depth, float).reshape(-1)
    if depth.size != 1:
        raise ValueError("the reference arm takes a uniform depth only")
    x = np.asarray(design.centreline.point(jnp.asarray(s)), float)
    return Arm(s, x, design.thickness, depth[0], design.youngs_modulus, design.density,
               rotary_inertia)


def straight_beam(length, n_elements, thickness, depth, youngs_modulus=2.07e11, density=7800.0,
                  rotary_inertia=False) -> Arm:
    """A straight beam along +x from the origin (for the closed-form checks)."""
    s = np.linspace(0.0, length, n_elements + 1)
    return Arm(s, np.stack([s, 0 * s], 1), thickness, depth, youngs_modulus, density,
               rotary_inertia)


def free_dofs(arm: Arm, pinned=(0,)) -> np.ndarray:
    """DOF indices left free by pinning the translations of the ``pinned`` nodes."""
    fixed = {3 * n + k for n in pinned for k in (0, 1)}
    return np.array([i for i in range(arm.n_dofs) if i not in fixed])


def spring(arm: Arm, node: int, direction, stiffness) -> np.ndarray:
    """Stiffness (3n, 3n) of an axial spring to ground at ``node`` along ``direction``."""
    n = np.asarray(direction, float) / np.linalg.norm(direction)
    out = np.zeros((arm.n_dofs, arm.n_dofs))
    out[np.ix_([3 * node, 3 * node + 1], [3 * node, 3 * node + 1])] = stiffness * np.outer(n, n)
    return out
