"""Limits, a second integrator, and the autodiff/vmap/jit contract of the flexible-body layer.

* rigid limit: E → ∞ makes the elastic response vanish as 1/E;
* quasi-static limit: a motion 80× slower than the first mode gives the static FE deflection
  under the same (gravity + rigid-motion) loads;
* modal truncation: keeping every mode reproduces the unreduced FE equations, integrated in
  physical coordinates from the assembled matrices;
* scipy's DOP853 on the same right-hand side agrees with diffrax;
* gradients agree with central finite differences; vmap equals a loop; no retracing.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.integrate import solve_ivp

import jaxdobby.flexible_body as flexible_body_module
import jaxdobby.response as response_module
from jaxdobby.beam import Beam
from jaxdobby.centreline import CentreLine
from jaxdobby.examples import krb_beam
from jaxdobby.flexible_body import flexible_body
from jaxdobby.floating_frame import SpinUp, frame_state, rotation_matrix
from jaxdobby.loads import gravity_load, rigid_motion_load
from jaxdobby.modal import modal_basis
from jaxdobby.response import _vector_field, simulate_flexible_body
from jaxdobby.supports import Supports, static_deflection

from compiled import jit_to_run

CLAMP = Supports(clamped=(0,))
GRAVITY = jnp.array([0.0, -9.81])


def curved_beam(n_elements=4, youngs_modulus=7e10):
    line = CentreLine.from_segments([("arc", 10.0, np.pi / 3)])
    b = krb_beam(n_elements)
    return Beam.uniform_mesh(line, n_elements, thickness=b.thickness, depth=b.depth,
                             youngs_modulus=youngs_modulus, density=3000.0)


def test_rigid_limit():
    ts = jnp.linspace(0.0, 3.0, 61)
    peaks = []
    for e in (7e10, 7e12, 7e14):
        body = flexible_body(curved_beam(youngs_modulus=e), CLAMP, 2, points=(10.0 * np.pi / 3,))
        out = simulate_flexible_body(body, SpinUp(jnp.asarray(1.0), jnp.asarray(2.0)), ts,
                                     gravity=GRAVITY)
        peaks.append(float(jnp.max(jnp.abs(out.point_displacements))))
    # Linear elasticity: the deformation scales as 1/E once the motion is quasi-static for the
    # stiffer beams (x100 in E gives 1e-2, within 2 %: residual dynamic amplification and
    # stiffening), and the deviation vanishes in the limit E -> infinity.
    np.testing.assert_allclose(peaks[1] / peaks[0], 1e-2, rtol=0.3)
    np.testing.assert_allclose(peaks[2] / peaks[1], 1e-2, rtol=0.02)
    assert peaks[2] < 1e-3 * peaks[0]


def test_quasi_static_limit():
    # All 9 modes kept (no truncation), 0.5 % damping, slow spin-up: Omega = 0.05 rad/s over
    # T = 200 s while the first mode is 3.8 rad/s. Started from the static solution, the response
    # must track static_deflection(gravity + rigid-motion loads) up to the softening
    # (omega/omega_1)^2 ~ 2e-4 and the damping lag 2 zeta omega/omega_1 ~ 1.3e-4 of the rotating
    # gravity load -> tolerance 1e-3 of the static deflection.
    beam = curved_beam(3)
    n_modes = 9
    body = flexible_body(beam, CLAMP, n_modes, points=(10.0 * np.pi / 3,), damping_ratio=0.005,
                         stiffening=False)
    phi = modal_basis(beam, CLAMP, n_modes).shapes
    motion = SpinUp(jnp.asarray(0.05), jnp.asarray(200.0))

    @jax.jit
    def static(t):
        f = frame_state(motion, t)
        g_body = rotation_matrix(f.angle).T @ GRAVITY
        load = gravity_load(beam, g_body) + rigid_motion_load(beam, f.angular_velocity,
                                                             f.angular_acceleration)
        return static_deflection(beam, CLAMP, load)

    q0 = phi.T @ beam.mass_matrix() @ static(0.0)
    ts = jnp.linspace(0.0, 200.0, 41)
    # The axial modes (~1e3 rad/s) make 200 s stiff for an explicit method: use an implicit one.
    out = simulate_flexible_body(body, motion, ts, gravity=GRAVITY, stiffening=0.0,
                                 y0=(q0, jnp.zeros(n_modes)), solver=diffrax.Kvaerno5(),
                                 rtol=1e-8, atol=1e-10)
    u_static = jax.vmap(static)(ts)
    tip_rows = beam.point_rows(10.0 * np.pi / 3)
    expected = u_static @ tip_rows.T
    np.testing.assert_allclose(out.point_displacements[:, 0, :], expected,
                               atol=1e-3 * float(jnp.max(jnp.abs(expected))))


def full_fe_response(beam, motion, ts, tip):
    """The unreduced equations on all free DOFs, in physical coordinates, with stiffening."""
    free = CLAMP.free_dofs(beam.n_nodes)
    m, m_t = beam.mass_matrix(), beam.translational_mass_matrix()
    k = beam.stiffness_matrix()
    g = beam.gyroscopic_matrix()
    fields = beam.rigid_fields()
    loads = {"centrifugal": m_t @ fields["position"], "euler": m @ fields["rotation"],
             "x": m_t @ fields["x"], "y": m_t @ fields["y"]}
    kg = {c: beam.geometric_stiffness_matrix(beam.element_axial_forces(
        static_deflection(beam, CLAMP, f)))[np.ix_(free, free)] for c, f in loads.items()}
    sub = lambda a: a[np.ix_(free, free)]  # noqa: E731
    m, m_t, k, g = sub(m), sub(m_t), sub(k), sub(g)
    loads = {c: f[free] for c, f in loads.items()}

    def rhs(t, y, args):
        u, v = y
        f = frame_state(motion, t)
        w, a = f.angular_velocity, f.angular_acceleration
        field = rotation_matrix(f.angle).T @ GRAVITY
        kgeo = w**2 * kg["centrifugal"] - a * kg["euler"] + field[0] * kg["x"] + field[1] * kg["y"]
        force = (w**2 * loads["centrifugal"] - a * loads["euler"] + field[0] * loads["x"]
                 + field[1] * loads["y"] - 2 * w * g @ v - (k - w**2 * m_t + a * g + kgeo) @ u)
        return v, jnp.linalg.solve(m, force)

    n = free.size
    sol = diffrax.diffeqsolve(diffrax.ODETerm(rhs), diffrax.Tsit5(), ts[0], ts[-1], None,
                              (jnp.zeros(n), jnp.zeros(n)), saveat=diffrax.SaveAt(ts=ts),
                              stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-12),
                              max_steps=2_000_000)
    return sol.ys[0] @ beam.point_rows(tip)[:, free].T


def test_all_modes_reproduce_the_unreduced_equations():
    def both():  # one program, compiled to run (two adaptive solves at rtol 1e-10)
        beam = curved_beam(3)
        tip = 10.0 * np.pi / 3
        motion = SpinUp(jnp.asarray(6.0), jnp.asarray(5.0))
        ts = jnp.linspace(0.0, 6.0, 61)
        body = flexible_body(beam, CLAMP, 9, points=(tip,))
        reduced = simulate_flexible_body(body, motion, ts, gravity=GRAVITY, rtol=1e-10,
                                         atol=1e-12)
        return reduced.point_displacements[:, 0, :], full_fe_response(beam, motion, ts, tip)

    reduced, full = jit_to_run(both)()
    # Same equations in another basis (modal vs physical, stiffening and gravity included), both
    # solved at rtol 1e-10: agreement to 1e-7 of the peak.
    scale = float(jnp.max(jnp.abs(full)))
    np.testing.assert_allclose(reduced, full, atol=1e-7 * scale)


def test_scipy_solve_ivp_agrees_with_diffrax():
    body = flexible_body(krb_beam(), CLAMP, 4, points=(10.0,))
    motion = SpinUp(jnp.asarray(6.0), jnp.asarray(15.0))
    ts = jnp.linspace(0.0, 20.0, 201)
    ours = simulate_flexible_body(body, motion, ts, rtol=1e-10, atol=1e-12)
    args = (body, motion, None, jnp.zeros(2), jnp.asarray(1.0))
    rhs = jit_to_run(lambda t, y: jnp.concatenate(_vector_field(t, (y[:4], y[4:]), args)))
    sol = solve_ivp(lambda t, y: np.asarray(rhs(t, y)), (0.0, 20.0), np.zeros(8),
                    method="DOP853", t_eval=np.asarray(ts), rtol=1e-11, atol=1e-13)
    tip_scipy = sol.y[:4].T @ np.asarray(body.points[0, 1])
    # Two independent integrators at rtol 1e-10/1e-11: agreement to 1e-7 of the peak deflection.
    tip = ours.point_displacements[:, 0, 1]
    np.testing.assert_allclose(tip, tip_scipy, atol=1e-7 * float(jnp.max(jnp.abs(tip))))


@jax.jit
def rms_tip(params):
    """RMS tip deflection [m] over the KRB spin-up, as a function of (thickness, depth, rate)."""
    thickness, depth, rate = params
    # A 0.5 kg tip mass, so the thickness matters (a uniform beam's modes do not depend on t).
    beam = eqx.tree_at(lambda b: (b.thickness, b.depth, b.point_masses), krb_beam(6),
                       (thickness, jnp.atleast_1d(depth), jnp.zeros(7).at[6].set(0.5)))
    body = flexible_body(beam, CLAMP, 3, points=(10.0,))
    out = simulate_flexible_body(body, SpinUp(rate, jnp.asarray(15.0)),
                                 jnp.linspace(0.0, 20.0, 81), rtol=1e-10, atol=1e-12,
                                 adjoint=diffrax.ForwardMode())
    return jnp.sqrt(jnp.mean(out.point_displacements[:, 0, 1] ** 2))


def test_gradient_matches_finite_differences():
    b = krb_beam(6)
    p0 = jnp.array([float(b.thickness), float(b.depth[0]), 6.0])
    # Three parameters and one output: forward mode (one solve carrying 3 tangents).
    grad = jax.jacfwd(rms_tip)(p0)
    h = 1e-5 * p0
    fd = np.array([(rms_tip(p0.at[i].add(h[i])) - rms_tip(p0.at[i].add(-h[i]))) / (2 * h[i])
                   for i in range(3)])
    # Central differences at h = 1e-5 relative on a solve at rtol 1e-10: truncation ~1e-10,
    # solver noise ~1e-10/1e-5 = 1e-5 relative -> agreement to 1e-4 relative.
    np.testing.assert_allclose(grad, fd, rtol=1e-4)


def test_vmap_equals_loop():
    b = krb_beam(6)
    batch = jnp.array([[float(b.thickness), float(b.depth[0]), r] for r in (4.0, 6.0, 10.0)])
    batched = jax.vmap(rms_tip)(batch)
    looped = jnp.array([rms_tip(p) for p in batch])
    # Each lane keeps its own adaptive steps under vmap: identical up to round-off.
    np.testing.assert_allclose(batched, looped, rtol=1e-10)


def test_entry_points_do_not_retrace(monkeypatch):
    traces = {"simulate": 0, "modes": 0}
    original_field, original_modes = response_module._vector_field, flexible_body_module.modal_basis

    def counting_field(*a):
        traces["simulate"] += 1
        return original_field(*a)

    def counting_modes(*a, **k):
        traces["modes"] += 1
        return original_modes(*a, **k)

    monkeypatch.setattr(response_module, "_vector_field", counting_field)
    monkeypatch.setattr(flexible_body_module, "modal_basis", counting_modes)
    ts = jnp.linspace(0.0, 2.0, 11)
    for thickness, rate in ((0.005, 4.0), (0.006, 5.0), (0.007, 6.0)):
        beam = eqx.tree_at(lambda b: b.thickness, krb_beam(5), jnp.asarray(thickness))
        body = flexible_body(beam, CLAMP, 3, points=(10.0,))
        simulate_flexible_body(body, SpinUp(rate, 15.0), ts)
    # One trace of each entry point for three parameter sets (the vector field is traced a fixed
    # small number of times within one compilation by diffrax; it must not grow per call).
    first = dict(traces)
    beam = eqx.tree_at(lambda b: b.thickness, krb_beam(5), jnp.asarray(0.008))
    simulate_flexible_body(flexible_body(beam, CLAMP, 3, points=(10.0,)), SpinUp(7.0, 15.0), ts)
    assert traces == first and first["modes"] == 1
