"""Shared fixtures: the demo mesh, small generated meshes, the real meshes of
../shared/data (or $COARSEN_DATA) and the `coarsen` command ($COARSEN_CLI)."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import coarsen

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def demo():
    V, F = coarsen.demo()
    V.flags.writeable = False
    F.flags.writeable = False
    return V, F


def subdivide(V, F):
    """Every triangle split 1-to-4 at its edges' midpoints."""
    F = np.asarray(F, dtype=np.int64)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, inv = np.unique(E, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    m, n = len(F), len(V)
    a, b, c = F.T
    ab, bc, ca = n + inv[:m], n + inv[m : 2 * m], n + inv[2 * m :]
    F2 = np.concatenate(
        [np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
    )
    return np.concatenate([V, (V[edges[:, 0]] + V[edges[:, 1]]) / 2]), F2


def torus(R=2.0, r=0.6, n=48, m=24):
    """A torus of n×m quads split in two triangles each."""
    u, v = np.meshgrid(np.arange(n) * 2 * np.pi / n, np.arange(m) * 2 * np.pi / m, indexing="ij")
    V = np.stack(
        [(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], axis=-1
    ).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    a = i * m + j
    b = ((i + 1) % n) * m + j
    c = ((i + 1) % n) * m + (j + 1) % m
    d = i * m + (j + 1) % m
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return V, F


@pytest.fixture(scope="session")
def data_dir():
    """The real meshes, or a skip that says where they were looked for."""
    d = Path(os.environ.get("COARSEN_DATA") or REPO.parent / "shared" / "data")
    if not (d / "stanford-bunny.obj").is_file():
        pytest.skip(f"the shared test meshes are not at {d} (set COARSEN_DATA)")
    return d


@pytest.fixture(scope="session")
def cli():
    """The `coarsen` command to compare with: $COARSEN_CLI (scripts/test sets it), else
    target/debug/coarsen, else `coarsen` on the PATH."""
    for candidate in (
        os.environ.get("COARSEN_CLI"),
        str(REPO / "target" / "debug" / "coarsen"),
        shutil.which("coarsen"),
    ):
        if candidate and os.access(candidate, os.X_OK) and Path(candidate).is_file():
            return candidate
    pytest.skip(
        "no `coarsen` command to compare with: set COARSEN_CLI (scripts/test builds it with "
        "`cargo test --workspace`, or run `cargo build -p coarsen-cli`)"
    )
