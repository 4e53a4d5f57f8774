"""The dobby's coupled equations in plain numpy, for ``scipy.integrate.solve_ivp``.

The same model as :func:`jaxdobby.dobby.vector_field` — not a different one: the modal invariants
(mass, stiffness, gyroscopic and geometric-stiffness matrices, point rows Φ_P) are the arrays of
the JAX-built :class:`~jaxdobby.dobby.DobbyModel`, converted to numpy once, and so are the
setup constants (the linkage's dimensions, the body-frame joint positions, the dead-centre crank
angle, the stroke and mid-stroke level). Everything that changes in time is re-written here in
numpy, the way a user without JAX would write it:

* modulator: φ(t) = φ₀ + π(n + s(τ)) with the motion law's closed-form s, s′, s″;
* crank-rocker 8-9-10 and double-rocker 10-11-12: position by circle intersection, velocity and
  acceleration by the classical loop-closure equations (differentiate |R − X|² = L² twice,
  Norton, *Design of Machinery*, §6–7): for a rocker end R = pivot + r e(ψ) tied by a coupler of
  length L to a moving point X, with d = R − X and e⊥ = e rotated +90°,

      ψ̇ = d·Ẋ / (r d·e⊥),     ψ̈ = (d·Ẍ + r ψ̇² d·e − |Ṙ − Ẋ|²) / (r d·e⊥);

* tumbler: y_H = E_y − √(L13² − (x_g − E_x)²) and its first two derivatives in closed form;
* the chain's Jacobian C′(P) = ∂c/∂P = [∂β/∂P; y_β ∂β/∂P] (rank one, ∂β/∂P = dᵀ/(r d·e⊥)) and
  the curvature term h = c̈ − G_q q̈ = the loop-closure acceleration with P̈ less its Φ_P q̈ part;
* Kane's terms, the chain's mass and forces, the ring link's change of direction — the formulas
  of :mod:`jaxdobby.floating_frame` and :mod:`jaxdobby.dobby`, in numpy.

No automatic differentiation anywhere here. The functions broadcast over leading axes (times
``t`` of shape (n,), states of shape (n, 2k)), so the same code gives the right-hand side at one
state and the outputs over a whole saved cycle; :meth:`NumpyDobby.rhs_vectorized` is the form
``solve_ivp(..., vectorized=True)`` wants (used by the implicit methods for their
finite-difference Jacobian).

:func:`jitted_rhs` is the second scipy variant: ``jax.jit`` of jaxdobby's own vector field and of
its Jacobian (``jax.jacfwd``), wrapped for ``solve_ivp`` (the fair comparison the diffrax
documentation asks for: scipy driving a compiled right-hand side).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

_PI = math.pi
_TWO_PI = 2.0 * math.pi
LINK, RING = 1, 0  # indices of the points of the flexible body (jaxdobby.dobby)


# -- motion laws: s(τ), s'(τ), s''(τ) of the first half; the second half by point symmetry ------
def _modified_sine(tau):
    k = 4.0 + _PI
    a = _PI / 3.0 + 4.0 * _PI * tau / 3.0
    early = tau <= 0.125
    s = np.where(early, (_PI * tau - 0.25 * np.sin(4.0 * _PI * tau)) / k,
                 (2.0 + _PI * tau - 2.25 * np.sin(a)) / k)
    v = np.where(early, _PI * (1.0 - np.cos(4.0 * _PI * tau)) / k, _PI * (1.0 - 3.0 * np.cos(a)) / k)
    acc = np.where(early, 4.0 * _PI**2 * np.sin(4.0 * _PI * tau) / k, 4.0 * _PI**2 * np.sin(a) / k)
    return s, v, acc


def _cycloidal(tau):
    w = _TWO_PI * tau
    return tau - np.sin(w) / _TWO_PI, 1.0 - np.cos(w), _TWO_PI * np.sin(w)


def _polynomial_345(tau):
    return (tau**3 * (10.0 + tau * (-15.0 + 6.0 * tau)), 30.0 * tau**2 * (1.0 - tau) ** 2,
            60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau))


def _modified_trapezoid(tau):
    a = 8.0 * _PI / (2.0 + _PI)
    w = 4.0 * _PI
    v1, s1 = a / w, a / w * (0.125 - 1.0 / w)
    v2, s2 = v1 + 0.25 * a, s1 + 0.25 * v1 + 0.5 * a * 0.25**2
    u, r = tau - 0.125, tau - 0.375
    first, second = tau <= 0.125, tau <= 0.375
    s = np.where(first, a / w * (tau - np.sin(w * tau) / w),
                 np.where(second, s1 + v1 * u + 0.5 * a * u**2,
                          s2 + v2 * r + a / w**2 * (1.0 - np.cos(w * r))))
    v = np.where(first, a / w * (1.0 - np.cos(w * tau)),
                 np.where(second, v1 + a * u, v2 + a / w * np.sin(w * r)))
    acc = np.where(first, a * np.sin(w * tau), np.where(second, a, a * np.cos(w * r)))
    return s, v, acc


_FIRST_HALVES = {"modified_sine": _modified_sine, "cycloidal": _cycloidal,
                 "polynomial_345": _polynomial_345, "modified_trapezoid": _modified_trapezoid}


def motion_law(name: str, tau):
    """s(τ), ds/dτ, d²s/dτ² of a dwell-rise-dwell law; τ clipped to [0, 1] (dwells: 0, 0)."""
    half = _FIRST_HALVES[name]
    inside = (tau > 0.0) & (tau < 1.0)
    tau = np.clip(tau, 0.0, 1.0)
    first = tau <= 0.5
    s1, v1, a1 = half(tau)
    s2, v2, a2 = half(1.0 - tau)
    s = np.where(first, s1, 1.0 - s2)
    v = np.where(inside, np.where(first, v1, v2), 0.0)
    a = np.where(inside, np.where(first, a1, -a2), 0.0)
    return s, v, a


# -- planar helpers (vectors over the last axis, any leading axes) ------------------------------
def _dot(u, v):
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]


def _perp(u):
    """u rotated by +90°."""
    return np.stack([-u[..., 1], u[..., 0]], axis=-1)


def _rotate(angle, v):
    """A(angle) v."""
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    return np.concatenate([c * v[..., :1] - s * v[..., 1:], s * v[..., :1] + c * v[..., 1:]], axis=-1)


def _unit(angle):
    return np.stack([np.cos(angle), np.sin(angle)], axis=-1)


def circle_intersection(a, ra, b, rb, branch):
    """Meeting point of circles (a, ra) and (b, rb), left (+1) or right (−1) of a → b."""
    ab = b - a
    d = np.sqrt(_dot(ab, ab))
    u = ab / d[..., None]
    x = (d**2 + ra**2 - rb**2) / (2.0 * d)
    h = np.sqrt(np.maximum(ra**2 - x**2, 0.0))
    return a + x[..., None] * u + (branch * h)[..., None] * _perp(u)


def rocker(pivot, radius, x, x_dot, x_ddot, coupler, branch):
    """Rocker end R = pivot + radius·e(ψ) tied to the moving point X by a coupler of length L.

    Returns ψ, ψ̇, ψ̈, the end R and its velocity Ṙ, and ∂ψ/∂X = dᵀ/(radius d·e⊥) (the velocity
    equation's coefficient), by the loop-closure equations of the module docstring.
    """
    end = circle_intersection(pivot, radius, x, coupler, branch)
    rel = end - pivot
    psi = np.arctan2(rel[..., 1], rel[..., 0])
    e = rel / radius
    e_perp = _perp(e)
    d = end - x
    den = radius * _dot(d, e_perp)
    dpsi_dx = d / den[..., None]
    psi_dot = _dot(dpsi_dx, x_dot)
    end_dot = (radius * psi_dot)[..., None] * e_perp
    rel_v = end_dot - x_dot
    psi_ddot = (_dot(d, x_ddot) + radius * psi_dot**2 * _dot(d, e) - _dot(rel_v, rel_v)) / den
    return psi, psi_dot, psi_ddot, dpsi_dx


@dataclasses.dataclass(frozen=True)
class NumpyDobby:
    """The coupled model as numpy arrays (SI units; shapes for k modes)."""

    # drive: loom speed [rad/s], dwell per pick [rad], crank angle in the first dwell [rad]
    speed: float
    dwell: float
    crank_start: float
    law: str
    # crank-rocker 8-9-10
    eccentric_axis: np.ndarray
    eccentricity: float
    ring_link_length: float
    ring_joint: np.ndarray          # body-frame position of the ring-link joint on the arm [m]
    ring_branch: int
    # double-rocker 10-11-12 and tumbler
    link_joint: np.ndarray          # body-frame position of the link-11 joint [m]
    link11_length: float
    blade_pivot: np.ndarray
    blade_input_arm: float
    blade_output_arm: float
    blade_output_offset: float
    tumbler_length: float
    frame_guide_x: float
    blade_branch: int
    # chain loads
    chain_inertia: np.ndarray       # D = (J_b, m_H)
    gravity: float
    warp_force: float
    warp_law: str
    stroke: float
    mid_level: float
    period: float
    coupling: str
    # flexible body (modal invariants, as built by jaxdobby)
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    translational_mass: np.ndarray
    gyroscopic: np.ndarray
    centrifugal: np.ndarray
    euler: np.ndarray
    translation: np.ndarray         # (k, 2)
    stiffening: dict
    point_stiffening: np.ndarray    # (points, 2, k, k)
    points: np.ndarray              # (points, 2, k)
    ring_direction_ref: np.ndarray
    ring_link_stiffness: float

    @classmethod
    def from_model(cls, model) -> NumpyDobby:
        """Convert a :class:`jaxdobby.dobby.DobbyModel` (the modal invariants and setup
        constants; no time-dependent quantity is taken from it)."""
        f = lambda x: np.asarray(x, dtype=float)
        c, m, b = model.chain, model.machine, model.body
        return cls(
            speed=float(model.operating.speed), dwell=float(c.dwell),
            crank_start=float(model.crank_start), law=c.motion_law,
            eccentric_axis=f(c.eccentric_axis), eccentricity=float(c.eccentricity),
            ring_link_length=float(c.ring_link_length),
            ring_joint=f(c.arm.point(c.ring_joint_arc_length)), ring_branch=int(c.ring_branch),
            link_joint=f(model.link_joint), link11_length=float(c.link11_length),
            blade_pivot=f(c.blade_pivot), blade_input_arm=float(c.blade_input_arm),
            blade_output_arm=float(c.blade_output_arm),
            blade_output_offset=float(c.blade_output_offset),
            tumbler_length=float(c.tumbler_length), frame_guide_x=float(c.frame_guide_x),
            blade_branch=int(c.blade_branch),
            chain_inertia=np.array([float(m.blade_inertia), float(m.heald_frame_mass)]),
            gravity=float(m.gravity), warp_force=float(model.operating.warp_force),
            warp_law=m.warp_law, stroke=float(model.stroke), mid_level=float(model.mid_level),
            period=float(model.period), coupling=m.coupling,
            mass=f(b.mass), stiffness=f(b.stiffness), damping=f(b.damping),
            translational_mass=f(b.translational_mass), gyroscopic=f(b.gyroscopic),
            centrifugal=f(b.centrifugal), euler=f(b.euler), translation=f(b.translation),
            stiffening={name: f(v) for name, v in b.stiffening.items()},
            point_stiffening=f(b.point_stiffening), points=f(b.points),
            ring_direction_ref=f(model.ring_direction_ref),
            ring_link_stiffness=float(m.ring_link_stiffness),
        )

    @property
    def n_modes(self) -> int:
        return self.mass.shape[0]

    # -- the rigid mechanism --------------------------------------------------------------------
    def crank(self, t):
        """φ, φ̇, φ̈ of the modulator at times t [s]."""
        span = _TWO_PI - self.dwell
        psi = self.speed * t + 0.5 * self.dwell
        n = np.floor(psi / _TWO_PI)
        tau = (psi - _TWO_PI * n - self.dwell) / span
        s, v, a = motion_law(self.law, tau)
        rate = self.speed / span
        return self.crank_start + _PI * (n + s), _PI * v * rate, _PI * a * rate**2

    def arm(self, t):
        """Arm angle θ, ω, α and the inertial ring-link direction (pin → arm joint) at t."""
        phi, phi_dot, phi_ddot = self.crank(t)
        u = _unit(phi)
        pin = self.eccentric_axis + self.eccentricity * u
        pin_dot = (self.eccentricity * phi_dot)[..., None] * _perp(u)
        pin_ddot = self.eccentricity * (phi_ddot[..., None] * _perp(u) - (phi_dot**2)[..., None] * u)
        radius = math.hypot(*self.ring_joint)
        psi, omega, alpha, _ = rocker(np.zeros(2), radius, pin, pin_dot, pin_ddot,
                                      self.ring_link_length, self.ring_branch)
        joint = radius * _unit(psi)
        direction = (joint - pin) / self.ring_link_length
        theta = psi - math.atan2(self.ring_joint[1], self.ring_joint[0])
        return theta, omega, alpha, direction

    def chain(self, p, p_dot, p_ddot):
        """The downstream chain driven by the link-11 joint at P (inertial, with rates).

        Returns c = (β, y_H), ċ, c̈ (each (..., 2)) and C′(P) = ∂c/∂P (..., 2, 2).
        """
        beta, beta_dot, beta_ddot, dbeta_dp = rocker(self.blade_pivot, self.blade_input_arm, p,
                                                     p_dot, p_ddot, self.link11_length,
                                                     self.blade_branch)
        gamma = beta + self.blade_output_offset
        r = self.blade_output_arm
        e = self.blade_pivot + r * _unit(gamma)                 # tumbler joint E
        e1 = r * _perp(_unit(gamma))                           # dE/dβ
        e2 = -r * _unit(gamma)                                 # d²E/dβ²
        w = self.frame_guide_x - e[..., 0]
        root = np.sqrt(self.tumbler_length**2 - w**2)
        y = e[..., 1] - root
        y_b = e1[..., 1] - w * e1[..., 0] / root
        y_bb = (e2[..., 1] + e1[..., 0] ** 2 / root - w * e2[..., 0] / root
                + w**2 * e1[..., 0] ** 2 / root**3)
        c = np.stack([beta, y], axis=-1)
        c_dot = np.stack([beta_dot, y_b * beta_dot], axis=-1)
        c_ddot = np.stack([beta_ddot, y_b * beta_ddot + y_bb * beta_dot**2], axis=-1)
        c_prime = np.stack([dbeta_dp, y_b[..., None] * dbeta_dp], axis=-2)
        return c, c_dot, c_ddot, c_prime

    def warp(self, t, height):
        """Warp-yarn force on the heald frame [N, up]."""
        offset = (height - self.mid_level) / (0.5 * self.stroke)
        if self.warp_law == "restoring":
            return -self.warp_force * offset
        lifting = np.mod(t, self.period) < 0.5 * self.period
        return -self.warp_force * np.abs(offset) * np.where(lifting, 1.0, -1.0)

    def chain_forces(self, t, height):
        """Q = (blade torque, frame force) of gravity and the warp force [N·m, N]."""
        frame = -self.chain_inertia[1] * self.gravity + self.warp(t, height)
        return np.stack([0.0 * frame, frame], axis=-1)

    def rigid(self, t):
        """θ, ω, α, the ring-link direction and the link-11 force (body frame) of the rigid
        mechanism at t; the force by the chain's d'Alembert balance f = −C′ᵀ(D c̈ − Q)."""
        theta, omega, alpha, direction = self.arm(t)
        p = self.link_joint
        sp = _perp(p)
        joint = _rotate(theta, p + 0.0 * theta[..., None])
        joint_dot = _rotate(theta, omega[..., None] * sp)
        joint_ddot = _rotate(theta, alpha[..., None] * sp - (omega**2)[..., None] * p)
        c, _, c_ddot, c_prime = self.chain(joint, joint_dot, joint_ddot)
        load = self.chain_inertia * c_ddot - self.chain_forces(t, c[..., 1])
        force = -np.einsum("...ij,...i->...j", c_prime, load)
        return theta, omega, alpha, _rotate(-theta, direction), _rotate(-theta, force)

    def rigid_heald(self, t):
        """Rigid heald-frame height, velocity and acceleration at t."""
        theta, omega, alpha, _ = self.arm(t)
        p, sp = self.link_joint, _perp(self.link_joint)
        c, c_dot, c_ddot, _ = self.chain(_rotate(theta, p + 0.0 * theta[..., None]),
                                         _rotate(theta, omega[..., None] * sp),
                                         _rotate(theta, alpha[..., None] * sp
                                                 - (omega**2)[..., None] * p))
        return c[..., 1], c_dot[..., 1], c_ddot[..., 1]

    # -- equations of motion --------------------------------------------------------------------
    def equations(self, t, q, qdot):
        """Mass matrix (..., k, k), force (..., k) and the chain's kinematics at (t, q, q̇)."""
        theta, omega, alpha, n_body, link_force = self.rigid(t)
        w2, al = (omega**2)[..., None, None], alpha[..., None, None]
        kg = self.stiffening
        field = _rotate(-theta, np.array([0.0, -self.gravity]) + 0.0 * theta[..., None])
        k_geo = (w2 * kg["centrifugal"] - al * kg["euler"]
                 + field[..., 0, None, None] * kg["x"] + field[..., 1, None, None] * kg["y"]
                 + np.einsum("ckl,...c->...kl", self.point_stiffening[LINK], link_force))
        force = ((omega**2)[..., None] * self.centrifugal - alpha[..., None] * self.euler
                 + field @ self.translation.T)
        if self.coupling == "one-way":
            force = force + link_force @ self.points[LINK]
        stiffness = self.stiffness - w2 * self.translational_mass + al * self.gyroscopic + k_geo
        damping = self.damping + 2.0 * omega[..., None, None] * self.gyroscopic
        force = (force - np.einsum("...kl,...l->...k", damping, qdot)
                 - np.einsum("...kl,...l->...k", stiffness, q))
        mass = self.mass + 0.0 * w2
        chain = None
        if self.coupling == "two-way":
            rows = self.points[LINK]                              # Φ_P, (2, k)
            r = self.link_joint + q @ rows.T
            sr, v_el = _perp(r), qdot @ rows.T
            p = _rotate(theta, r)
            p_dot = _rotate(theta, omega[..., None] * sr + v_el)
            p_rest = _rotate(theta, 2.0 * omega[..., None] * _perp(v_el) + alpha[..., None] * sr
                             - (omega**2)[..., None] * r)
            c, c_dot, h, c_prime = self.chain(p, p_dot, p_rest)
            a_rows = np.swapaxes(_rotate(theta[..., None], rows.T), -1, -2)  # A Φ_P, (..., 2, k)
            g_q = c_prime @ a_rows                                 # (..., 2, k)
            d = self.chain_inertia
            mass = mass + np.einsum("...ik,...i,...il->...kl", g_q, d, g_q)
            force = force + np.einsum("...ik,...i->...k", g_q,
                                      self.chain_forces(t, c[..., 1]) - d * h)
            chain = (c, c_dot, h, g_q, c_prime)
        rows = self.points[RING]
        u = q @ rows.T
        n, n0 = n_body, self.ring_direction_ref
        ring = n * _dot(n, u)[..., None] - n0 * _dot(n0, u)[..., None]
        force = force - self.ring_link_stiffness * ring @ rows
        return mass, force, chain

    def rhs(self, t, x):
        """dx/dt of the state x = (q, q̇), shape (2k,) (or (..., 2k) with t broadcasting)."""
        k = self.n_modes
        q, qdot = x[..., :k], x[..., k:]
        mass, force, _ = self.equations(np.asarray(t, dtype=float), q, qdot)
        return np.concatenate([qdot, np.linalg.solve(mass, force[..., None])[..., 0]], axis=-1)

    def rhs_vectorized(self, t, y):
        """``solve_ivp(vectorized=True)`` form: y of shape (2k, m) → (2k, m)."""
        return self.rhs(t, y.T).T

    def outputs(self, t, x):
        """Heald-frame series over saved states: t (n,), x (n, 2k) → dict of (n,) arrays."""
        if self.coupling != "two-way":
            raise NotImplementedError("outputs: two-way coupling only")
        k = self.n_modes
        q, qdot = x[..., :k], x[..., k:]
        mass, force, (c, c_dot, h, g_q, _) = self.equations(t, q, qdot)
        qddot = np.linalg.solve(mass, force[..., None])[..., 0]
        y_r, v_r, a_r = self.rigid_heald(t)
        acc = np.einsum("...k,...k->...", g_q[..., 1, :], qddot) + h[..., 1]
        return {"heald_rigid": y_r, "velocity_rigid": v_r, "acceleration_rigid": a_r,
                    "heald_flexible": c[..., 1], "velocity_flexible": c_dot[..., 1],
                    "acceleration_flexible": acc}


METRICS = ("deviation_pp", "deviation_min", "deviation_max", "velocity_deviation_amp",
           "acceleration_amp")
"""The metrics compared between jaxdobby and scipy (jaxdobby.metrics.cycle_metrics names)."""


def refined_extremes(x: np.ndarray) -> tuple[float, float]:
    """(max, min) of a periodic signal sampled uniformly over one period (last sample = first),
    each extreme sample refined by the vertex of the parabola through it and its neighbours —
    the rule of :func:`jaxdobby.metrics.extremes`, written again here in numpy."""
    y = np.asarray(x)[:-1]
    out = []
    for i, sign in ((int(np.argmax(y)), 1.0), (int(np.argmin(y)), -1.0)):
        a, b, c = y[i - 1], y[i], y[(i + 1) % len(y)]
        curvature = a - 2.0 * b + c
        out.append(b - (a - c) ** 2 / (8.0 * curvature) if sign * curvature < 0.0 else b)
    return out[0], out[1]


def cycle_metrics(series: dict) -> dict:
    """The compared metrics from :meth:`NumpyDobby.outputs` (same definitions as jaxdobby)."""
    dev = series["heald_flexible"] - series["heald_rigid"]
    vdev = series["velocity_flexible"] - series["velocity_rigid"]
    acc = series["acceleration_flexible"]
    hi, lo = refined_extremes(dev)
    v_hi, v_lo = refined_extremes(vdev)
    a_hi, a_lo = refined_extremes(acc)
    return {"deviation_pp": hi - lo, "deviation_min": lo, "deviation_max": hi,
            "velocity_deviation_amp": v_hi - v_lo, "acceleration_amp": a_hi - a_lo}


_JITTED: dict = {}


def jitted_rhs(model):
    """``jax.jit`` of jaxdobby's vector field and its Jacobian, wrapped for ``solve_ivp``.

    The model's arrays travel as one flat argument (``ravel_pytree``), so the compiled pair is
    shared by every model of the same structure (one compilation per process, not per sample)
    and a call passes three arrays. Returns ``(fun, jac)``, both taking ``(t, y)`` with numpy in
    and out; the first call of a new structure compiles.
    """
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    from jax.flatten_util import ravel_pytree

    from jaxdobby.dobby import vector_field

    params, static = eqx.partition(model, eqx.is_array)
    flat, unravel = ravel_pytree(params)
    key = (jax.tree.structure(model), tuple(np.shape(x) for x in jax.tree.leaves(params)))
    if key not in _JITTED:
        k = model.n_modes

        def field(t, y, flat):
            m = eqx.combine(unravel(flat), static)
            qdot, qddot = vector_field(t, (y[:k], y[k:]), m)
            return jnp.concatenate([qdot, qddot])

        _JITTED[key] = (jax.jit(field), jax.jit(jax.jacfwd(field, argnums=1)))
    f, j = _JITTED[key]
    return (lambda t, y: np.asarray(f(t, y, flat)), lambda t, y: np.asarray(j(t, y, flat)))


def metric_error(metrics: dict, reference: dict) -> float:
    """Error of a run's metrics against a reference [-]: the largest over :data:`METRICS` of
    |m − m_ref| / scale, with scale = |m_ref| for the ranges and amplitudes and the reference's
    ``deviation_pp`` for ``deviation_min``/``deviation_max`` (signed levels that may pass
    near zero)."""
    worst = 0.0
    for name in METRICS:
        ref = float(reference[name])
        scale = abs(float(reference["deviation_pp"])) if name in ("deviation_min",
                                                                  "deviation_max") else abs(ref)
        worst = max(worst, abs(float(metrics[name]) - ref) / scale)
    return worst
