"""Time integration of a flexible body in a prescribed floating frame (diffrax).

:func:`simulate_flexible_body` integrates Kane's equations of :mod:`jaxdobby.floating_frame`
with an adaptive explicit Runge–Kutta method (Tsitouras 5(4) by default; the equations are not
stiff for the handful of modes kept) and returns a :class:`FlexibleResponse`, a small pytree of
time series. It is jittable, vmappable over any float field of its arguments, and differentiable
(diffrax's checkpointed adjoint by default).

Example (the Kane–Ryan–Banerjee spin-up beam, see also :mod:`jaxdobby.examples`)::

    body = flexible_body(beam, Supports(clamped=(0,)), n_modes=4, points=(10.0,))
    out = simulate_flexible_body(body, SpinUp(6.0, 15.0), jnp.linspace(0.0, 30.0, 601))
    out.point_displacements[:, 0, 1]     # transverse tip deflection in the body frame [m]
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax.numpy as jnp
from jax import Array

from ._x64 import require_x64
from .flexible_body import FlexibleBody
from .floating_frame import FrameMotion, frame_state, kane_terms


class PointForces(eqx.Module):
    """Inertial forces at a body's points as a function of time and state: override __call__.

    ``__call__(t, q, qdot, frame)`` returns shape (n_points, 2) [N].
    """

    def __call__(self, t, q, qdot, frame):
        raise NotImplementedError


class FlexibleResponse(eqx.Module):
    """Time series of a flexible-body simulation.

    Attributes:
        ts: times [s], shape (n_t,).
        q, qdot: modal coordinates and rates, shape (n_t, n_modes).
        point_displacements: elastic displacement of each of ``body.points`` in the body frame
            [m], shape (n_t, n_points, 2).
        result: diffrax's result code (``diffrax.RESULTS``), success when the solve succeeded.
        num_steps: accepted steps taken.
    """

    ts: Array
    q: Array
    qdot: Array
    point_displacements: Array
    result: diffrax.RESULTS
    num_steps: Array


def _vector_field(t, y, args):
    body, motion, forces, gravity, stiffening = args
    q, qdot = y
    frame = frame_state(motion, t)
    point_forces = None if forces is None else forces(t, q, qdot, frame)
    mass, force = kane_terms(body, frame, q, qdot, point_forces=point_forces, gravity=gravity,
                             stiffening=stiffening)
    return qdot, jnp.linalg.solve(mass, force)


@eqx.filter_jit
def simulate_flexible_body(body: FlexibleBody, motion: FrameMotion, ts: Array, *,
                           point_forces: PointForces | None = None, gravity=(0.0, 0.0),
                           stiffening=1.0, y0=None, rtol=1e-8, atol=1e-12,
                           solver: diffrax.AbstractSolver | None = None,
                           max_steps: int = 1_000_000, throw: bool = True,
                           adjoint: diffrax.AbstractAdjoint | None = None) -> FlexibleResponse:
    """Integrate the elastic coordinates of ``body`` while its frame follows ``motion``.

    Args:
        body: modal invariants (:func:`~jaxdobby.flexible_body.flexible_body`).
        motion: prescribed frame motion (:class:`~jaxdobby.floating_frame.FrameMotion`).
        ts: output times [s]; the solve runs from ``ts[0]`` to ``ts[-1]``.
        point_forces: optional inertial forces at ``body.points``.
        gravity: inertial gravity vector [m/s²].
        stiffening: geometric-stiffness factor (1 on, 0 off).
        y0: initial ``(q, qdot)``; zeros (undeformed, at rest in the frame) by default.
        rtol, atol: tolerances of the adaptive step controller (atol in units of q).
        solver: a diffrax solver; ``diffrax.Tsit5()`` by default.
        max_steps: step budget (static).
        throw: raise on solver failure (set False under vmap and inspect ``result``).
        adjoint: how to differentiate the solve; diffrax's ``RecursiveCheckpointAdjoint`` (reverse
            mode) by default, ``diffrax.ForwardMode()`` for ``jax.jacfwd``/``jax.jvp``.

    Python floats among the options (``stiffening``, ``rtol``, …) are compile-time constants;
    pass arrays for values that change between calls, to avoid recompiling.
    """
    require_x64()
    ts = jnp.asarray(ts, dtype=float)
    k = body.n_modes
    if y0 is None:
        y0 = (jnp.zeros(k), jnp.zeros(k))
    args = (body, motion, point_forces, jnp.asarray(gravity, dtype=float),
            jnp.asarray(stiffening, dtype=float))
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(_vector_field),
        diffrax.Tsit5() if solver is None else solver,
        t0=ts[0], t1=ts[-1], dt0=None, y0=y0, args=args,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps, throw=throw,
        adjoint=diffrax.RecursiveCheckpointAdjoint() if adjoint is None else adjoint,
    )
    q, qdot = sol.ys
    return FlexibleResponse(
        ts=ts, q=q, qdot=qdot,
        point_displacements=jnp.einsum("pck,tk->tpc", body.points, q),
        result=sol.result, num_steps=sol.stats["num_accepted_steps"],
    )
