"""The output directory of a Sobol run: manifest, finished chunks, atomic writes.

Layout::

    DIR/manifest.json          what the run is (problem, N, seed, second order, chunk size, model,
                               SHA-256 of the sample matrix); --resume refuses a different run
    DIR/chunks/chunk-000012.npz
                               model outputs of rows [12·C, 13·C) (the last chunk is shorter),
                               written once the chunk is finished

Every file is written to a temporary file in its own directory, flushed to disk and moved into
place with ``os.replace``, so a reader (or a resumed run) sees a whole file or none: a run killed
at any moment loses at most the chunks in flight. Nothing here imports JAX.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..io import atomic_write, write_json  # noqa: F401  (re-exported)

MANIFEST = "manifest.json"
CHUNKS = "chunks"
_ROWS = "__rows__"  # reserved key of a chunk file: (start, stop) of its rows
_PROCESS = "__process__"  # reserved key: the process that computed it (provenance)


def samples_digest(samples: np.ndarray) -> str:
    """SHA-256 of a sample matrix (float64, C order, little-endian), with its shape."""
    x = np.ascontiguousarray(samples, dtype="<f8")
    h = hashlib.sha256(repr(x.shape).encode())
    h.update(x.tobytes())
    return h.hexdigest()


class ChunkStore:
    """Finished chunks of one run in a directory (see the module docstring).

    Args:
        directory: the run's output directory (created if missing).
        manifest: JSON-ready description of the run; a resumed run must match it exactly.
    """

    def __init__(self, directory: str | os.PathLike, manifest: Mapping):
        self.directory = Path(directory)
        self.manifest = json.loads(json.dumps(dict(manifest)))  # normalise to JSON types
        self.chunk_dir = self.directory / CHUNKS

    def prepare(self, resume: bool) -> None:
        """Check that the directory may hold this run and clear temporaries of a killed run.

        With several processes, every process calls this, then all meet at a barrier, then all
        call :meth:`create`: no process writes before every process has checked.

        Raises:
            ValueError: a fresh run into a directory that already holds a run; ``resume`` with
                nothing to resume; ``resume`` of a different run (naming the fields that differ).
        """
        path = self.directory / MANIFEST
        has_chunks = self.chunk_dir.is_dir() and any(self.chunk_dir.glob("chunk-*.npz"))
        if not resume:
            if path.exists() or has_chunks:
                raise ValueError(f"output directory {str(self.directory)!r} already holds a run: "
                                 "pass --resume to continue it, or choose another --out")
            return
        if not path.exists():
            raise ValueError(f"--resume: {str(self.directory)!r} holds no run to resume (no "
                             f"{MANIFEST}); start it without --resume")
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError) as e:
            raise ValueError(f"--resume: cannot read {str(path)!r}: {e}") from None
        new = self.manifest
        differ = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
        if differ:
            raise ValueError(f"--resume: the run in {str(self.directory)!r} differs from this one "
                             f"in {differ} (e.g. {differ[0]}: stored {old.get(differ[0])!r}, now "
                             f"{self.manifest.get(differ[0])!r}); resume with the same settings "
                             "or choose another --out")
        for stale in self.chunk_dir.glob(".*.tmp"):  # left by a run killed mid-write
            stale.unlink(missing_ok=True)

    def create(self) -> None:
        """Create the directories and write the manifest (atomically; idempotent)."""
        self.chunk_dir.mkdir(parents=True, exist_ok=True)
        write_json(self.directory / MANIFEST, self.manifest)

    def chunk_path(self, index: int) -> Path:
        """Path of chunk ``index``'s file."""
        return self.chunk_dir / f"chunk-{index:06d}.npz"

    def finished(self) -> set[int]:
        """Indices of the chunks whose files exist."""
        if not self.chunk_dir.is_dir():
            return set()
        return {int(p.stem.split("-")[1]) for p in self.chunk_dir.glob("chunk-*.npz")}

    def write_chunk(self, index: int, rows: tuple[int, int], outputs: Mapping[str, np.ndarray],
                    process: int = 0) -> Path:
        """Write chunk ``index`` (rows ``[start, stop)``) with its per-row outputs, atomically."""
        arrays = {k: np.asarray(v) for k, v in outputs.items()}
        arrays[_ROWS] = np.asarray(rows, dtype=np.int64)
        arrays[_PROCESS] = np.asarray(process, dtype=np.int64)
        return atomic_write(self.chunk_path(index), lambda f: np.savez(f, **arrays))

    def read_chunk(self, index: int) -> tuple[tuple[int, int], dict[str, np.ndarray], int]:
        """Read chunk ``index``: its rows (start, stop), outputs, and the process that wrote it."""
        with np.load(self.chunk_path(index), allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        start, stop = (int(v) for v in data.pop(_ROWS))
        process = int(data.pop(_PROCESS))
        return (start, stop), data, process
