"""trimesh and pyvista meshes in and out (duck-typed: neither is a dependency)."""

import numpy as np
import pytest

import coarsen
from conftest import torus


def test_trimesh_round_trip(demo, tmp_path):
    trimesh = pytest.importorskip("trimesh", reason="trimesh is not installed (pip install trimesh)")
    V, F = demo
    tm = trimesh.Trimesh(vertices=V, faces=F, process=False)
    out, report = coarsen.remesh(tm, vertices=500, pipeline="uniform-cvt")
    assert isinstance(out, trimesh.Trimesh)
    V2, F2, _ = coarsen.remesh(V, F, vertices=500, pipeline="uniform-cvt")
    assert np.array_equal(out.vertices, V2) and np.array_equal(out.faces, F2)
    assert report["output_vertices"] == 500 and out.is_watertight
    out, _, attrs = coarsen.remesh(tm, vertices=500, attributes=True)
    assert isinstance(out, trimesh.Trimesh) and len(attrs["vertex"]["mean_curvature"]) == 500
    m = coarsen.metrics(tm, out)
    assert m == coarsen.metrics(V, F, out.vertices, out.faces)
    coarsen.write(tmp_path / "t.ply", out)
    V3, F3 = coarsen.read(tmp_path / "t.ply")
    assert np.array_equal(V3, out.vertices) and np.array_equal(F3, out.faces)
    with pytest.raises(ValueError, match="F: must be left out"):
        coarsen.remesh(tm, F, vertices=10)


def test_pyvista_round_trip(demo):
    pv = pytest.importorskip(
        "pyvista",
        reason="pyvista is not installed: `pip install pyvista` in the test venv, or "
        "COARSEN_TEST_PYVISTA=1 scripts/test",
    )
    V, F = demo
    flat = np.hstack([np.full((len(F), 1), 3), F]).ravel()
    mesh = pv.PolyData(V, flat)
    out, report = coarsen.remesh(mesh, vertices=500, pipeline="qem")
    assert isinstance(out, pv.PolyData) and out.n_points == 500 and out.is_all_triangles
    V2, F2, _ = coarsen.remesh(V, F, vertices=500, pipeline="qem")
    assert np.array_equal(out.points, V2)
    assert np.array_equal(out.faces.reshape(-1, 4)[:, 1:], F2)
    # Quads are refused, naming the first one.
    Vt, Ft = torus(n=8, m=6)
    quads = pv.PolyData(Vt, np.hstack([[4, 0, 1, 7, 6], np.hstack([np.full((len(Ft), 1), 3), Ft]).ravel()]))
    with pytest.raises(ValueError, match="only triangle faces are supported, but face 0 has 4 points"):
        coarsen.remesh(quads, vertices=10)
    strips = pv.PolyData(Vt, strips=np.array([4, 0, 1, 6, 7]))
    with pytest.raises(ValueError, match="triangle strips"):
        coarsen.remesh(strips, vertices=10)
