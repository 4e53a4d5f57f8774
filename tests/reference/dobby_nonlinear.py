"""Independent reference, part 2: the whole default machine with a co-rotational arm (issue 21).

The arm (:mod:`tests.reference.corotational_arm`) keeps every finite-element DOF (no modal
reduction), its stiffness comes from the co-rotational strain energy (no linearised stiffening,
no preload assumption), and the ring link 9 is a real two-force member: an axial spring
k₉ = E A₉ / L₉ between the eccentric pin Q(t) of the rigid crank and the *actual* ring-link joint
J of the deformed arm, V₉ = ½ k₉ (|J − Q| − L₉)², its direction following the motion. The
downstream chain (link 11, big blade, tumblers, heald frame, warp force) is jaxdobby's rigid
one-DOF closure (``chain_from_joint``, ``generalised_chain_forces``, ``chain_inertia``) — not
the assumption under test — driven by the actual link-11 joint P; the coupling is written here.

Coordinates: the full nodal displacement field u (3 per node) in the frame that turns with the
rigid arm angle θ(t) of the crank-rocker — an exact change of variables (no term is dropped):
a material point moves to r = A(θ)(X + N u), so with ω = θ̇, α = θ̈ and S the 90° turn

    (M_t + M_r) ü + 2ω G u̇ + α[(M_t + M_r) s_X + G u] − ω² M_t (x_X + u)
        + ∇U(u) + C u̇ + ∇_u V₉ + (∂c/∂u)ᵀ (D c̈ − Q_c) = M_t (x, y) Aᵀ g,

where c = (β, y_H) = chain(A(X_P + u_P)) and c̈ = C'(P) P̈ + C''(P)[Ṗ, Ṗ] with
P̈ = A(ü_P + 2ωSu̇_P + αS r_P − ω² r_P) (Kane's partial velocities, as d'Alembert's principle
gives for any field; Kane & Levinson 1985). Damping C: ``"modal"`` — 2 % in *every* mode of the
supported arm (C = MΦ diag(2ζω)Φᵀ M over all modes: jaxdobby's damping where it keeps the
mode) — or ``"stiffness"`` — C = (2ζ/ω₁)·K, 2 % at the first mode and rising with frequency.

Switches (:class:`Options`) put back one of jaxdobby's assumptions at a time: ``ring="fixed"``
(spring along the rigid-kinematics direction, k₉ n nᵀ u_J), ``elastic="linear"`` (K u plus the
consistent geometric stiffness Σₑ Nₑ(t) K_σₑ u of the static axial forces of the rigid-motion
loads and the rigid link-11 force — jaxdobby's linearised stiffening), ``"linear-inertia"`` (the
same without gravity and warp force in the preload), ``"linear-actual"`` (the same with the
*actual* link-11 force of the coupled motion in the preload instead of the rigid one — the fix
the budget points to), ``"linear-none"`` (no stiffening),
``rotary_inertia=False``, ``damping="stiffness"``; ``preload_ring="actual"`` solves the
preload's static problems with the ring link along its direction at t (not at mid-lift).

Time integration: the implicit midpoint rule (symmetric, A-stable, second order) on a uniform
grid of ``steps`` per cycle, a chord-Newton solve per step; the periodic state by Newton
shooting with the exact monodromy matrix of the discrete map (products of step Jacobians).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
import scipy.linalg

from jaxdobby.dobby import (build_model, chain_from_joint, chain_inertia, crank_angle,
                            generalised_chain_forces, rigid_joint_position, rigid_state)
from tests.reference.corotational_arm import arm_from_design, free_dofs, spring

_S = jnp.array([[0.0, -1.0], [1.0, 0.0]])
_CYCLES = {}  # compiled cycle maps, see Reference._cycle_fn


@dataclasses.dataclass(frozen=True)
class Options:
    """Model-form switches of the reference (defaults: the reference itself)."""

    ring: str = "follow"            # "follow" | "fixed"
    elastic: str = "corotational"   # or "linear", "linear-inertia", "linear-actual", "linear-none"
    preload_ring: str = "mid-lift"  # ring direction of the preload's static solves, or "actual"
    rotary_inertia: bool = True
    damping: str = "modal"          # "modal" | "stiffness" | "none"
    refine: int = 1
    steps: int = 6000


@jax.jit
def _rigid_rows(m, t):
    """The rigid mechanism of jaxdobby's model ``m`` at times t (n_t,) and its link-11 force."""
    rs = jax.vmap(lambda tt: rigid_state(m, tt))(t)
    phi = crank_angle(m.chain, m.crank_start, t, m.operating.speed)
    pin = m.chain.eccentric_axis + m.chain.eccentricity * jnp.stack(
        [jnp.cos(phi), jnp.sin(phi)], -1)
    y_rigid = jax.vmap(lambda tt: chain_from_joint(m, rigid_joint_position(m, tt))[1])(t)
    f = rs.frame
    row = dict(t=t, theta=f.angle, omega=f.angular_velocity, alpha=f.angular_acceleration,
               pin=pin, n=rs.ring_direction, y_rigid=y_rigid)
    return row, rs.link_force


def _rot(theta):
    c, s = jnp.cos(theta), jnp.sin(theta)
    return jnp.array([[c, -s], [s, c]])


class Reference:
    """The reference machine for one (machine, operating point, options)."""

    def __init__(self, machine, operating, options: Options = Options()):
        self.options, self.machine = options, machine
        self.model = model = build_model(machine, operating)
        self.arm = arm = arm_from_design(machine.arm, options.refine, options.rotary_inertia)
        self.free = free_dofs(arm)
        self.j = arm.node(machine.arm.ring_joint_arc_length)
        self.p = arm.node(machine.chain.link11_arc_length)
        self.k9 = float(machine.ring_link_stiffness)
        self.L9 = float(machine.linkage.ring_link_length)
        self.mass = arm.M_t + arm.M_r
        k_sup = arm.K + spring(arm, self.j, np.asarray(model.ring_direction_ref), self.k9)
        self.k_supported = k_sup
        f = self.free
        lam, phi = scipy.linalg.eigh(k_sup[np.ix_(f, f)], self.mass[np.ix_(f, f)])
        self.frequencies_hz = np.sqrt(lam) / (2 * np.pi)
        zeta = float(machine.damping_ratio)
        c = np.zeros_like(k_sup)
        if options.damping == "modal":
            mf = self.mass[np.ix_(f, f)] @ phi
            c[np.ix_(f, f)] = mf @ np.diag(2 * zeta * np.sqrt(lam)) @ mf.T
        elif options.damping == "stiffness":
            c = 2 * zeta / np.sqrt(lam[0]) * k_sup
        elif options.damping == "none":  # for the energy check
            pass
        else:
            raise ValueError(f"damping = {options.damping!r}")
        self.damping = c
        self.period = float(model.period)
        self.h = self.period / options.steps
        self.n = f.size

    # -- the rigid mechanism, tabulated -------------------------------------------------------
    def rigid_table(self, t):
        """Rows of rigid quantities at times t (n_t,): θ, ω, α, eccentric pin, ring direction
        (body), rigid heald-frame height, element preload forces (``elastic="linear*"``)."""
        row, link_force = _rigid_rows(self.model, jnp.asarray(t))
        row["preload"] = jnp.asarray(self._preload(row, link_force))
        if self.options.preload_ring == "actual" and self.options.elastic == "linear-actual":
            row["link_map"] = jnp.asarray(np.stack([
                self.link_force_map(self.arm.K + spring(self.arm, self.j, n, self.k9))
                for n in np.asarray(row["n"])]))
        return row

    def _preload(self, row, link_force):
        """Static element axial forces [N] of the rigid-motion loads (jaxdobby's K_g preload)."""
        arm, opt = self.arm, self.options.elastic
        n_t = row["t"].shape[0]
        if opt in ("corotational", "linear-none"):
            return np.zeros((n_t, arm.L.size))
        g = 0.0 if opt == "linear-inertia" else float(self.machine.gravity)
        theta, om, al = (np.asarray(row[k]) for k in ("theta", "omega", "alpha"))
        lf = np.asarray(link_force) * (opt != "linear-actual")  # actual force: in residual
        if opt == "linear-inertia":  # the link force without frame weight and warp force
            mi = build_model(self.machine.replace(gravity=0.0),
                             self.model.operating.__class__(speed=self.model.operating.speed,
                                                            warp_force=0.0))
            lf = np.asarray(_rigid_rows(mi, row["t"])[1])
        gb = np.stack([-g * np.sin(theta), -g * np.cos(theta)], -1)  # Aᵀ(0, −g)
        loads = (om[:, None] ** 2 * (arm.M_t @ arm.position)
                 - al[:, None] * (self.mass @ arm.rotation)
                 + gb[:, :1] * (arm.M_t @ arm.x) + gb[:, 1:] * (arm.M_t @ arm.y))
        loads[:, 3 * self.p:3 * self.p + 2] += lf
        f = self.free
        u = np.zeros_like(loads)
        if self.options.preload_ring == "actual":  # supports with the ring's direction at t
            nb = np.asarray(row["n"])
            for i in range(n_t):
                k = arm.K + spring(arm, self.j, nb[i], self.k9)
                u[i, f] = np.linalg.solve(k[np.ix_(f, f)], loads[i, f])
        else:
            u[:, f] = np.linalg.solve(self.k_supported[np.ix_(f, f)], loads[:, f].T).T
        return np.stack([arm.axial_forces(ui) for ui in u])

    def link_force_map(self, k_supported=None):
        """Element axial forces [N] per unit body-frame force [N] at the link-11 joint, (n_el, 2):
        the static solve of the supported arm (as the preload's)."""
        k = self.k_supported if k_supported is None else k_supported
        f, out = self.free, []
        for c in range(2):
            load = np.zeros(self.arm.n_dofs)
            load[3 * self.p + c] = 1.0
            u = np.zeros(self.arm.n_dofs)
            u[f] = np.linalg.solve(k[np.ix_(f, f)], load[f])
            out.append(self.arm.axial_forces(u))
        return np.stack(out, 1)

    # -- equations of motion ------------------------------------------------------------------
    def residual(self, q, v, a, row):
        """R(q, q̇, q̈) = inertia + internal − applied generalised forces on the free DOFs [N]."""
        arm, opt = self.arm, self.options
        nd = arm.n_dofs
        u, ud, udd = (jnp.zeros(nd).at[self.free].set(x) for x in (q, v, a))
        om, al = row["omega"], row["alpha"]
        rot = _rot(row["theta"])
        mass, mt, g = jnp.asarray(self.mass), jnp.asarray(arm.M_t), jnp.asarray(arm.G)
        r = (mass @ udd + 2 * om * g @ ud + al * (mass @ arm.rotation + g @ u)
             - om**2 * (mt @ (arm.position + u)) + jnp.asarray(self.damping) @ ud)
        gb = rot.T @ jnp.array([0.0, -float(self.machine.gravity)])
        r = r - mt @ (gb[0] * arm.x + gb[1] * arm.y)
        chain_force = self._chain_force(u, ud, udd, row)  # on the arm, body frame [N]
        pd = slice(3 * self.p, 3 * self.p + 2)
        r = r.at[pd].add(-chain_force)
        if opt.elastic == "corotational":
            r = r + jax.grad(arm.strain_energy)(u)
        else:
            preload = row["preload"]
            if opt.elastic == "linear-actual":
                link_map = row.get("link_map", jnp.asarray(self.link_force_map()))
                preload = preload + link_map @ chain_force
            r = r + arm.K @ u + jnp.einsum("e,eij,j->i", preload, arm.K_sigma, u)
        jd = slice(3 * self.j, 3 * self.j + 2)
        if opt.ring == "follow":
            def ring_energy(uj):
                d = rot @ (arm.X[self.j] + uj) - row["pin"]
                return 0.5 * self.k9 * (jnp.sqrt(d @ d) - self.L9) ** 2
            r = r.at[jd].add(jax.grad(ring_energy)(u[jd]))
        else:
            n = row["n"]
            r = r.at[jd].add(self.k9 * n * (n @ u[jd]))
        return r[self.free]

    def _chain_force(self, u, ud, udd, row):
        """Force of link 11 on the arm [N], body frame: −Aᵀ C'(P)ᵀ (D c̈ − Q) (d'Alembert)."""
        m, om, al = self.model, row["omega"], row["alpha"]
        rot = _rot(row["theta"])
        pd = slice(3 * self.p, 3 * self.p + 2)
        rp = self.arm.X[self.p] + u[pd]
        pos = rot @ rp
        vel = rot @ (om * _S @ rp + ud[pd])
        acc = rot @ (udd[pd] + 2 * om * _S @ ud[pd] + al * _S @ rp - om**2 * rp)
        closure = lambda x: chain_from_joint(m, x)  # noqa: E731
        c = closure(pos)
        c_prime, c_second = jax.jvp(jax.jacfwd(closure), (pos,), (vel,))
        c_acc = c_prime @ acc + c_second @ vel
        load = chain_inertia(m) * c_acc - generalised_chain_forces(m, row["t"], c[1])
        return -rot.T @ (c_prime.T @ load)

    def heald_height(self, q, row):
        """Heald-frame height y_H [m] of the deformed machine."""
        u = jnp.zeros(self.arm.n_dofs).at[self.free].set(q)
        pos = _rot(row["theta"]) @ (self.arm.X[self.p] + u[3 * self.p:3 * self.p + 2])
        return chain_from_joint(self.model, pos)[1]

    def partials(self, q, v, a, row):
        """∂R/∂q, ∂R/∂q̇, ∂R/∂q̈ (n, n) each, by forward-mode autodiff."""
        return jax.jacfwd(self.residual, argnums=(0, 1, 2))(q, v, a, row)

    # -- one cycle of the implicit midpoint rule ---------------------------------------------
    def _cycle_fn(self, newton_iterations=4):
        """The jitted cycle map; shared by References of the same machine, warp force and options
        (the speed enters only through the tables and the step h)."""
        key = (id(self.machine), float(self.model.operating.warp_force), self.options)
        if key not in _CYCLES:
            _CYCLES[key] = jax.jit(self._make_cycle(newton_iterations))
        return _CYCLES[key]

    def _make_cycle(self, newton_iterations):
        n = self.n

        def step(carry, rows, h):
            q, v, lu, phi = carry
            mid, end = rows

            def res(vm):
                return self.residual(q + 0.5 * h * vm, vm, 2.0 * (vm - v) / h, mid)

            vm = v
            for _ in range(newton_iterations):
                vm = vm - jsl.lu_solve(lu, res(vm))
            err = jnp.max(jnp.abs(res(vm)))
            rq, rv, ra = self.partials(q + 0.5 * h * vm, vm, 2.0 * (vm - v) / h, mid)
            jv = 0.5 * h * rq + rv + 2.0 / h * ra
            lu = jsl.lu_factor(jv)
            dq = -jsl.lu_solve(lu, rq)
            dv = 2.0 / h * jsl.lu_solve(lu, ra)
            eye = jnp.eye(n)
            step_jac = jnp.block([[eye + h * dq, h * dv], [2.0 * dq, 2.0 * dv - eye]])
            q1, v1 = q + h * vm, 2.0 * vm - v
            out = (self.heald_height(q1, end), err)
            return (q1, v1, lu, step_jac @ phi), (out, q1, v1)

        def cycle(x0, table, h):
            q0, v0 = x0[:n], x0[n:]
            mid0 = jax.tree_util.tree_map(lambda z: z[0], table[0])
            rq, rv, ra = self.partials(q0, v0, jnp.zeros(n), mid0)
            lu = jsl.lu_factor(0.5 * h * rq + rv + 2.0 / h * ra)
            (q, v, _, phi), ((y, err), qs, vs) = jax.lax.scan(
                lambda c, r: step(c, r, h), (q0, v0, lu, jnp.eye(2 * n)), table)
            return jnp.concatenate([q, v]), phi, y, err, qs, vs

        return cycle

    def tables(self):
        """Rigid tables at the step mid-points and ends of one cycle (t = 0 … T)."""
        steps = self.options.steps
        t = np.arange(2 * steps + 1) * 0.5 * self.h
        row = self.rigid_table(t)
        mid = jax.tree_util.tree_map(lambda z: z[1::2], row)
        end = jax.tree_util.tree_map(lambda z: z[2::2], row)
        return mid, end, row

    def steady_state(self, x0=None, tol=1e-7, max_iter=6, verbose=False):
        """Periodic steady state by Newton shooting from ``x0`` (default: rest); a dict with the
        cycle's deviation series, states, shooting diagnostics and the last state ``x0``."""
        cycle = self._cycle_fn()
        mid, end, row = self.tables()
        x0 = jnp.zeros(2 * self.n) if x0 is None else jnp.asarray(x0)
        for it in range(max_iter):
            x1, phi, y, err, qs, vs = cycle(x0, (mid, end), self.h)
            gap = float(jnp.max(jnp.abs(x1 - x0)) / max(float(jnp.max(jnp.abs(x1))), 1e-30))
            if verbose:
                print(f"shooting {it}: periodicity {gap:.2e}, "
                      f"newton residual {float(err.max()):.1e}")
            if gap < tol:
                break
            x0 = x0 + jnp.linalg.solve(jnp.eye(2 * self.n) - phi, x1 - x0)
        y_rigid = np.asarray(end["y_rigid"])
        dev = np.asarray(y) - y_rigid
        return dict(t=np.asarray(end["t"]), deviation=dev, periodicity=gap, iterations=it + 1,
                    newton_residual=float(err.max()), q=np.asarray(qs), v=np.asarray(vs),
                    table=end, monodromy=np.asarray(phi), x0=np.asarray(x0))


def extremes(x):
    """Max and min [same unit] of a periodic signal sampled uniformly, each refined by the
    parabola through the extreme sample and its two neighbours."""
    x = np.asarray(x)

    def top(z):
        k = int(np.argmax(z))
        a, b, c = z[k - 1], z[k], z[(k + 1) % z.size]
        den = a - 2 * b + c
        return b - 0.125 * (c - a) ** 2 / den if den < 0 else b

    return top(x), -top(-x)


def metrics(result):
    """Deviation max, min and peak-to-peak [m] of a steady cycle."""
    hi, lo = extremes(result["deviation"])
    return dict(deviation_max=hi, deviation_min=lo, deviation_pp=hi - lo)


def frozen_frequencies(residual, q, v, row):
    """Natural frequencies [Hz] of a model ``residual(q, q̇, q̈, row)`` linearised about the state
    (q, q̇) with time frozen at ``row``: K = ∂R/∂q, M = ∂R/∂q̈ (symmetric parts), damping and
    gyroscopic terms left out. The same definition is applied to jaxdobby and to the reference."""
    @jax.jit
    def linearise(q, v, row):
        zero = jnp.zeros_like(q)
        ra = jax.jacfwd(residual, argnums=2)(q, v, zero, row)
        a = -jnp.linalg.solve(ra, residual(q, v, zero, row))
        return jax.jacfwd(residual, argnums=0)(q, v, a, row), ra

    k, m = (np.asarray(x) for x in linearise(q, v, row))
    lam = scipy.linalg.eigh(0.5 * (k + k.T), 0.5 * (m + m.T), eigvals_only=True)
    return np.sqrt(np.clip(lam, 0, None)) / (2 * np.pi)


def reference_frequency(ref, result, t_star):
    """First frozen coupled frequency [Hz] of the reference on its steady cycle at ``t_star``."""
    k = int(np.argmin(np.abs(result["t"] - t_star)))
    row = jax.tree_util.tree_map(lambda z: z[k], result["table"])
    return frozen_frequencies(ref.residual, jnp.asarray(result["q"][k]),
                              jnp.asarray(result["v"][k]), row)[0]
