"""Stored programs (jaxdobby.programs): what the command line runs through them is what
simulate computes, and the package's shipped programs of the default configuration are
current."""

import functools
import importlib

import equinox as eqx
import jax
import numpy as np
import pytest

from jaxdobby import programs
from jaxdobby.config import RunOptions
from jaxdobby.parameters import Setup
from jaxdobby.sensitivity.batch import chunk_key
from jaxdobby.sensitivity.command import SHIPPED_DEVICES, default_study_program
from jaxdobby.simulate import report_programs, simulate, stored_report, summary


@pytest.fixture(scope="module")
def default_setup():
    return Setup()


def test_shipped_program_of_the_default_configuration_is_current(default_setup):
    """The first `jaxdobby simulate` with an empty cache skips tracing only if the package ships
    the default configuration's program for the current sources (their fingerprint is part of
    its key). After a change of jaxdobby's code: `python -m jaxdobby.programs` makes it anew."""
    (name, run, args, static_key), (report_name, _, report_key) = report_programs(
        default_setup, RunOptions())
    # the report's arguments are the run's outputs (read from the shipped run program, or
    # traced anew if it is stale)
    leaves = [jax.ShapeDtypeStruct(a.shape, a.dtype) for a in programs.stored_program(
        name, run, args, static_key=static_key, directory=None).out_avals]
    _, sobol, share = default_study_program()
    for key in (programs.program_key(name, static_key, args),
                programs.program_key(report_name, report_key, leaves),
                programs.program_key(sobol.name, sobol.static_key, [share])):
        assert (programs.SHIPPED / key).exists(), (
            f"the shipped program {key} is stale: run `python -m jaxdobby.programs` and "
            "commit jaxdobby/data/programs")
    # jaxdobby optimize's three (values, the scan of its starts, the gradient): the
    # evaluator reads each from the shipped ones, or traces it if it is stale
    for _, _, _, file in optimize_programs():
        assert (programs.SHIPPED / file).exists(), (
            f"the shipped program {file} is stale: run `python -m jaxdobby.programs` and "
            "commit jaxdobby/data/programs")
    # jaxdobby loom's batch of a weave of 4 picks on 8 frames (twill22, twill31, basket22)
    file = loom_program()[2]
    assert (programs.SHIPPED / file).exists(), (
        f"the shipped program {file} is stale: run `python -m jaxdobby.programs` and commit "
        "jaxdobby/data/programs")
    assert len(list(programs.SHIPPED.glob("*.jaxexport"))) == 7


def loom_program(argv=("loom", "--weave", "twill22")):
    """(exported, specs, file name) of the first batch of the ``jaxdobby loom`` command line
    ``argv`` (parsed as the command parses it)."""
    from jaxdobby.cli import build_parser
    from jaxdobby.command_line import setup_from_args
    from jaxdobby.weave.command import _plan, _strokes_mm
    from jaxdobby.weave.loom import frames_program

    ns = build_parser().parse_args(list(argv))
    setup, _ = setup_from_args(ns)
    plan, _ = _plan(ns)
    return frames_program(setup.machine, setup.operating, plan,
                          _strokes_mm(ns, plan.shape[1]) * 1e-3)


@pytest.mark.parametrize("argv", [
    ("loom", "--weave", "twill31", "--speed", "1200", "--front-stroke", "100"),
    ("loom", "--weave", "basket22", "--frames", "8", "--strokes", *["90"] * 8),
])
def test_weaves_of_four_picks_on_eight_frames_share_the_shipped_loom_program(argv):
    # the program depends on the picks and the moving frames, not on the plan, the speed or
    # the strokes (arrays: the program's inputs)
    assert loom_program(argv)[2] == loom_program()[2]


@functools.cache
def optimize_evaluator():
    """The evaluator of a plain `jaxdobby optimize` and its study (compiling, or loading, only
    the values the evaluator starts with)."""
    from jaxdobby.optimize.command import default_evaluator

    return default_evaluator()


def optimize_programs():
    """(exported, specs, options, file name) of a plain `jaxdobby optimize`'s programs."""
    evaluator, study = optimize_evaluator()
    return evaluator.programs(study.starts)


def test_shipped_executables_of_the_default_configuration_are_current(default_setup):
    """The first `jaxdobby simulate` and default `jaxdobby sobol` on a 2-core x86-64 CPU skip
    XLA's compilation only if the package ships their compiled executables for the current
    programs (the programs' text is part of their key): `python -m jaxdobby.programs`."""
    (name, run, args, static_key), (report_name, report, report_key) = report_programs(
        default_setup, RunOptions())
    run_p = programs.stored_program(name, run, args, static_key=static_key, directory=None)
    leaves = [jax.ShapeDtypeStruct(a.shape, a.dtype) for a in run_p.out_avals]
    report_p = programs.stored_program(report_name, report, leaves, static_key=report_key,
                                       directory=None)
    keys = programs.together_keys([(run_p, args), (report_p, leaves)], programs.ONE_SHOT)
    fn, sobol, share = default_study_program()
    exported = programs.stored_program(sobol.name, fn, [share], static_key=sobol.static_key,
                                       directory=None)
    two_cpus = [jax.devices("cpu")[0]] * SHIPPED_DEVICES  # the key reads their count and kind
    keys.append(chunk_key(sobol, exported, share, two_cpus))
    for program, specs, options, _ in optimize_programs():
        keys += programs.together_keys([(program, specs)], options)
    program, specs, _ = loom_program()
    keys += programs.together_keys([(program, specs)], programs.ONE_SHOT)
    for key in keys:
        assert key is not None and programs.executable_variants(key), (
            f"the shipped executable {key} is stale: run `python -m jaxdobby.programs` and "
            "commit jaxdobby/data/programs")
    # every shipped file is a variant of a current key (a stale one would be dead weight),
    # named after the features it records
    stems = {key.removesuffix(".xlaexe") for key in keys}
    for path in programs.SHIPPED.glob("*.xlaexe"):
        stem, tag, _ = path.name.split(".")
        assert stem in stems, f"{path.name} is stale: delete it"
        assert path.name == programs._variant_name(stem, programs.variant_features(path))
        # no feature its code cannot use is required of the CPU that loads it
        assert not programs.variant_features(path) & programs.SYSTEM_FEATURES, path.name
    for stem in stems:  # and none needs more features than another variant of its program
        # built under the same instruction-set cap (an AVX-512 chunk beside the AVX2 one)
        features = list(map(programs.variant_features, programs.executable_variants(stem)))
        assert not any(a < b and programs.isa_level(a) == programs.isa_level(b)
                       for a in features for b in features), stem


def test_the_variant_of_the_most_features_that_fits_is_loaded(monkeypatch):
    """Where an AVX-512 and an AVX2 variant of the Sobol chunk both fit the CPU, the AVX-512
    one is loaded (its loops are the batch's lanes: 512-bit vectors pay); on a CPU without
    AVX-512 the AVX2 one. Checked through the loader on the variants' own feature sets."""
    from jax.experimental import serialize_executable

    wide = [p for p in programs.SHIPPED.glob("sobol-dobby-chunk-*.xlaexe")
            if programs.isa_level(programs.variant_features(p)) == programs.WIDE_ISA]
    if not wide:
        pytest.skip("no AVX-512 chunk variant ships (shipped from a CPU without AVX-512)")
    key = wide[0].name.split(".")[0] + ".xlaexe"
    variants = {programs.isa_level(programs.variant_features(p)): p
                for p in programs.executable_variants(key)}
    loaded = []
    monkeypatch.setattr(serialize_executable, "deserialize_and_load",
                        lambda serialized, *a, **k: loaded.append(
                            programs.isa_level(programs.compiled_features(serialized))) or "x")
    for host, expected in [(variants[programs.WIDE_ISA], programs.WIDE_ISA),
                           (variants[programs.EXECUTABLE_ISA], programs.EXECUTABLE_ISA)]:
        monkeypatch.setattr(programs, "host_features",
                            lambda host=host: programs.variant_features(host))
        assert programs._load_first_fitting(key, None) == "x"
        assert loaded[-1] == expected


def test_system_features_are_marked_off_and_nothing_else_changes():
    """without_system_features flips exactly the recorded '+feature' entries named in
    SYSTEM_FEATURES to '-feature' (so a serialised executable keeps its length and framing),
    leaves every other byte as it was, and is idempotent."""
    record = b"+64bit,+avx2,-avx512f,+pku,+sse4a,+wbnoinvd,+rtm,-xsaves,+fma,+prefer-no-gather"
    blob = b"\x08\x02head" + record + b"\x12\x04tail+pku"
    out = programs.without_system_features(blob)
    assert len(out) == len(blob) and out.endswith(b"tail+pku")  # outside the record: untouched
    assert programs.compiled_features(out) == {"64bit", "avx2", "sse4a", "fma"}
    assert programs.compiled_features(blob) - programs.compiled_features(out) == {
        "pku", "wbnoinvd", "rtm", "prefer-no-gather"}
    assert programs.without_system_features(out) == out
    assert programs.without_system_features(b"no record") == b"no record"


def test_stored_report_equals_simulate_and_is_reused(tmp_path, default_setup, monkeypatch,
                                                     capfd):
    """stored_report (an exported program, stored, then read back by a second call with other
    float values) against simulate() and summary() run directly on the same inputs: the same
    computation, but the stored program is compiled at LLVM level 0 (programs.ONE_SHOT) and
    simulate at JAX's default level, which round differently (fused multiply-adds); the periodic
    solve amplifies round-off of its 432-step cycle map by ‖(I − Φ)⁻¹‖, so equal to 1e-10
    relative (measured ≤ 1.0e-12). A stale key (other
    sources) must not find the stored file."""
    monkeypatch.setattr(programs, "SHIPPED", tmp_path / "shipped")  # none shipped
    first, _, _ = stored_report(default_setup, RunOptions(), directory=tmp_path)
    stored = sorted(tmp_path.glob("*.jaxexport"))
    assert len(stored) == 2  # the run and its report
    slower = Setup(operating=default_setup.operating.__class__.from_users_units(speed_rpm=600.0))
    got, series, stress = stored_report(slower, RunOptions(), directory=tmp_path)
    assert sorted(tmp_path.glob("*.jaxexport")) == stored  # read back, not exported anew
    run = simulate(slower.machine, slower.operating)
    want = summary(run)
    for key, value in want.items():
        if key == "periodicity_residual":
            # ‖F(x) − x‖/‖x‖ ≈ 5e-11 is itself near round-off: F is 432 collocation steps, whose
            # rounding (≈ 432 × 2.2e-16 ≈ 1e-13 of ‖x‖, amplified by the cycle's response)
            # differs between the two compilations (measured 1.2e-13)
            assert got[key] == pytest.approx(value, rel=0, abs=1e-12), key
        elif isinstance(value, float) or (isinstance(value, list) and value
                                         and all(isinstance(v, float) for v in value)):
            assert got[key] == pytest.approx(value, rel=1e-10, abs=1e-300), key
        elif key == "warnings":  # (code, message, value, limit): values to round-off
            assert [w["code"] for w in got[key]] == [w["code"] for w in value]
            for a, b in zip(got[key], value):
                assert a["value"] == pytest.approx(b["value"], rel=1e-10), a["code"]
        else:
            assert got[key] == value, key
    np.testing.assert_allclose(series.deviation, run.series.deviation, rtol=0,
                               atol=1e-10 * float(np.ptp(run.series.deviation)))
    assert float(stress.metrics["stress_max"]) * 1e-6 == pytest.approx(got["stress_max_mpa"])
    assert first["speed_rpm"] == pytest.approx(800.0) and got["speed_rpm"] == pytest.approx(600.0)
    monkeypatch.undo()  # the package's shipped programs and executables again
    if not programs.executables_usable():
        return
    # Through the shipped executables (compiled by `python -m jaxdobby.programs` with the
    # instruction set capped at AVX2, serialised, loaded here): the locally compiled run's
    # numbers to round-off, 1e-10 relative as above (the same program and options; the cap
    # only changes which vector instructions XLA's LLVM picks, hence how it contracts
    # multiply-adds; measured ≤ 1e-12 here, 1.3e-11 on the study's chunk program)
    loaded, fits = [], []
    load = programs.shipped_executables

    def recorded(keys, *a, **k):
        fits.extend(any(map(programs.fits_here, programs.executable_variants(key)))
                    for key in keys)
        loaded.extend(load(keys, *a, **k))
        return loaded[-len(keys):]

    monkeypatch.setattr(programs, "shipped_executables", recorded)
    # compiled programs are kept per process: start from none, so that these are loaded here
    monkeypatch.setattr(importlib.import_module("jaxdobby.simulate"), "_REPORT_PROGRAMS", {})
    capfd.readouterr()
    shipped, _, _ = stored_report(default_setup, RunOptions())
    # XLA's loader (C++, on the process's stderr) found every feature the executables require
    assert "cpu_aot_loader" not in capfd.readouterr().err
    # loaded exactly where a variant compiled for this CPU's features ships
    assert len(loaded) == 2 and [c is not None for c in loaded] == fits
    for key, value in first.items():
        if key == "periodicity_residual":
            assert shipped[key] == pytest.approx(value, rel=0, abs=1e-12), key
        elif isinstance(value, float):
            assert shipped[key] == pytest.approx(value, rel=1e-10, abs=1e-300), key
    (name, _, args, static_key), _ = report_programs(slower, RunOptions())
    assert programs.program_key(name, static_key + " changed", args) not in {
        p.name for p in stored}


def test_python_simulate_answers_from_the_shipped_run(default_setup, monkeypatch):
    """simulate() of the default sizes from Python (any float values; here 1100 r/min, 500 N)
    loads the executable the package ships for the command line's run
    (jaxdobby.simulate.shipped_simulation) wherever a variant fits this CPU: nothing traced or
    compiled (the traced path is made to fail). Its Simulation against the traced and compiled
    one of the same inputs (the shipped executables switched off): the same program at another
    LLVM level and instruction-set cap, so equal to 1e-10 relative, as in the test above
    (measured ≤ 4e-12), with the same structure. Under a trace (jit, grad, vmap) the shipped
    run is never used."""
    from jaxdobby import Machine, OperatingPoint

    simulation = importlib.import_module("jaxdobby.simulate")
    machine = Machine.default()
    op = OperatingPoint.from_users_units(speed_rpm=1100.0, warp_force_n=500.0)
    (name, run, args, static_key), _ = report_programs(default_setup, RunOptions())
    run_p = programs.stored_program(name, run, args, static_key=static_key, directory=None)
    key = programs.together_keys([(run_p, args)], programs.ONE_SHOT)[0]
    fits = programs.executables_usable() and any(
        map(programs.fits_here, programs.executable_variants(key)))
    if fits:
        with monkeypatch.context() as m:
            m.setattr(simulation, "_simulate", None)  # called: TypeError
            got = simulate(machine, op)
    else:
        assert simulation.shipped_simulation(machine, op, None, "collocation", 432) is None
        got = simulate(machine, op)
    monkeypatch.setenv("JAXDOBBY_SHIPPED_EXECUTABLES", "off")
    want = simulate(machine, op)
    assert jax.tree.structure(got) == jax.tree.structure(want)
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
        a, b = np.asarray(a), np.asarray(b)
        if b.dtype.kind == "f" and b.size > 1 or b.dtype.kind != "f":
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * float(np.max(np.abs(b))))
    for metric, value in want.metrics.items():
        assert float(got.metrics[metric]) == pytest.approx(float(value), rel=1e-10), metric
    monkeypatch.delenv("JAXDOBBY_SHIPPED_EXECUTABLES")
    seen = []

    def probe(speed):
        seen.append(simulation.shipped_simulation(
            machine, OperatingPoint(speed=speed, warp_force=op.warp_force), None,
            "collocation", 432))
        return speed

    jax.make_jaxpr(probe)(op.speed)
    assert seen == [None]


def test_a_program_with_host_callbacks_runs_unstored(tmp_path):
    """jax.export does not serialise host callbacks (diffrax's adaptive solver has them:
    `jaxdobby simulate --method adaptive`): such a program is traced and compiled in every run,
    not stored, and gives what the function gives."""
    seen = []

    def fn(x):
        jax.debug.callback(lambda v: seen.append(float(v)), x[0])
        return [2.0 * x, x.sum()]

    x = jax.numpy.arange(3.0)
    got = programs.stored_program("callback", fn, [x], static_key="", directory=tmp_path)
    assert isinstance(got, programs.Unstored) and not list(tmp_path.iterdir())
    assert [(a.shape, a.dtype) for a in got.out_avals] == [((3,), x.dtype), ((), x.dtype)]
    (compiled,) = programs.compile_together([(got, [x])])
    doubled, total = compiled(x)
    np.testing.assert_array_equal(np.asarray(doubled), [0.0, 2.0, 4.0])
    assert float(total) == 3.0 and seen == [0.0]


def test_shipped_executables_are_not_loaded_where_they_do_not_fit(monkeypatch):
    """An executable is machine code for one instruction set: it is loaded only where
    executables_usable() allows (never with JAXDOBBY_SHIPPED_EXECUTABLES=off, never off the
    CPU backend or on a CPU without x86-64-v3, never on a CPU that lacks one of the features it
    was compiled for), and a key that ships nothing loads nothing."""
    shipped = [p.name.split(".")[0] + ".xlaexe" for p in programs.SHIPPED.glob("*.xlaexe")]
    assert shipped
    if programs.executables_usable():
        # a CPU without one feature of each variant (its last, alphabetically)
        variants = programs.executable_variants(shipped[0])
        lacking = frozenset.intersection(*map(programs.variant_features, variants))
        fewer = lacking - {sorted(lacking)[-1]}
        with monkeypatch.context() as m:
            m.setattr(programs, "host_features", lambda: fewer)
            assert not any(map(programs.fits_here, variants))
            assert programs.shipped_executable(shipped[0]) is None
    monkeypatch.setenv("JAXDOBBY_SHIPPED_EXECUTABLES", "off")
    assert not programs.executables_usable()
    assert programs.shipped_executable(shipped[0]) is None
    monkeypatch.delenv("JAXDOBBY_SHIPPED_EXECUTABLES")
    monkeypatch.setattr(programs, "_cpu_runs_shipped", lambda: False)
    assert not programs.executables_usable()
    assert programs.shipped_executable(shipped[0]) is None
    monkeypatch.setattr(programs, "_cpu_runs_shipped", lambda: True)
    assert programs.executables_usable() == (jax.default_backend() == "cpu")
    assert programs.shipped_executable("nothing-000.xlaexe") is None
    assert programs.executable_key("x", programs.Unstored(None, ()), [], "") is None


_CHUNK_AB = r"""
import dataclasses, json, os, sys, tempfile
from pathlib import Path
os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                           + " --xla_force_host_platform_device_count=2")
from jaxdobby.command_line import _configure_jax
_configure_jax()
import jax, numpy as np
from jaxdobby.programs import executables_usable
from jaxdobby.sensitivity import batch
from jaxdobby.sensitivity.command import SobolConfig, MODELS, build_space, default_chunk
from jaxdobby.sensitivity.command import default_study_model
row, stored, dim = default_study_model()
devices = tuple(jax.devices())
chunk = default_chunk(2)
from jaxdobby.programs import executable_variants, fits_here
loaded, fits = [], []
load = batch.shipped_executable
def recorded(*args):
    fits.append(any(map(fits_here, executable_variants(args[0]))))
    loaded.append(load(*args))
    return loaded[-1]
batch.shipped_executable = recorded
shipped, sharding = batch._compile(row, chunk, dim, devices, stored)
with tempfile.TemporaryDirectory() as d:  # `ship` set: compiled here, written to d
    compiled, _ = batch._compile(row, chunk, dim, devices,
                                 dataclasses.replace(stored, ship=Path(d)))
space = build_space(SobolConfig(), MODELS["dobby"])
x = jax.device_put(space.sample(1024, second_order=True, seed=0)[:chunk], sharding)
a, b = jax.device_get(shipped(x)), jax.device_get(compiled(x))
worst = max(float(np.max(np.abs(a[k] - b[k]) / np.abs(b[k]))) for k in b
            if k != "ok" and not k.startswith("validity"))
same = all(np.array_equal(a[k], b[k]) for k in b if k == "ok" or k.startswith("validity"))
print(json.dumps({"usable": executables_usable(), "worst": worst, "same_flags": same,
                  "loaded": [c is not None for c in loaded], "fits": fits}))
"""


@pytest.mark.slow
def test_shipped_chunk_executable_of_the_default_study_equals_a_compiled_one(tmp_path):
    """The default study's chunk program on 2 CPU devices, loaded from the package's shipped
    executable (AVX2-capped machine code), against the same program compiled in this process
    (this CPU's own instruction set, the command line's options), on the first 512 rows of the
    default design: the same metrics to round-off, 1e-10 relative (the periodic solve amplifies
    the rounding of the 432-step cycle map; measured 1.3e-11), the same status flags. Slow:
    XLA compiles the chunk program (~10 s); the default suite checks the same mechanism on
    `jaxdobby simulate`'s two programs (test_stored_report_equals_simulate_and_is_reused)."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, JAXDOBBY_CACHE_DIR="off")
    out = subprocess.run([sys.executable, "-c", _CHUNK_AB], env=env, capture_output=True,
                         text=True, check=True, cwd=tmp_path)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    if not got["usable"] or got["fits"] == [False]:
        pytest.skip("this machine does not load the shipped executables (none compiled for "
                    "its CPU's features)")
    assert got["loaded"] == [True], got  # the first from the package, the second compiled
    assert got["same_flags"] and got["worst"] <= 1e-10, got


def test_stored_call_keys_on_static_parts_and_stores_the_program(tmp_path, monkeypatch):
    """stored_call: the arrays among its arguments are the program's inputs, everything else
    (strings, ints, a module's static fields) is part of its key. Values of the same shapes
    run the same compiled program; another static value is another program; a new process
    (here: the per-process table emptied) reads the stored program instead of tracing."""
    monkeypatch.setattr(programs, "SHIPPED", tmp_path / "shipped")  # none shipped
    traced = []

    def fn(setup, x, power):
        traced.append(power)
        return {"y": setup.operating.speed * x**power, "n": x.sum()}

    s = Setup()
    x = np.arange(3.0)
    got = programs.stored_call("test-call", fn, (s, x, 2), directory=tmp_path)
    speed = float(s.operating.speed)
    np.testing.assert_allclose(got["y"], speed * x**2, rtol=1e-15)  # exact arithmetic here
    again = programs.stored_call("test-call", fn, (s, x + 1.0, 2), directory=tmp_path)
    np.testing.assert_allclose(again["y"], speed * (x + 1.0)**2, rtol=1e-15)
    assert traced == [2]  # the same program for other values
    cubed = programs.stored_call("test-call", fn, (s, x, 3), directory=tmp_path)
    np.testing.assert_allclose(cubed["y"], speed * x**3, rtol=1e-15)
    assert traced == [2, 3] and len(list(tmp_path.glob("test-call-*.jaxexport"))) == 2
    monkeypatch.setattr(programs, "_CALLS", {})
    programs.stored_call("test-call", fn, (s, x, 2), directory=tmp_path)
    assert traced == [2, 3]  # read back, not traced


def test_optimize_values_through_the_shipped_programs_equal_a_traced_solve():
    """`jaxdobby optimize`'s evaluator runs the package's stored programs (the default study's
    ship compiled); its values equal those of the same steady-state batch traced and compiled
    here, to round-off (1e-10 relative: XLA's optimisation levels differ, the arithmetic does
    not)."""
    from jaxdobby.optimize.objective import batch_values

    evaluator, study = optimize_evaluator()
    _, values = evaluator.value(study.space.initial)
    want = eqx.filter_jit(batch_values)(study.space, study.space.initial, evaluator.speeds,
                                        evaluator.steps)
    for name in ("deviation", "deviation_rms", "acceleration", "deviation_pp",
                 "acceleration_pp"):
        np.testing.assert_allclose(values[name], np.asarray(want[name]), rtol=1e-10,
                                   err_msg=name)
    assert np.all(values["converged"] == 1.0)


@pytest.mark.slow  # ~30 s: simulates a frame alone and compiles the batch anew
def test_loom_batch_through_the_shipped_program_equals_each_frame_alone(monkeypatch):
    """`jaxdobby loom --weave twill22` runs the package's shipped program; each frame's
    metrics equal those of simulate() on that frame alone (its plan and stroke; 1e-9
    relative: the same equations, vmapped or not), and a batch compiled here instead of loaded
    gives them to round-off."""
    from jaxdobby.weave.loom import frame_run, run_frames, shipped_weave_args

    machine, operating, plan, strokes = shipped_weave_args()
    rows = run_frames(machine, operating, plan, strokes)
    for i in (0, 7):
        alone = frame_run(machine, operating, plan[:, i], strokes[i]).metrics
        for name in ("deviation_pp", "velocity_deviation_amp", "acceleration_amp"):
            assert float(rows[i][name]) == pytest.approx(float(alone[name]), rel=1e-9), name
    monkeypatch.setattr(programs, "executables_usable", lambda: False)
    compiled = run_frames(machine, operating, plan, strokes)
    for a, b in zip(rows, compiled):
        for name in ("deviation_pp", "velocity_deviation_amp", "acceleration_amp"):
            assert float(a[name]) == pytest.approx(float(b[name]), rel=1e-10), name
