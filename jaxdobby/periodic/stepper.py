"""One cycle of the coupled equations by Gauss collocation, with extremes reduced on the fly.

A *pass* integrates one heald-frame cycle from a state x = (q, q̇) with the three-stage Gauss
method of :mod:`jaxdobby.periodic.collocation` on the tables of :mod:`jaxdobby.periodic.cycle`
(``lax.scan`` over the N steps). Each step:

1. predicts the stage accelerations by extrapolating the previous step's (a quadratic);
2. runs two simplified-Newton iterations on the stage equations. The residual is the full
   nonlinear one of :func:`jaxdobby.dobby.equations_at` (the chain in closed form,
   :func:`jaxdobby.periodic.chain.chain_terms`). The matrix is either given, inverted once per
   step before the pass (the equations linearised about the rigid motion,
   :mod:`jaxdobby.periodic.linear`: what the batch evaluator uses), or frozen at the middle node of
   the step's predicted stages: the chain's inertia μ g gᵀ there, K(τ), C(τ) — and, with
   ``full_jacobian``, the chain's stiffness and damping (forward-mode derivatives in the
   joint's two displacement and two velocity components). Two iterations (the default) leave
   a cycle's metrics within ~3e-7 of converged ones (``tests/test_batch.py``);
3. optionally carries tangent vectors through the linear step map of that frozen matrix (the
   monodromy matrix for the shooting of :mod:`jaxdobby.periodic.dense`);
4. optionally records the heald frame's displacement deviation, velocity deviation and
   acceleration at the three nodes and keeps running maxima and minima, each local extremum of
   the sampled series refined by the parabola through it and its two neighbours (the nodes are
   0.11…0.39 h apart), wrapping around the periodic cycle. No time series is stored;
5. optionally (``record``) returns each step's start state and converged stage accelerations,
   from which :func:`jaxdobby.periodic.collocation.dense_weights` gives the solution at any time
   (the time series of :func:`jaxdobby.simulate.simulate`).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import Array

from . import collocation as gl
from .chain import Downstream, chain_reachable, chain_terms
from .cycle import ArmTerms, StageTables
from .linear import chain_jacobian, tangent_step

SIGNALS = ("deviation", "velocity_deviation", "acceleration")
"""The signals whose extremes a pass records, in this order."""


class PassResult(NamedTuple):
    """What a pass returns.

    Attributes:
        end: state after one cycle, (2k,).
        tangents: the tangents after one cycle, (2k, m) (m = 0 without tangents).
        maxima, minima: extremes of :data:`SIGNALS` over the cycle, each (3,) [m, m/s, m/s²].
        reachable: the chain closed at every node.
        trajectory: with ``record``, (q_n, q̇_n, A) at the start of every step, shapes (N, k),
            (N, k), (N, 3, k) (A: the converged stage accelerations); else None.
    """

    end: Array
    tangents: Array
    maxima: Array
    minima: Array
    reachable: Array
    trajectory: tuple[Array, Array, Array] | None = None


def _residuals(arm: ArmTerms, ds: Downstream, st: StageTables, pos, vel, acc, key=None):
    """Stage residuals F − M(Q)A, (3, k), and the chain terms at the three nodes."""
    rows_t = gl.transpose(ds.rows)
    ct = jax.vmap(chain_terms, in_axes=(None, 0, 0, 0))(ds, st.frame, gl.matmul(pos, rows_t),
                                                        gl.matmul(vel, rows_t))
    if key is not None:
        ct = gl.stored(ct, key)
    kq = sum(st.stiffness[:, :, j] * pos[:, j, None] for j in range(pos.shape[1]))
    cv = (gl.matmul(vel, gl.transpose(arm.damping))
          + 2.0 * st.frame.omega[:, None] * gl.matmul(vel, gl.transpose(arm.gyroscopic)))
    ga = sum(ct.g[:, j] * acc[:, j] for j in range(acc.shape[1]))
    ma = gl.matmul(acc, gl.transpose(arm.mass)) + (ct.mu * ga)[:, None] * ct.g
    out = (st.force - cv - kq + ct.phi[:, None] * ct.g - ma, ct)
    return out if key is None else gl.stored(out, key)


def _outer(g):
    """g gᵀ of a (k, lanes...) vector."""
    return g[:, None] * g[None]


def _parabola_peaks(t, y):
    """Largest and smallest values of the parabolas through (t, y)[j−1:j+2] at interior local
    extrema of the sequences y (signal, sequence, lanes...) at times t (1, sequence, lanes...),
    else the samples themselves; each (signal, lanes...)."""
    tm, t0, tp = t[:, :-2], t[:, 1:-1], t[:, 2:]
    ym, y0, yp = y[:, :-2], y[:, 1:-1], y[:, 2:]
    a, b = tm - t0, tp - t0
    dm, dp = (ym - y0) / a, (yp - y0) / b
    r = (dp - dm) / (b - a)
    p = dp - r * b
    safe = jnp.where(r == 0.0, 1.0, r)
    vertex = y0 - p**2 / (4.0 * safe)
    is_max = (y0 >= ym) & (y0 >= yp) & (r < 0.0)
    is_min = (y0 <= ym) & (y0 <= yp) & (r > 0.0)
    hi = jnp.where(is_max, vertex, y0)
    lo = jnp.where(is_min, vertex, y0)
    return jnp.nanmax(hi, axis=1), jnp.nanmin(lo, axis=1)


def cycle_pass(arm: ArmTerms, ds: Downstream, tables, period, x0: Array, *,
               solvers=None, tangents: Array | None = None, full_jacobian: bool = False,
               outputs: bool = False, record: bool = False, steps: int | None = None,
               iterations: int = 2, count=None) -> PassResult:
    """Integrate one cycle from ``x0`` (see the module docstring).

    Args:
        arm, ds: the model's Kane terms and chain.
        tables: :class:`~jaxdobby.periodic.cycle.StageTables` with leading axes (N, 3), or a
            function of the step index n returning step n's, leading axis (3,), with ``steps``
            = N (to read a lane's tables out of a batch's without copying them first).
        period: T [s].
        x0: initial state (q, q̇), (2k,). A batch with its lanes last (as
            :func:`jaxdobby.periodic.steady._solve` runs one): x0 (2k, B) and every leaf of
            the other arguments with a trailing lane axis; the results then have it too.
        solvers: the steps' Newton matrices, inverted once beforehand
            (:class:`~jaxdobby.periodic.collocation.StageSolver` with leading axis N, from
            :func:`jaxdobby.periodic.linear.linearise`), or a function of the step index n
            returning step n's (with ``tables`` a function too); None: each step builds its own
            at the middle node of its predicted stages.
        tangents: (2k, m) tangent vectors to carry, or None.
        full_jacobian: include the chain's stiffness and damping in the Newton matrix.
        outputs: record the extremes of :data:`SIGNALS`.
        record: return the trajectory (see :class:`PassResult`).
        iterations: simplified-Newton iterations per step (static, ≥ 1; the outputs are taken
            at the stage states of the last one's residual).
        count: None, the cycle is the tables' N steps (a scan); else its number of steps, a
            run-time integer ≤ N (the tables' first ``count`` rows, made by
            :func:`jaxdobby.periodic.cycle.node_phases` with a ``size``): a loop of that many
            steps (not differentiable in reverse mode, no ``record``).
    """
    if iterations < 1:
        raise ValueError(f"iterations must be at least 1; got {iterations}")
    k = x0.shape[0] // 2
    if callable(tables):
        table_at, n_steps, xs_tables = tables, steps, None
    else:
        table_at, n_steps, xs_tables = None, tables.height.shape[0], tables
    if solvers is not None and (tangents is not None or full_jacobian):
        raise ValueError("stored solvers do not carry tangents (see jaxdobby.periodic.linear)")
    solver_at = solvers if callable(solvers) else None
    xs_solvers = None if callable(solvers) else solvers
    if count is not None and record:
        raise ValueError("a pass of a run-time step count does not record its trajectory")
    h = period / (n_steps if count is None else count)
    rows = ds.rows
    m = 0 if tangents is None else tangents.shape[1]

    def step(carry, xs):
        index, st, solver = xs
        if table_at is not None:
            st = table_at(index)
        if solver_at is not None:
            solver = solver_at(index)
        q, v, prev, tan, ext = carry
        acc = gl.weigh(gl.EXTRAPOLATE, prev)
        pos, vel = gl.stored(gl.stage_states(q, v, acc, h), index)
        res, ct = _residuals(arm, ds, st, pos, vel, acc, index)
        if solvers is None:
            mid = jax.tree.map(lambda a: a[1], st)
            mass = arm.mass + ct.mu[1] * _outer(ct.g[1])
            stiff = mid.stiffness
            damp = arm.damping + 2.0 * mid.frame.omega * arm.gyroscopic
            if full_jacobian:
                ju, jud = chain_jacobian(ds, mid.frame, gl.matmul(rows, pos[1]),
                                         gl.matmul(rows, vel[1]), acc[1])
                stiff, damp = gl.stored((stiff - gl.matmul(ju, rows),
                                       damp - gl.matmul(jud, rows)), index)
            solver = gl.stored(gl.StageSolver(mass, damp, stiff, h), index)
        for _ in range(iterations - 1):
            acc = gl.stored(acc + solver.solve(res), index)
            pos, vel = gl.stored(gl.stage_states(q, v, acc, h), index)
            res, ct = _residuals(arm, ds, st, pos, vel, acc, index)
        out_acc = acc
        acc = gl.stored(acc + solver.solve(res), index)
        qn, vn = gl.advance(q, v, acc, h)
        if m:
            tan = tangent_step(solver, damp, stiff, tan, h)
        if outputs:
            ga = sum(ct.g[:, j] * out_acc[:, j] for j in range(k))
            values = jnp.stack([
                ct.height - st.height,
                ct.slope * ct.beta_rate - st.velocity,
                ct.slope * (ga + ct.h_beta) + ct.curvature * ct.beta_rate**2,
            ])  # (signal, node)
            hist_t, hist_y, head, hi, lo, ok = ext
            t_seq = jnp.concatenate([hist_t, st.frame.phase])
            y_seq = jnp.concatenate([hist_y, values], axis=1)
            new_hi, new_lo = _parabola_peaks(t_seq[None], y_seq)
            reach = jax.vmap(chain_reachable, in_axes=(None, 0, 0))(
                ds, st.frame, gl.matmul(pos, gl.transpose(rows)))
            head = jnp.where(index == 0, values[:, :2], head)
            ext = (t_seq[-2:], y_seq[:, -2:], head, jnp.fmax(hi, new_hi), jnp.fmin(lo, new_lo),
                   ok & jnp.all(reach, axis=0))
        return (qn, vn, acc, tan, ext), ((q, v, acc) if record else None)

    # starting predictor: q̈ from the equations at the initial state and the first node
    step0 = jax.tree.map(lambda a: a[0], xs_tables) if table_at is None else table_at(0)
    first = jax.tree.map(lambda a: a[:1], step0)
    q0, v0 = x0[:k], x0[k:]
    lanes = x0.shape[1:]
    res0, ct0 = _residuals(arm, ds, first, q0[None], v0[None], jnp.zeros((1, k) + lanes))
    a0 = gl.solve(arm.mass + ct0.mu[0] * _outer(ct0.g[0]), res0[0])
    prev = jnp.broadcast_to(a0, (3,) + a0.shape)
    tan0 = jnp.zeros((2 * k, 0)) if tangents is None else tangents
    ext0 = ()
    if outputs:
        nan2 = jnp.full((3, 2) + lanes, jnp.nan)
        ext0 = (jnp.full((2,) + lanes, jnp.nan), nan2, nan2, jnp.full((3,) + lanes, -jnp.inf),
                jnp.full((3,) + lanes, jnp.inf), jnp.ones(lanes, bool))
    carry = (q0, v0, prev, tan0, ext0)
    if count is None:
        (q, v, _, tan, ext), trajectory = jax.lax.scan(
            step, carry, (jnp.arange(n_steps), xs_tables, xs_solvers))
    else:
        def at(index, tree):
            return jax.tree.map(lambda a: a[index], tree)

        (q, v, _, tan, ext), trajectory = jax.lax.fori_loop(
            0, count, lambda n, c: step(c, (n, at(n, xs_tables), at(n, xs_solvers)))[0],
            carry), None
    if outputs:
        hist_t, hist_y, head, hi, lo, ok = ext
        # the cycle is periodic: refine the extrema at the seam too
        t_seq = jnp.concatenate([hist_t - 1.0, step0.frame.phase[:2]])
        y_seq = jnp.concatenate([hist_y, head], axis=1)
        seam_hi, seam_lo = _parabola_peaks(t_seq[None], y_seq)
        maxima, minima = jnp.fmax(hi, seam_hi), jnp.fmin(lo, seam_lo)
    else:
        maxima = minima = jnp.full((3,) + lanes, jnp.nan)
        ok = jnp.ones(lanes, bool)
    return PassResult(jnp.concatenate([q, v]), tan, maxima, minima, ok, trajectory)
