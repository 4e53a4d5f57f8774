"""Modal truncation and stress: mode displacement vs mode acceleration vs the unreduced arm.

A check of the static correction (:mod:`jaxdobby.stress.correction`) on a problem whose
unreduced finite-element solution is exact and cheap: the supported arm of a model (pinned at
the pivot, ring link along its mid-lift direction) as a linear time-invariant structure,

    M ü + C u̇ + K u = f(t),    f(t) = ω²M_t x − αM Sx + M_t Aᵀg + P_linkᵀ F_link(t),

driven by the loads of the model's rigid mechanism over one cycle (the rigid swing's inertia,
gravity and the link-11 force of rigid inverse dynamics) and damped by ζ in *every* mode
(C = MΦ diag(2ζω) ΦᵀM over all modes, so a k-mode model is an exact truncation of it). Its
periodic response is solved harmonic by harmonic, (K − (nΩ)²M + i nΩ C) Uₙ = Fₙ, on all free
DOFs (the unreduced reference) and on k modes, with the stress recovered from Φq (mode
displacement) or from Φq + R f (mode acceleration). This is the one-way model without the
rotating-frame terms: what it isolates is the truncation, which the full dobby model cannot
afford to run unreduced.
"""

from __future__ import annotations

import numpy as np

from ..arm import arm_beam, arm_supports
from ..dobby import DobbyModel, rigid_state
from ..floating_frame import rotation_matrix
from ..modal import modal_basis
from ..supports import supported_stiffness
from .correction import residual_flexibility
from .recovery import stress_operator


def cycle_loads(model: DobbyModel, n_samples: int = 256) -> np.ndarray:
    """Nodal loads f(t) (n_samples, n_dofs) [N, N·m] of the rigid mechanism at t = jT/n."""
    import jax

    machine = model.machine
    beam = arm_beam(machine.arm)
    m, m_t, fields = beam.mass_matrix(), beam.translational_mass_matrix(), beam.rigid_fields()
    rigid_loads = jax.numpy.stack([m_t @ fields["position"], m @ fields["rotation"],
                                   m_t @ fields["x"], m_t @ fields["y"]], axis=1)
    link_rows = beam.point_rows(model.chain.link11_arc_length)
    times = np.arange(n_samples) * float(model.period) / n_samples

    def at(t):
        r = rigid_state(model, t)
        f = r.frame
        field = rotation_matrix(f.angle).T @ np.array([0.0, -float(model.machine.gravity)])
        coeff = jax.numpy.stack([f.angular_velocity**2, -f.angular_acceleration,
                                 field[0], field[1]])
        return rigid_loads @ coeff + link_rows.T @ r.link_force

    return np.asarray(jax.jit(jax.vmap(at))(times))


def dobby_truncation_study(model: DobbyModel, modes=(1, 2, 3, 4, 5, 6, 7, 8),
                           n_samples: int = 256, points_per_element: int = 5) -> dict:
    """:func:`truncation_study` of ``model``'s supported arm under its rigid mechanism's loads."""
    machine = model.machine
    return truncation_study(arm_beam(machine.arm),
                            arm_supports(model.ring_direction_ref, machine.ring_link_stiffness,
                                         machine.arm.ring_joint_node),
                            cycle_loads(model, n_samples), float(model.period),
                            float(machine.damping_ratio), modes, points_per_element)


def truncation_study(beam, supports, loads, period: float, damping_ratio: float,
                     modes=(1, 2, 3, 4, 5, 6, 7, 8), points_per_element: int = 5) -> dict:
    """Peak |σ| over the beam and the cycle [Pa], and the largest stress error over beam and
    cycle relative to that peak, for the unreduced beam and for k modes by mode displacement
    ("md") and mode acceleration ("ma").

    Args:
        beam, supports: the structure; loads: nodal loads at n uniform times over one period
            (n, n_dofs) [N, N·m]; period [s]; damping_ratio: ζ of every mode.

    Returns ``{"modes": [...], "full_peak": float, "md_peak": [...], "ma_peak": [...],
    "md_error": [...], "ma_error": [...]}``.
    """
    free = supports.free_dofs(beam.n_nodes)
    m = np.asarray(beam.mass_matrix())
    k = np.asarray(supported_stiffness(beam, supports))
    everything = modal_basis(beam, supports, free.size)
    phi_all = np.asarray(everything.shapes)
    w_all = np.asarray(everything.frequencies)
    zeta = float(damping_ratio)
    loads = np.asarray(loads)
    n_samples = loads.shape[0]
    f_n = np.fft.rfft(loads, axis=0)  # (n_harmonics, n_dofs)
    n_omega = 2.0 * np.pi / period * np.arange(f_n.shape[0])

    def modal_response(phi, w):
        h = 1.0 / (w[None, :] ** 2 - n_omega[:, None] ** 2 + 2j * zeta * w[None, :]
                   * n_omega[:, None])
        return (f_n @ phi) * h @ phi.T  # (n_harmonics, n_dofs)

    # unreduced: the assembled system, damped in every mode, solved directly per harmonic
    c_full = m @ phi_all @ np.diag(2.0 * zeta * w_all) @ phi_all.T @ m
    u_full = np.zeros_like(f_n)
    ff = np.ix_(free, free)
    for j, w in enumerate(n_omega):
        u_full[j, free] = np.linalg.solve(k[ff] - w**2 * m[ff] + 1j * w * c_full[ff], f_n[j, free])
    stress_op = np.asarray(stress_operator(beam, points_per_element).matrix)

    def stress(u_harmonics):
        return np.fft.irfft(u_harmonics, n=n_samples, axis=0) @ stress_op.T

    full = stress(u_full)
    peak = float(np.abs(full).max())
    out = {"modes": list(modes), "full_peak": peak, "md_peak": [], "ma_peak": [],
           "md_error": [], "ma_error": []}
    for n_modes in modes:
        phi = phi_all[:, :n_modes]
        residual = np.asarray(residual_flexibility(k, free, phi))
        md = stress(modal_response(phi, w_all[:n_modes]))
        ma = md + np.fft.irfft(f_n @ residual.T, n=n_samples, axis=0) @ stress_op.T
        for key, s in (("md", md), ("ma", ma)):
            out[f"{key}_peak"].append(float(np.abs(s).max()))
            out[f"{key}_error"].append(float(np.abs(s - full).max()) / peak)
    return out
