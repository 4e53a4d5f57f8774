"""The periodic steady cycle of one machine by collocation, as time series.

The fast path of :func:`jaxdobby.simulate.simulate` (``method="collocation"``): the equations of
the batch evaluator (:mod:`jaxdobby.periodic.cycle`, :mod:`jaxdobby.periodic.stepper`: the two-way
coupled model, three-stage Gauss collocation on a phase-normalised grid, the chain in closed
form) with

* the periodic state by chord shooting started from the periodic state of the equations
  linearised about the rigid motion, with their monodromy matrix as the chord matrix (as the
  batch evaluator, :mod:`jaxdobby.periodic.linear`), and the implicit-function derivative of
  :func:`jaxdobby.steady_state.attach_root_derivative` (so gradients through a run follow
  dx₀/dp = (I − F_x)⁻¹ F_p, not the iterations; a cheaper reverse-mode-only form of the same
  derivative for the optimiser, :func:`_steady_reverse`);
* the steady cycle as the collocation polynomial (:func:`jaxdobby.periodic.collocation.dense_weights`)
  sampled ``per_step`` times per step, uniformly in time, plus the end point t = T.

The collocation solution is accurate to O(h⁴) between the step boundaries (the stage order) and
O(h⁶) at them; with the default 432 steps per cycle its metrics agree with the adaptive reference
to ~3e-5 (:mod:`jaxdobby.periodic.steady`; the tests compare this path too).
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ..dobby import DobbyModel
from ..outputs import ArmMotion
from ..steady_state import ShootingResult, attach_root_derivative, relative_residual
from .chain import Downstream, chain_reachable, chain_terms
from .collocation import MATRIX2, NODES, dense_weights
from .cycle import ArmTerms, RigidArm, StageTables, node_phases, rigid_arm, tables_at
from .linear import linearise
from .steady import Cycle, terms_of
from .stepper import PassResult, cycle_pass

PER_STEP = 4
"""Output times per collocation step (uniform in time)."""


class DenseCycle(eqx.Module):
    """The steady cycle of :func:`steady_cycle`.

    Attributes:
        time: output times t [s], shape (n,), 0 … T uniformly (n = steps·per_step + 1).
        q, qdot: modal coordinates and rates there, shape (n, k).
        shooting: the periodic state's shooting result.
        end: the state after the saved cycle, (2k,) (for the periodicity check).
        reachable: the chain closed at every collocation node of the saved cycle.
        outputs: the heald frame's rigid and flexible motion, the link-11 joint's deviation
            and the link forces at ``time`` (:func:`outputs_at`; the keys of
            :class:`~jaxdobby.outputs.Timeseries`).
        motion: the arm's rigid motion and q̈ at ``time`` (:class:`~jaxdobby.outputs.ArmMotion`).
    """

    time: Array
    q: Array
    qdot: Array
    shooting: ShootingResult
    end: Array
    reachable: Array
    outputs: dict
    motion: ArmMotion


def outputs_at(arm: ArmTerms, ds: Downstream, rigid: RigidArm, st: StageTables, q: Array,
               qdot: Array) -> tuple[dict[str, Array], ArmMotion]:
    """What a run reports at output times, from the state (q, q̇) there (each (n, k)) and the
    rigid motion's tables ``st`` and ``rigid`` at the same phases (leading axis n): the keys of
    :class:`~jaxdobby.outputs.Timeseries`, and the arm's motion with q̈
    (:class:`~jaxdobby.outputs.ArmMotion`, what the stress correction needs).

    The chain in closed form (:func:`~jaxdobby.periodic.chain.chain_terms`), q̈ from the
    equations of motion at (q, q̇) — M(q) q̈ = f − C q̇ − K q + g φ, the residual of the
    passes — and the same definitions as :func:`jaxdobby.outputs.flexible_outputs` and
    :func:`~jaxdobby.outputs.rigid_outputs` (which use the autodiff kinematics of
    :mod:`jaxdobby.dobby`; the tests hold the two to round-off). SI units, heights and forces
    positive up; the link-11 force acts on the arm, in inertial axes.
    """
    flex = jax.vmap(chain_terms, in_axes=(None, 0, 0, 0))(ds, st.frame, q @ ds.rows.T,
                                                          qdot @ ds.rows.T)
    omega = st.frame.omega
    force = (st.force - qdot @ arm.damping.T - 2.0 * omega[:, None] * (qdot @ arm.gyroscopic.T)
             - jnp.einsum("nij,nj->ni", st.stiffness, q) + flex.phi[:, None] * flex.g)
    mass = arm.mass[None] + flex.mu[:, None, None] * flex.g[:, :, None] * flex.g[:, None, :]
    qddot = jnp.linalg.solve(mass, force[..., None])[..., 0]
    beta_acc = jnp.sum(flex.g * qddot, axis=1) + flex.h_beta
    c, s = st.frame.cos, st.frame.sin

    def inertial(v):
        return jnp.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], axis=1)

    link_body = flex.grad_body * (flex.phi - flex.mu * (beta_acc - flex.h_beta))[:, None]
    motion = ArmMotion(cos=c, sin=s, rate=omega, acceleration=st.frame.alpha,
                       ring_direction=rigid.ring, link_force=st.link_force,
                       modal_acceleration=qddot)
    outputs = dict(
        heald_flexible=flex.height,
        velocity_flexible=flex.slope * flex.beta_rate,
        acceleration_flexible=flex.slope * beta_acc + flex.curvature * flex.beta_rate**2,
        link_point_deviation=inertial(q @ ds.rows.T),
        ring_link_force=arm.ring_stiffness * jnp.sum(rigid.ring * (q @ arm.ring_rows.T), axis=1),
        link11_force=inertial(link_body),
        modal=q,
        modal_rate=qdot,
        heald_rigid=st.height,  # the tables' chain at q = 0
        velocity_rigid=st.velocity,
        acceleration_rigid=st.acceleration,
    )
    return outputs, motion


class _Chord(NamedTuple):
    """State of the chord iteration of :func:`steady_cycle`: passes run, the next start state,
    the residuals of the last two passes, and the last pass (its start state and result)."""

    passes: Array
    x: Array
    residual: Array
    previous: Array
    start: Array
    run: PassResult


def _recorded_pass(cycle: Cycle, x: Array) -> PassResult:
    """One recording pass of ``cycle`` from ``x`` (what every chord iteration runs)."""
    return cycle_pass(cycle.arm, cycle.downstream, cycle.tables, cycle.period, x, record=True)


@jax.custom_jvp
def _replayed(cycle: Cycle, x: Array, run: PassResult) -> PassResult:
    """``run``, the recorded pass of ``cycle`` from ``x``, computed already: its value is
    returned as it is; its derivative is that of the pass (a JVP of it, traced only under
    differentiation). The forward program then holds one copy of the pass, the chord loop's."""
    return run


@_replayed.defjvp
def _replayed_jvp(primals, tangents):
    cycle, x, run = primals
    d_cycle, d_x, _ = tangents
    _, d_run = jax.jvp(_recorded_pass, (cycle, x), (d_cycle, d_x))
    return run, d_run


def _steady_outputs(cycle: Cycle, x: Array) -> tuple[Array, tuple[Array, Array, Array]]:
    """(end state, trajectory) of the recorded pass of ``cycle`` from ``x``."""
    run = _recorded_pass(cycle, x)
    return run.end, run.trajectory


@jax.custom_vjp
def _steady_reverse(cycle: Cycle, root: Array, end: Array, trajectory):
    """(``end``, ``trajectory``): the recorded pass of ``cycle`` from its periodic state
    ``root``, computed already, with the reverse-mode derivative of the whole steady cycle
    (the pass and the periodic state's implicit-function derivative) in one pullback of the
    pass; see :func:`_steady_reverse_bwd`. Reverse mode only."""
    return end, trajectory


def _steady_reverse_fwd(cycle, root, end, trajectory):
    return (end, trajectory), (cycle, root, end, trajectory)


def _steady_reverse_bwd(res, cotangent):
    """The pullback of R(p, x*(p)), R the recorded pass, x* = F(p, x*) its periodic state:

        p̄ = R_pᵀ r̄ + F_pᵀ λ,   λ = (I − F_x)⁻ᵀ R_xᵀ r̄.

    R_x (every output's derivative by the 2k start coordinates, F_x among them) is one
    forward pass carrying 2k tangents; F = R.end, so both terms of p̄ are one pullback of the
    pass with the cotangent r̄ + λ on its end state."""
    cycle, root, end, trajectory = res
    n = root.shape[0]
    cols = jax.vmap(lambda v: jax.jvp(lambda x: _steady_outputs(cycle, x), (root,), (v,))[1])(
        jnp.eye(n, dtype=root.dtype))
    x_bar = sum(jnp.tensordot(c, b, axes=b.ndim)
                for c, b in zip(jax.tree.leaves(cols), jax.tree.leaves(cotangent)))
    monodromy = cols[0].T
    lam = jnp.linalg.solve(jnp.eye(n, dtype=root.dtype) - monodromy.T, x_bar)
    end_bar, traj_bar = cotangent
    _, pullback = jax.vjp(lambda c: _steady_outputs(c, root), cycle)
    (cycle_bar,) = pullback((end_bar + lam, traj_bar))
    return (cycle_bar, jnp.zeros_like(root), jnp.zeros_like(end),
            jax.tree.map(jnp.zeros_like, trajectory))


_steady_reverse.defvjp(_steady_reverse_fwd, _steady_reverse_bwd)


def steady_cycle(model: DobbyModel, steps: int, *, tolerance=1e-6, per_step: int = PER_STEP,
                 max_iterations: int = 8, reverse_only: bool = False) -> DenseCycle:
    """Periodic steady cycle of ``model`` by collocation (see the module docstring).

    The chord iteration x ← x + (I − Φ)⁻¹(F(x) − x) starts from the periodic state of the
    equations linearised about the rigid motion, with their monodromy matrix Φ
    (:func:`~jaxdobby.periodic.linear.linearise`, as the batch evaluator), and stops one pass
    after the residual ‖F(x) − x‖/‖x‖ falls to ``tolerance``: that last pass, from the
    corrected state, is the recorded steady cycle. Every pass is the same recording pass, so
    the compiled program holds it once; the recorded cycle is differentiable through
    :func:`_replayed` and the implicit-function derivative of the periodic state
    (:func:`jaxdobby.steady_state.attach_root_derivative`), in forward and reverse mode; with
    ``reverse_only``, through :func:`_steady_reverse` (reverse mode only: ``jax.jacfwd`` raises),
    which pulls the cotangents of the pass and of the periodic state back in one pullback of
    the pass. The same derivative (to round-off: 1e-8 relative in
    ``tests/test_optimize_studies.py``) at about half the cost: the design gradient of
    ``jaxdobby optimize`` with 8 variables costs 3.2 forward solves against 5.1
    (``benchmarks/gradient_cost.py``): ``jax.lax.custom_root`` and :func:`_replayed` linearise
    the pass three times (the recorded cycle, F_p, F_x) and pull two of them back; here one
    pass carries 2k tangents and one is pulled back.

    Args:
        model: the coupled model (two-way coupling).
        steps: collocation steps per cycle (static).
        tolerance: relative periodicity to stop the shooting at.
        per_step: output times per step (static).
        max_iterations: chord iterations at most before the recorded pass (static).
        reverse_only: differentiable in reverse mode only, at less cost (static).
    """
    if model.machine.coupling != "two-way":
        raise ValueError("the collocation path solves the two-way coupled model; got coupling="
                         f"{model.machine.coupling!r} (use method='rk4' or 'adaptive')")
    # the rigid motion at the collocation nodes and at the output times in one evaluation
    # (one copy of the autodiff kinematics in the program); the end t = T is the phase 0 of the
    # periodic motion (the opposing warp law turns there)
    n_out = steps * per_step
    terms = terms_of(model)
    arm, ds, period = terms.arm, terms.downstream, terms.period
    phases = jnp.concatenate([node_phases(steps).reshape(-1),
                              (jnp.arange(n_out + 1) % n_out) / n_out])
    rigid = rigid_arm(model, phases)
    every = tables_at(arm, ds, rigid, period)
    tables = jax.tree.map(lambda a: a[:3 * steps].reshape((steps, 3) + a.shape[1:]), every)
    out_tables, out_rigid = (jax.tree.map(lambda a: a[3 * steps:], x) for x in (every, rigid))
    cycle = terms.cycle(tables)

    def iterate(c):
        lin = linearise(c.arm, c.downstream, c.tables, c.period)
        chord = jnp.linalg.inv(jnp.eye(lin.monodromy.shape[0]) - lin.monodromy)
        x = chord @ lin.rest_response
        inf = jnp.asarray(jnp.inf, x.dtype)

        def step(it):
            run = _recorded_pass(c, it.x)
            return _Chord(it.passes + 1, it.x + chord @ (run.end - it.x),
                          relative_residual(it.x, run.end), it.residual, it.x, run)

        def keep_going(it):
            # run until the pass *after* the one whose residual reached the tolerance
            return (it.passes <= max_iterations) & (it.previous > tolerance)

        # no pass before the loop (it would be a second copy in the program): a blank one
        blank = jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype),
                             jax.eval_shape(_recorded_pass, c, x))
        return jax.lax.while_loop(keep_going, step, _Chord(jnp.asarray(0), x, inf, inf, x, blank))

    it = jax.lax.stop_gradient(iterate(cycle))
    converged_residual = jnp.where(it.previous > tolerance, it.residual, it.previous)
    if reverse_only:
        state = it.start
        end, (q, v, acc) = _steady_reverse(cycle, state, it.run.end, it.run.trajectory)
    else:
        state = attach_root_derivative(lambda x: _recorded_pass(cycle, x).end, it.start)
        run = _replayed(cycle, state, it.run)
        end, (q, v, acc) = run.end, run.trajectory
    shooting = ShootingResult(state=state, residual=converged_residual, iterations=it.passes,
                              converged=converged_residual <= tolerance)
    h = period / steps
    theta = np.arange(per_step) / per_step
    w1, w2 = (jnp.asarray(w) for w in dense_weights(theta))
    k = q.shape[1]
    qs = (q[:, None] + (h * jnp.asarray(theta))[None, :, None] * v[:, None]
          + h**2 * jnp.einsum("jm,nmk->njk", w2, acc)).reshape(-1, k)
    vs = (v[:, None] + h * jnp.einsum("jm,nmk->njk", w1, acc)).reshape(-1, k)
    t = (h * (jnp.arange(steps)[:, None] + jnp.asarray(theta)[None])).reshape(-1)
    # the chain must close at every collocation node (stage positions Qᵢ of every step)
    stage_q = q[:, None] + h * jnp.asarray(NODES)[None, :, None] * v[:, None] \
        + h**2 * jnp.einsum("im,nmk->nik", jnp.asarray(MATRIX2), acc)
    frames = jax.tree.map(lambda a: a.reshape(-1), tables.frame)
    reach = jax.vmap(chain_reachable, in_axes=(None, 0, 0))(
        ds, frames, stage_q.reshape(-1, k) @ ds.rows.T)
    q_all = jnp.concatenate([qs, end[None, :k]])
    qdot_all = jnp.concatenate([vs, end[None, k:]])
    outputs, motion = outputs_at(arm, ds, out_rigid, out_tables, q_all, qdot_all)
    return DenseCycle(time=jnp.concatenate([t, period[None]]), q=q_all, qdot=qdot_all,
                      shooting=shooting, end=end, reachable=jnp.all(reach),
                      outputs=outputs, motion=motion)
