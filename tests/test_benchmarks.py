"""The benchmarks against scipy: the same equations on both sides, and every script's smoke run.

1. The numpy right-hand side of ``benchmarks/scipy_model.py`` (what the scipy side integrates)
   equals ``jaxdobby.dobby.vector_field`` at random states and times, for two machines.
2. The periodic steady state found with ``solve_ivp`` (``benchmarks/scipy_steady.py``) has the
   metrics of ``jaxdobby.simulate`` (Gauss collocation, another integrator and periodic solver).
3. Each benchmark script runs with ``--quick`` in a subprocess and writes its JSON with the
   expected keys and sane values (no timing assertions: the machine is shared), and the README
   generator turns those files (and an unknown one) into markdown.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from benchmarks.scipy_model import METRICS, NumpyDobby, metric_error
from benchmarks.scipy_steady import jitted_problem, steady_state
from jaxdobby import Machine, OperatingPoint
from jaxdobby.dobby import build_model, vector_field
from jaxdobby.simulate import simulate

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("machine, operating", [
    (Machine.default(), OperatingPoint()),
    (Machine.default(n_modes=3, warp_law="opposing"),
     OperatingPoint.from_users_units(speed_rpm=1100.0, warp_force_n=900.0)),
])
def test_numpy_rhs_equals_vector_field(machine, operating):
    # The numpy code re-derives every time-dependent quantity (modulator, loop-closure rates,
    # the chain's curvature term) by hand where jaxdobby uses autodiff; only round-off may
    # differ. Measured <= 6e-13 relative per component (a small acceleration component near a
    # cancellation), ~1e-15 on the largest, so 1e-10 of the largest component is a wide margin
    # that a wrong sign or factor anywhere would break by orders of magnitude.
    model = build_model(machine, operating)
    numpy_model = NumpyDobby.from_model(model)
    k = model.n_modes
    field = jax.jit(lambda t, x: jnp.concatenate(vector_field(t, (x[:k], x[k:]), model)))
    rng = np.random.default_rng(1)
    scale = np.r_[np.full(k, 1e-4), np.full(k, 1e-1)]  # modal displacements and rates
    for _ in range(12):
        t = rng.uniform(0.0, 2.0 * numpy_model.period)  # both picks and the dwells
        x = rng.normal(size=2 * k) * scale
        expected = np.asarray(field(t, x))
        got = numpy_model.rhs(t, x)
        np.testing.assert_allclose(got, expected, rtol=0,
                                   atol=1e-10 * np.max(np.abs(expected)))
    # broadcasting over states (the form solve_ivp's vectorised Jacobian uses)
    xs = rng.normal(size=(2 * k, 3)) * scale[:, None]
    cols = np.stack([numpy_model.rhs(0.03, xs[:, j]) for j in range(3)], axis=1)
    np.testing.assert_allclose(numpy_model.rhs_vectorized(0.03, xs), cols, rtol=1e-13, atol=0)


def test_scipy_steady_state_matches_jaxdobby():
    # scipy's steady state of the benchmark (DOP853 rtol 1e-10, Newton shooting, metrics from
    # its numpy outputs) against jaxdobby's default solve of the same machine (Gauss
    # collocation, 432 steps, the metrics' extremes refined by parabolas) over the same 3001
    # output times: two integrators and two periodic solvers that share only the equations
    # (test_numpy_rhs_equals_vector_field). Collocation agrees with jaxdobby's adaptive Tsit5 at
    # rtol 1e-8 to ≤ 1e-6 (test_dobby, slow), scipy at rtol 1e-10 to far less; tolerance 1e-5, the
    # bar the batch path is held to (measured 6.2e-8). Periodic to 1e-7 on scipy's side: there
    # the chord iteration stalls at the period map's own noise (residuals 1e-9 ... 6e-8 in
    # further iterations at rtol 1e-10, measured 2026-12-02), and a 1e-7 start state moves the
    # metrics by far less than 1e-5. One mode, so that the non-stiff problem is cheap for scipy.
    machine, operating = Machine.default(n_modes=1), OperatingPoint()
    ref = simulate(machine, operating)
    assert bool(ref.converged)
    model = build_model(machine, operating)
    numpy_model = NumpyDobby.from_model(model)
    run = steady_state(jitted_problem(model, numpy_model), "DOP853", 1e-10, 1e-14,
                       np.asarray(ref.series.t), tolerance=1e-7, strategy="newton")
    assert run.converged
    expected = {m: float(ref.metrics[m]) for m in METRICS}
    assert metric_error(run.metrics, expected) < 1e-5, (run.metrics, expected)


def _run(script, tmp_path, *args):
    # as the README runs them: from the repository root, with no PYTHONPATH (the installed
    # package and the scripts' own path to benchmarks/); a persistent compilation cache shared
    # by the scripts' processes and reruns
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["JAXDOBBY_BENCH_CACHE"] = str(ROOT / ".pytest_cache" / "xla")
    p = subprocess.run([sys.executable, str(ROOT / "benchmarks" / script), "--quick", "--out",
                        str(tmp_path), *args], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=900, check=False)
    assert p.returncode == 0, p.stderr[-4000:]
    return p


def _common_keys(data):
    env = data["environment"]
    assert env["float64"] is True
    assert {"jax", "scipy", "numpy"} <= set(env["versions"])
    assert env["device"]["cores_available"] >= 1
    assert isinstance(data["markdown"], str) and "|" in data["markdown"]
    assert data["rows"]


@pytest.mark.slow  # ~50 s of cold processes: a smoke run of the benchmark script, whose
# numbers the default suite checks elsewhere (collocation vs adaptive: test_dobby)
def test_bench_simulate_quick(tmp_path):
    _run("bench_simulate.py", tmp_path)
    data = json.loads((tmp_path / "simulate_quick.json").read_text())
    _common_keys(data)
    assert data["cold"]["quick"]["total_s"] > 0 and data["cold"]["quick"]["converged"]
    (jax_default,) = data["jaxdobby"]
    assert jax_default["converged"] and jax_default["median_s"] > 0
    # the default (collocation) path is accurate (~1e-6 against the adaptive reference; loose
    # bound: the quick reference is itself at smoke tolerances)
    assert jax_default["error"] < 1e-3
    assert {r["method"] for r in data["scipy"]} == {"RK45", "Radau"}
    assert {r["rhs"] for r in data["scipy"]} == {"numpy", "jitted"}
    for r in data["scipy"]:
        assert r["converged"] and r["median_s"] > 0 and 0 <= r["error"] < 1e-2
    assert (tmp_path / data["figure"]).stat().st_size > 1000


@pytest.mark.slow  # ~1 min on 2 cores (56 s, 2026-12-06): 2 processes compile the batch path
# beside the scipy runs and 4 pool workers the model build; scipy needs ~5 s per sample at 1 mode
def test_bench_batch_quick(tmp_path):
    pytest.importorskip("jaxdobby.periodic")
    _run("bench_batch.py", tmp_path)
    data = json.loads((tmp_path / "batch_quick.json").read_text())
    _common_keys(data)
    assert data["sane"]
    assert set(data["jaxdobby"]) == {"1", "2"}
    # two cores as two host devices of one process (shard_map), the script's default since the
    # throughput benchmark measured it faster than two processes (1155 against 986 samples/s)
    assert data["two_cores"] == "devices" and data["jaxdobby"]["2"]["devices"] == 2
    for k in ("1", "2"):
        for size in data["jaxdobby"][k]["sizes"]:
            assert size["ok_fraction"] == 1.0 and size["samples_per_s"] > 0
    assert data["scipy_pool_numpy"]["workers_seen"] == 2
    for r in data["rows"]:
        assert r["speedup_vs_serial_numpy"] > 0
    assert data["accuracy"]["jaxdobby_batch_max_error"] < 1e-3


@pytest.mark.slow  # compiling forward mode through the shooting takes minutes on 2 cores
def test_bench_gradient_quick(tmp_path):
    _run("bench_gradient.py", tmp_path)
    data = json.loads((tmp_path / "gradient_quick.json").read_text())
    _common_keys(data)
    assert len(data["jaxdobby"]["gradient_8"]["value"]) == 8
    # autodiff and scipy's central difference of the same metric agree: truncation of the
    # relative step 1e-4 ~1e-4 (the deviation is curved in thickness), scipy's periodic
    # residual 1e-8 over the step ~2.5e-4 (measured 8.7e-4); 1e-2 leaves the margin of a smoke run
    assert data["derivative_thickness"]["relative_difference"] < 1e-2


@pytest.mark.slow  # ~10 s: four fresh processes of the command line
def test_commands_cold_quick(tmp_path):
    _run("commands_cold.py", tmp_path)
    data = json.loads((tmp_path / "commands_cold_quick.json").read_text())
    _common_keys(data)
    assert [r["command"] for r in data["rows"]] == ["jaxdobby simulate", "jaxdobby beam"]
    for r in data["rows"]:
        assert r["exit_codes"] == [0, 0] and r["cold_s"] > 0 and r["cached_s"] > 0


def test_make_readme_reads_results_generically(tmp_path):
    from benchmarks.make_readme import build

    (tmp_path / "gradient_cost.json").write_text(json.dumps(
        {"date": "2026-01-01", "rows": [{"case": "thickness", "ratio": 2.5}]}))
    (tmp_path / "sobol_throughput.json").write_text(json.dumps(
        {"markdown": "| a | b |\n|---|---|\n| 1 | 2 |"}))
    (tmp_path / "odd.json").write_text("[1, 2]")
    (tmp_path / "broken.json").write_text("{")
    (tmp_path / "simulate_quick.json").write_text(json.dumps({"markdown": "QUICK"}))
    text = build(tmp_path)
    assert "| case | ratio |" in text and "| thickness | 2.5 |" in text
    assert "| a | b |" in text
    assert "odd.json" in text and "broken.json" in text
    assert "QUICK" not in text
    assert "How to rerun" in text


@pytest.mark.slow  # compiles the batch path five times (~5 min on 2 cores)
def test_batch_profile_quick(tmp_path):
    _run("batch_profile.py", tmp_path)
    data = json.loads((tmp_path / "batch_profile_quick.json").read_text())
    assert data["environment"]["float64"] is True
    assert all(v > 0 for v in data["per_sample_ms"].values())
    assert sum(data["cycles_histogram"]) == data["chunk"] == 8
    # the rounds integrate at most what a vmapped while loop would
    assert data["cycles_needed"] <= data["cycles_vmapped_while"]
