"""The Kane–Ryan–Banerjee spin-up beam (J. Guid. Control Dyn. 10(2), 1987) against an
independent geometrically nonlinear model.

The reference (tests/reference/spinup_vonkarman.py) is a von Kármán finite-element beam in
numpy/scipy with the full rotating-frame inertia of the nodal field and no modal reduction or
geometric-stiffness linearisation, converged in elements (its own tests). jaxdobby's model is the
linear modal one of the floating-frame layer with geometric stiffening; the difference between
the two is a modelling difference that grows with the deflection (0.2 % of the peak at
Ω = 4 rad/s, 0.9 % at 10 rad/s, measured), which sets the tolerances.
"""

import numpy as np
import pytest

from jaxdobby.examples import spin_up_beam
from reference.spinup_vonkarman import KRB_SPINUP_RESULTS, spinup_metrics, tip_deflection


@pytest.mark.parametrize("rate", [4.0, 6.0, 10.0])
def test_spin_up_against_nonlinear_reference(rate):
    ts, tip = spin_up_beam(rate, n_out=3001)
    ours, ref = spinup_metrics(ts, tip), KRB_SPINUP_RESULTS[rate]
    # Peak lag during the spin-up: tens of centimetres, within 1.5 % of the nonlinear model.
    np.testing.assert_allclose(ours["peak"], ref["peak"], rtol=0.015)
    np.testing.assert_allclose(ours["t_peak"], ref["t_peak"], rtol=0.005)
    # Millimetres after the spin-up. The reference shows this amplitude depends on the axial
    # Coriolis load (without it: 2.0-3.0 mm instead of 3.8-6.6), which a modal model of bending
    # modes stiffened by the rigid-motion loads does not carry: agreement to 10 % is the claim.
    assert 1e-3 < ours["amplitude"] < 1e-2
    np.testing.assert_allclose(ours["amplitude"], ref["amplitude"], rtol=0.10)


def test_spin_up_history_matches_reference():
    # The whole history at Omega = 6 rad/s, reference computed here (16 elements, Radau).
    ts, tip = spin_up_beam(6.0, n_out=601)
    ref = tip_deflection(6.0, np.asarray(ts), n_elements=16)
    np.testing.assert_allclose(np.asarray(tip), ref, atol=0.01 * np.max(np.abs(ref)))


@pytest.mark.parametrize("rate", [4.0, 6.0, 10.0])
def test_without_stiffening_the_beam_diverges(rate):
    # The first frequency is 3.80 rad/s < Omega: centrifugal softening wins without the
    # geometric stiffness, and the deflection grows without bound (here: beyond 10 beam lengths).
    _, tip = spin_up_beam(rate, stiffening=False)
    assert not np.all(np.abs(np.asarray(tip)) < 100.0)
