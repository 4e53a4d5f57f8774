"""The Sobol pipeline split over devices, over processes, and interrupted: the same indices.

Each case runs the whole command in fresh Python processes (``python -m jaxdobby.sensitivity``,
Ishigami, N = 4096 with second order: 32768 rows in 33 chunks of 1000) and compares with one
uninterrupted single-device run in this process.

Equality is *bitwise* (model outputs and every index), not to a tolerance: the model is
evaluated row by row (vmap; no reduction across rows), so a row's result does not depend on
which device, process or chunk computes it, nor on how many rows share its shard; the indices
are a deterministic function (seeded bootstrap) of the outputs in row order. Any difference at
all means rows were lost, duplicated, misplaced or recomputed differently.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from jaxdobby.sensitivity import ChunkStore, SobolConfig, run_sobol

ROOT = Path(__file__).resolve().parents[1]
N, SEED, CHUNK = 4096, 11, 1000
CHUNKS = 33  # ceil(4096 · 8 / 1000)
ARGS = ["--model", "ishigami", "--n", str(N), "--second-order", "--seed", str(SEED),
        "--chunk-size", str(CHUNK), "--no-figures", "--json"]


def env(**extra):
    e = dict(os.environ, PYTHONPATH=str(ROOT), JAX_PLATFORMS="cpu")
    # no device-count flag of the parent, but the compile options the tests run with
    # (tests/conftest.py), so that bit-identical claims compare programs compiled alike
    e["XLA_FLAGS"] = os.environ.get("JAXDOBBY_TEST_XLA_FLAGS", "")
    if "XLA_FLAGS" in extra:
        extra["XLA_FLAGS"] = f"{e['XLA_FLAGS']} {extra['XLA_FLAGS']}".strip()
    e.update(extra)
    return e


def cli(*args):
    return [sys.executable, "-m", "jaxdobby.sensitivity", *ARGS, *args]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "run"
    run = run_sobol(SobolConfig(model="ishigami", n=N, second_order=True, seed=SEED, out=out,
                                chunk_size=CHUNK, devices=1, figures=False))
    assert run.evaluation.devices == 1 and run.evaluation.processes == 1
    return json.loads((out / "indices.json").read_text()), np.load(out / "outputs.npz")["output_y"]


def assert_same(reference, out, indices):
    ref_indices, ref_y = reference
    np.testing.assert_array_equal(np.load(out / "outputs.npz")["output_y"], ref_y)
    assert indices["metrics"] == ref_indices["metrics"]
    assert indices["failures"] == ref_indices["failures"]


def test_two_host_devices_match_one(reference, tmp_path):
    out = tmp_path / "run"
    p = subprocess.run(cli("--out", str(out), "--devices", "2"), capture_output=True, text=True,
                       timeout=120, env=env(XLA_FLAGS="--xla_force_host_platform_device_count=2"))
    assert p.returncode == 0, p.stderr
    indices = json.loads(p.stdout)
    assert indices["run"]["devices"] == 2  # really sharded over two devices
    assert_same(reference, out, indices)


def test_devices_flag_alone_gives_two_cpu_devices(reference, tmp_path):
    """Without XLA_FLAGS, ``--devices 2`` makes the CPU two JAX devices (jax_num_cpu_devices
    set by the command before JAX starts): sharded, and the same numbers."""
    out = tmp_path / "run"
    p = subprocess.run(cli("--out", str(out), "--devices", "2"), capture_output=True, text=True,
                       timeout=120, env=env())
    assert p.returncode == 0, p.stderr
    indices = json.loads(p.stdout)
    assert indices["run"]["devices"] == 2
    assert_same(reference, out, indices)


def free_port():
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def test_two_processes_match_one(reference, tmp_path):
    out = tmp_path / "run"
    coord = ["--coordinator", f"localhost:{free_port()}", "--num-processes", "2"]
    procs = [subprocess.Popen(cli("--out", str(out), *coord, "--process-id", str(i)),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env())
             for i in (0, 1)]
    try:
        results = [p.communicate(timeout=120) for p in procs]
    finally:
        for p in procs:
            p.kill()
    for p, (_, err) in zip(procs, results):
        assert p.returncode == 0, err
    indices = json.loads(results[0][0])
    assert results[1][0] == ""  # only process 0 reports
    assert indices["run"]["processes"] == 2
    # Each process computed its own share: chunk i by process i mod 2.
    store = ChunkStore(out, {})
    assert {i: store.read_chunk(i)[2] for i in range(CHUNKS)} == {i: i % 2 for i in range(CHUNKS)}
    assert_same(reference, out, indices)


SLOW_CHILD = """
import sys, time, jax
jax.config.update("jax_enable_x64", True)
from jaxdobby.sensitivity import SobolConfig, run_sobol
cfg = SobolConfig(model="ishigami", n={n}, second_order=True, seed={seed}, chunk_size={chunk},
                  out=sys.argv[1], figures=False)
run_sobol(cfg, progress=lambda done, total: time.sleep(0.3))  # slow enough to be killed
"""


def test_resume_after_kill_gives_identical_indices(reference, tmp_path):
    out = tmp_path / "run"
    child = subprocess.Popen([sys.executable, "-c", SLOW_CHILD.format(n=N, seed=SEED, chunk=CHUNK),
                              str(out)], env=env(), stderr=subprocess.PIPE)
    chunks = out / "chunks"
    deadline = time.monotonic() + 90
    while not (chunks.is_dir() and len(list(chunks.glob("chunk-*.npz"))) >= 4):
        assert child.poll() is None, child.stderr.read().decode()
        assert time.monotonic() < deadline, "no chunks written"
        time.sleep(0.02)
    child.send_signal(signal.SIGKILL)
    child.wait()
    child.stderr.close()
    finished = len(list(chunks.glob("chunk-*.npz")))
    assert 4 <= finished < CHUNKS and not (out / "indices.json").exists()  # really interrupted
    (chunks / ".chunk-000031.npz.abc.tmp").write_bytes(b"half a chunk")  # as if killed mid-write

    p = subprocess.run(cli("--out", str(out), "--resume"), capture_output=True, text=True,
                       timeout=120, env=env())
    assert p.returncode == 0, p.stderr
    indices = json.loads(p.stdout)
    assert indices["run"]["chunks_computed_here"] == CHUNKS - finished  # finished ones skipped
    assert not list(chunks.glob("*.tmp"))
    assert_same(reference, out, indices)
