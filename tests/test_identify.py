"""``jaxdobby identify``: twin experiments, the covariance against finite differences, an
unidentifiable pair, the interpolation, and bad input.

A twin experiment makes a measured-like trace with the model itself (chosen parameters, white
noise, an arbitrary time origin and position zero) and fits it from the default machine.

Two sizes of the model share the work:

* the default suite fits a small model (2 modes of the arm, 144 collocation steps per cycle,
  one start: the fixture ``small``), whose steady-cycle program compiles in well under a
  minute; its twin experiment and the exact Jacobian against finite differences are default
  tests (the twin is made by the same small model, so the claims are those of the method);
* the full-size model (4 modes, 432 steps, two starts: the fixture ``fitted``) takes minutes to
  compile on two cores: its tests are marked slow (run them with ``-m slow``), as is the
  coverage study over repeated noise draws.

Every test of a size shares one compiled program: the fit of (heald_frame_mass_kg,
damping_ratio) with that many starts (the twin traces go through it too, see
:func:`jaxdobby.identify.twin.model_trace`).
"""

import json

import jax.numpy as jnp
import numpy as np
import pytest

from jaxdobby.cli import main
from jaxdobby.config import RunOptions, load, to_toml
from jaxdobby.identify import identify, synthetic
from jaxdobby.identify.measurement import Measurement, to_csv
from jaxdobby.identify.model import MM, fourier, interpolate, parameterisation
from jaxdobby.identify.twin import model_trace
from jaxdobby.identify.uncertainty import covariance, summarise
from jaxdobby.parameters import PARAMETERS, Setup, apply

KEYS = ("heald_frame_mass_kg", "damping_ratio")
LANES = 2
TRUE = {"heald_frame_mass": 13.0, "damping_ratio": 0.03}
NOISE = dict(noise_acceleration=5.0, noise_position_mm=0.05)
"""About 1 % of the acceleration's RMS and 0.1 % of the stroke: a good accelerometer and a
laser displacement sensor."""
TWIN = dict(phase=0.37, offset_mm=3.0, start_s=17.25, cycles=2.0, rate_hz=4000.0)


SMALL_OPTIONS = RunOptions(steps=144)
"""The small model of the default suite: 144 collocation steps per cycle (with 2 modes)."""


def small_setup():
    """The default machine with 2 modes of the arm kept (the small model)."""
    import dataclasses

    import equinox as eqx

    setup = Setup()
    return eqx.tree_at(lambda s: s.machine, setup, dataclasses.replace(setup.machine, n_modes=2))


def twin(seed, **kw):
    true = apply(Setup(), TRUE)
    return synthetic(true, **(TWIN | NOISE | kw), seed=seed, keys=KEYS, lanes=LANES)


class Fit:
    """A twin experiment of one model size: the measurement, the fit, and how it was made."""

    def __init__(self, setup, options, lanes, seed=0):
        self.setup, self.options, self.lanes = setup, options, lanes
        self.meas = synthetic(apply(setup, TRUE), **(TWIN | NOISE), seed=seed, keys=KEYS,
                              lanes=lanes, options=options)
        self.res = identify(setup, self.meas, KEYS, starts=lanes, options=options)

    def trace(self, setup, phase):
        """Model (acceleration, position) at the measured times through the shared program."""
        return model_trace(setup, self.meas.time, phase, self.options, keys=KEYS,
                           lanes=self.lanes)


@pytest.fixture(scope="module")
def small():
    return Fit(small_setup(), SMALL_OPTIONS, lanes=1)


@pytest.fixture(scope="module")
def full():
    return Fit(Setup(), None, lanes=LANES)


@pytest.fixture(scope="module")
def fitted(full):
    return full.meas, full.res


def _check_twin(meas, res):
    """The claims of a twin experiment (see the test below)."""
    assert res.converged and not res.warnings
    for key, name in zip(KEYS, TRUE):
        est, se = res.estimates[key], res.standard_errors[key]
        # the claim: the truth lies within 3 reported standard errors (a single draw; the
        # coverage of ±2σ over many draws is the slow test) and the errors are small enough
        # (< 3 %) for the claim to mean something
        assert abs(est - TRUE[name]) < 3 * se, (key, est, se)
        assert se < 0.03 * TRUE[name]
    assert abs((res.phase - TWIN["phase"] + 0.5) % 1.0 - 0.5) < 3 * res.phase_error
    assert abs(res.position_offset / MM - TWIN["offset_mm"]) < 0.01
    # the residuals are the noise: RMS within 10 % of the added standard deviations
    # (2400 samples: the RMS of white noise scatters by ~1.5 %)
    np.testing.assert_allclose(res.residual_rms["acceleration_m_s2"],
                               NOISE["noise_acceleration"], rtol=0.1)
    np.testing.assert_allclose(res.residual_rms["position_mm"], NOISE["noise_position_mm"],
                               rtol=0.1)


def test_small_twin_experiment_recovers_the_parameters_within_their_errors(small):
    _check_twin(small.meas, small.res)


def test_small_twin_with_the_accelerometer_alone(small):
    """One channel: no position offset to fit (its Jacobian column is zero; the inner step
    must leave it, not fail); the same program as the two-channel fit."""
    meas = synthetic(apply(small.setup, TRUE), **(TWIN | NOISE), seed=0, keys=KEYS, lanes=1,
                     options=small.options, channels=("acceleration",))
    res = identify(small.setup, meas, KEYS, starts=1, options=small.options)
    assert res.converged and not res.warnings and res.position_offset is None
    for key, name in zip(KEYS, TRUE):
        # 3σ as the two-channel fit; without the position channel the errors grow (~40 %)
        assert abs(res.estimates[key] - TRUE[name]) < 3 * res.standard_errors[key], key
        assert res.standard_errors[key] < 0.03 * TRUE[name]
    np.testing.assert_allclose(res.residual_rms["acceleration_m_s2"],
                               NOISE["noise_acceleration"], rtol=0.1)


@pytest.mark.slow  # the shared twin fit: minutes to compile on 2 cores
def test_twin_experiment_recovers_the_parameters_within_their_errors(full):
    _check_twin(full.meas, full.res)


def _fd_jacobian(res, meas, h=1e-5, trace_of=None):
    """Columns dr/dz (central differences of the model through new steady states), dr/dφ and
    dr/db for the weighted residuals of ``res`` at its estimate."""
    n = meas.time.size
    weights = 1.0 / np.asarray(res.sigma)  # the fit's channel weights
    cols = []

    def trace(setup, phase):
        acc, pos = trace_of(setup, phase)
        return np.concatenate([acc * weights[0], (pos / MM) * weights[1]])

    for key, name in zip(KEYS, TRUE):
        theta = res.estimates[key]
        plus = trace(apply(res.setup, {name: theta * np.exp(h)}), res.phase)
        minus = trace(apply(res.setup, {name: theta * np.exp(-h)}), res.phase)
        cols.append((plus - minus) / (2 * h))
    hp = 1e-7
    cols.append((trace(res.setup, res.phase + hp) - trace(res.setup, res.phase - hp)) / (2 * hp))
    cols.append(np.concatenate([np.zeros(n), np.full(n, weights[1])]))
    return np.stack(cols, axis=1)


def _check_jacobian(fit: Fit):
    meas, res = fit.meas, fit.res
    n = meas.time.size
    size = res.jacobian.shape[0] // 2
    jac = np.concatenate([res.jacobian[:n], res.jacobian[size:size + n]])
    fd = _fd_jacobian(res, meas, trace_of=fit.trace)
    # central differences with h = 1e-5 in ln θ: truncation ~h² ≈ 1e-10, the steady state's
    # periodicity tolerance 1e-9 over 2h: ~1e-4 of a column's scale at most
    for i in range(jac.shape[1]):
        scale = np.max(np.abs(fd[:, i]))
        np.testing.assert_allclose(jac[:, i], fd[:, i], atol=2e-4 * scale, err_msg=str(i))
    r = np.zeros(jac.shape[0])
    r[0] = 1.0
    c_exact = covariance(jac, r, jac.shape[0])
    c_fd = covariance(fd, r, jac.shape[0])
    np.testing.assert_allclose(np.sqrt(np.diag(c_exact)), np.sqrt(np.diag(c_fd)), rtol=1e-3)


def test_small_jacobian_and_covariance_match_finite_differences(small):
    _check_jacobian(small)


@pytest.mark.slow  # the shared twin fit: minutes to compile on 2 cores
def test_jacobian_and_covariance_match_finite_differences(full):
    _check_jacobian(full)


@pytest.mark.slow  # the shared twin fit: minutes to compile on 2 cores
def test_the_product_modulus_times_area_is_flagged_not_identifiable(fitted):
    """Only E·A of the ring link enters the model (its stiffness): their columns in ln θ are
    equal, JᵀJ singular, and both must be flagged, with standard errors beyond the estimates."""
    meas, res = fitted
    keys = ("ring_link_modulus_pa", "ring_link_area_mm2")
    names = [PARAMETERS[n].name for n in ("ring_link_modulus", "ring_link_area")]
    par = parameterisation(res.setup, keys)
    h = 1e-4
    n = meas.time.size
    cols = []
    for name in names:
        theta = float(PARAMETERS[name].get(res.setup))
        tr = [model_trace(apply(res.setup, {name: theta * np.exp(s)}), meas.time, res.phase,
                          keys=KEYS, lanes=LANES) for s in (h, -h)]
        cols.append(np.concatenate([(tr[0][0] - tr[1][0]), (tr[0][1] - tr[1][1]) / MM]) / (2 * h))
    size = n
    acc, pos = model_trace(res.setup, meas.time, res.phase + 1e-7, keys=KEYS, lanes=LANES)
    acc0, pos0 = model_trace(res.setup, meas.time, res.phase - 1e-7, keys=KEYS, lanes=LANES)
    cols.append(np.concatenate([acc - acc0, (pos - pos0) / MM]) / 2e-7)
    cols.append(np.concatenate([np.zeros(n), np.ones(n)]))
    jac = np.stack(cols, axis=1)
    rng = np.random.default_rng(1)
    r = rng.standard_normal(2 * n)
    u = np.zeros(4)
    out = summarise(res.setup, meas, par, u, r, jac, (1.0, 1.0), size, True, np.zeros(1))
    # finite differences leave the two columns equal to ~1e-5, not exactly: the standard
    # errors are then huge rather than infinite — at least the estimates themselves
    assert all(not out.standard_errors[k] < out.estimates[k] for k in keys), out.standard_errors
    assert any("not identifiable" in w and keys[0] in w for w in out.warnings)
    assert any("not identifiable" in w and keys[1] in w for w in out.warnings)
    # the identifiable pair of the twin fit is not flagged
    assert not res.warnings


def test_trigonometric_interpolation_is_exact_for_a_band_limited_trace():
    n = 64
    t = np.arange(n) / n
    f = lambda x: np.cos(2 * np.pi * 3 * x + 0.4) + 0.5 * np.sin(2 * np.pi * 31 * x)  # noqa
    x = np.random.default_rng(0).uniform(-3.0, 7.0, 50)
    # harmonics below n/2 are reproduced to rounding at any (also far, negative) phase
    np.testing.assert_allclose(interpolate(fourier(jnp.asarray(f(t))), jnp.asarray(x)), f(x),
                               atol=1e-12)


@pytest.mark.slow  # the shared twin fit: minutes to compile on 2 cores
def test_model_trace_interpolation_error_is_far_below_the_noise(fitted):
    """The steady cycle interpolated from every other grid point against the points left out:
    the interpolation error of the full grid is smaller still (spectral convergence)."""
    from jaxdobby.identify.model import cycle_grids, solver_settings

    setup = Setup()
    method, steps = solver_settings(setup, None)
    par = parameterisation(setup, KEYS)
    _, grid, _ = cycle_grids(setup, par.names, par.log, method, steps, np.zeros((LANES, 2)))
    g = np.asarray(grid[0])
    n = g.shape[1]
    half = interpolate(fourier(jnp.asarray(g[:, ::2])), jnp.asarray(np.arange(1, n, 2) / n))
    err = np.max(np.abs(np.asarray(half) - g[:, 1::2]), axis=1)
    # 5 % of the twin's noise (5 m/s², 0.05 mm) at half the grid
    assert err[0] < 0.25 and err[1] < 2.5e-3, err


def _write(tmp_path, meas, name="trace.csv"):
    path = tmp_path / name
    path.write_text(to_csv(meas))
    return str(path)


@pytest.mark.slow  # the shared twin fit: minutes to compile on 2 cores
def test_cli_json_and_outputs(fitted, tmp_path, capsys):
    """The command on the twin trace, started from the in-process estimate (a configuration
    file, both starts there: the fit then converges in a few steps) must return that
    estimate."""
    meas, res = fitted
    out = tmp_path / "out"
    start = tmp_path / "start.toml"
    start.write_text(to_toml(res.setup))
    code = main(["identify", _write(tmp_path, meas), "--speed", "800", "--fit", *KEYS,
                 "--config", str(start), "--starts", str(LANES), "--spread", "0", "--json",
                 "--out", str(out)])
    printed = json.loads(capsys.readouterr().out)
    assert code == 0
    assert {"estimates", "standard_errors", "correlation", "residual_rms", "phase_deg",
            "converged"} <= set(printed)
    # the CSV holds the samples to 17 digits: the same minimum, to the optimiser's tolerance
    # (a relative step of 1e-7) and far inside the standard errors
    for key in KEYS:
        np.testing.assert_allclose(printed["estimates"][key], res.estimates[key], rtol=1e-5)
        np.testing.assert_allclose(printed["standard_errors"][key], res.standard_errors[key],
                                   rtol=1e-3)
    np.testing.assert_allclose(printed["phase_deg"], 720.0 * res.phase, atol=1e-4)
    assert (out / "identify.json").exists() and (out / "identify_fit.png").exists()
    # the warnings list holds the fit's entries and the identified machine's validity
    # warnings, those simulate gives identified.toml (same codes; the fit's own are not)
    assert main(["simulate", "--config", str(out / "identified.toml"), "--json"]) == 0
    rerun = json.loads(capsys.readouterr().out)
    fit_codes = {"not_identifiable", "at_bound", "fit_not_converged", "fit"}
    assert ([w["code"] for w in printed["warnings"] if w["code"] not in fit_codes]
            == [w["code"] for w in rerun["warnings"]])
    # identified.toml goes through the configuration parser of `simulate --config` (every key
    # and range checked) and holds the estimates; the run itself is in the slow test below
    setup, _ = load(out / "identified.toml")
    for key, name in zip(KEYS, TRUE):
        np.testing.assert_allclose(float(PARAMETERS[name].get(setup)),
                                   printed["estimates"][key], rtol=1e-12)


@pytest.mark.slow
def test_identified_toml_runs_through_simulate(fitted, tmp_path, capsys):
    from jaxdobby.identify.report import summary, write

    meas, res = fitted
    write(tmp_path, meas, res, summary(res), figures=False)
    assert main(["simulate", "--config", str(tmp_path / "identified.toml"), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["converged"]


def test_fit_warnings_are_named_entries_of_the_warnings_list():
    # the lines uncertainty.summarise writes (its texts), as entries of the shared list
    from jaxdobby.identify.report import fit_warning_entries

    lines = ["heald_frame_mass_kg is on a bound of its range: its estimate and standard error "
             "are not those of an interior minimum",
             "not identifiable: damping_ratio (standard error 3 against the estimate 0.02) is "
             "not determined by this trace",
             "not identifiable: a and b are correlated +0.9999: this trace fixes a combination "
             "of the two, not each",
             "the optimiser did not converge: the estimates are its last iterate"]
    got = fit_warning_entries(lines)
    assert [w["code"] for w in got] == ["at_bound", "not_identifiable", "not_identifiable",
                                        "fit_not_converged"]
    assert all(set(w) == {"code", "message", "value", "limit"} for w in got)
    assert [w["message"] for w in got] == lines


BAD = [
    ("time_s,other\n0,1\n", "heald_frame_acceleration_m_s2"),
    ("time_s,heald_frame_position_mm\n0,1\n0.002,2\n0.001,3\n", "increase strictly"),
    ("time_s,heald_frame_position_mm\n0,1\n0.001,2\n0.003,3\n", "uniformly sampled"),
    ("time_s,heald_frame_position_mm\n0,1\n0.001,nan\n0.002,3\n", "NaN"),
    ("time_s,heald_frame_position_mm\n0,1\n0.001,2\n0.002,3\n", "less than one heald-frame"),
]


@pytest.mark.parametrize("text, words", BAD)
def test_bad_trace_is_one_line_exit_2(tmp_path, capsys, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    code = main(["identify", str(path), "--fit", "heald_frame_mass_kg"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and words in err, err


@pytest.mark.parametrize("key, words", [("heald_frame_mass", None), ("n_modes", "integer"),
                                        ("mass_kg", "unknown parameter"),
                                        ("depth_mm", "list parameter"),
                                        ("speed_rpm", "not fitted")])
def test_bad_parameter_is_one_line_exit_2(tmp_path, capsys, key, words):
    if words is None:  # a registry name is accepted as well as its key: go on to a bad bound
        args = ["--bounds", "heald_frame_mass=5:1"]
        words = "LOW must be < HIGH"
    else:
        args = []
    t = np.arange(0, 0.2, 1e-3)
    path = _write(tmp_path, Measurement(t, position=np.sin(t)))
    code = main(["identify", path, "--fit", key, *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and words in err, err


@pytest.mark.slow
def test_coverage_of_two_sigma_over_noise_draws():
    """Over repeated noise draws the truth lies within ±2 reported σ about 95 % of the time
    (the Gauss–Newton covariance is honest). 40 draws × 2 parameters: a binomial 95 % count
    has standard deviation ~2.4 %; accept 85…100 %."""
    hits = []
    for seed in range(1, 41):
        meas = twin(seed)
        res = identify(Setup(), meas, KEYS, starts=LANES)
        assert res.converged
        hits += [abs(res.estimates[k] - TRUE[n]) < 2 * res.standard_errors[k]
                 for k, n in zip(KEYS, TRUE)]
        print(f"draw {seed}: " + " ".join(  # progress of a long run (pytest -s)
            f"{k} {(res.estimates[k] - TRUE[n]) / res.standard_errors[k]:+.2f}σ"
            for k, n in zip(KEYS, TRUE)), flush=True)
    assert 0.85 <= np.mean(hits) <= 1.0, np.mean(hits)
