"""Shared fixtures of the Python package's tests: the command-line tool and the test meshes.

ctest runs them with PYTHONPATH at the build's python/ directory (or an installed package),
FACETREE_CLI the tool built beside it, FACETREE_SHARED_DATA and FACETREE_TEST_DATA the meshes.
"""
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import facetree


def _path(variable: str) -> Path:
    value = os.environ.get(variable)
    if not value:
        pytest.fail(f"{variable} is not set (run the tests through ctest)")
    return Path(value)


@pytest.fixture(scope="session")
def cli() -> Path:
    return _path("FACETREE_CLI")


@pytest.fixture(scope="session")
def shared_data() -> Path:
    return _path("FACETREE_SHARED_DATA")


@pytest.fixture(scope="session")
def test_data() -> Path:
    return _path("FACETREE_TEST_DATA")


@pytest.fixture(scope="session")
def bunny(shared_data):
    """bunny_zipper as arrays: vertices, faces, face ids, and its path."""
    path = shared_data / "bunny_zipper.ply.zst"
    vertices, faces, ids = facetree.read_mesh(path)
    return vertices, faces, ids, path


def run_cli(cli: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    result = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    if check and result.returncode != 0:
        raise AssertionError(f"facetree {' '.join(map(str, args))} failed: {result.stderr}")
    return result


def grid_mesh(n: int):
    """An n x n grid of squares, two triangles each, in z = 0 (float32, int32)."""
    xs, ys = np.meshgrid(np.arange(n + 1, dtype=np.float32), np.arange(n + 1, dtype=np.float32))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size, np.float32)], axis=1)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = (j * (n + 1) + i).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return vertices, faces.astype(np.int32)
