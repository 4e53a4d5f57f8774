"""The Gauss–Legendre method's constants (jaxdobby.periodic.collocation), written out as literals
or computed in rational arithmetic so that every CPU traces the same program, held against
NumPy's LAPACK and BLAS, which compute the same quantities independently (in floating point,
with a few units in the last place of their own: hence the tolerances of 1e-14)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from jaxdobby.periodic import collocation as gl


def test_eigen_decomposition_of_the_butcher_matrix():
    lam = np.linalg.eigvals(gl.MATRIX)
    real = lam[np.argmin(np.abs(lam.imag))].real
    cplx = lam[np.argmax(lam.imag)]
    assert abs(gl.GAMMA - real) < 1e-14 * abs(real)
    assert abs(gl.LAMBDA - cplx) < 1e-14 * abs(cplx)
    diag = np.diag([gl.GAMMA, gl.LAMBDA, np.conj(gl.LAMBDA)])
    np.testing.assert_allclose(gl.T @ diag @ gl.T_INV, gl.MATRIX, rtol=0, atol=1e-14)
    np.testing.assert_allclose(gl.T_INV, np.linalg.inv(gl.T), rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(gl.T[:, 2], np.conj(gl.T[:, 1]))
    assert np.all(gl.T[:, 0].imag == 0) and np.max(np.abs(gl.T), axis=0).tolist() == [1, 1, 1]


def test_the_eigenvalues_invert_the_roots_of_the_pade_denominator():
    # the stability function of Gauss-3 is the (3,3) Padé approximant of e^z; the Butcher
    # matrix's eigenvalues are the reciprocals of its poles, the roots of z³ − 12z² + 60z − 120
    roots = np.roots([1.0, -12.0, 60.0, -120.0])
    got = np.sort_complex(np.array([gl.GAMMA, gl.LAMBDA, np.conj(gl.LAMBDA)]))
    np.testing.assert_allclose(got, np.sort_complex(1.0 / roots), rtol=1e-14)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 3), st.integers(1, 3), st.booleans())
def test_exact_product_agrees_with_matmul(rows, cols, cplx):
    rng = np.random.default_rng(rows * 10 + cols + 100 * cplx)
    a = rng.standard_normal((rows, 3)) + (1j * rng.standard_normal((rows, 3)) if cplx else 0)
    b = rng.standard_normal((3, cols))
    np.testing.assert_allclose(gl.exact_product(a, b), a @ b, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(gl.exact_product(a[0], b[:, 0]), a[0] @ b[:, 0], rtol=1e-14,
                               atol=1e-15)


def test_derived_weights():
    np.testing.assert_allclose(gl.MATRIX2, gl.MATRIX @ gl.MATRIX, rtol=1e-15, atol=1e-17)
    np.testing.assert_allclose(gl.WEIGHTS2, gl.WEIGHTS @ gl.MATRIX, rtol=1e-15)
    # the quadratic through the nodes reproduces 1, s and s² at s = 1 + cⱼ
    for power in range(3):
        np.testing.assert_allclose(gl.EXTRAPOLATE @ gl.NODES**power, (1 + gl.NODES)**power,
                                   rtol=1e-14)
