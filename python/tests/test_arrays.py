"""Arrays in and out: conversions, files, attributes, the lists, the report."""

import json
from pathlib import Path

import numpy as np
import pytest

import coarsen
from conftest import REPO, torus


def test_remesh_returns_arrays_and_the_report(demo):
    V, F = demo
    V2, F2, report = coarsen.remesh(V, F, vertices=500)
    assert V2.dtype == np.float64 and V2.shape == (500, 3)
    assert F2.dtype == np.uint32 and F2.ndim == 2 and F2.shape[1] == 3
    assert V2.flags.writeable and F2.flags.writeable and V2.flags.c_contiguous
    assert F2.max() < 500
    assert report["pipeline"] == coarsen.DEFAULT_PIPELINE == "adaptive-cvt"
    assert report["output_vertices"] == 500 and report["output_faces"] == len(F2)
    assert report["input"] == "mesh" and report["input_vertices"] == len(V)
    assert [s["kind"] for s in report["stages"]][0] == "curvature"
    json.dumps(report)  # plain JSON content


def test_other_dtypes_are_converted_and_give_the_same_result(demo):
    V, F = demo
    ref = coarsen.remesh(V, F, vertices=300, pipeline="qem")
    for V1, F1 in [
        (V, F.astype(np.int64)),
        (V, F.astype(np.int32)),
        (np.asfortranarray(V), F[:, :].copy(order="F")),
        (V.astype(">f8"), F.astype(">i8")),
        (V.tolist(), F.tolist()),
    ]:
        out = coarsen.remesh(V1, F1, vertices=300, pipeline="qem")
        assert np.array_equal(out[0], ref[0]) and np.array_equal(out[1], ref[1])
    # float32 positions are converted (not the same mesh, so only its counts).
    V2, F2, _ = coarsen.remesh(V.astype(np.float32), F.astype(np.uint64), vertices=300, pipeline="qem")
    assert V2.shape == (300, 3)


def test_each_target_and_the_pipelines_own(demo):
    V, F = demo
    assert len(coarsen.remesh(V, F, vertices=400, pipeline="qem")[0]) == 400
    _, F2, r = coarsen.remesh(V, F, faces=1000, pipeline="qem")
    assert abs(len(F2) - 1000) <= 2 and r["target"] is not None
    _, F2, r = coarsen.remesh(V, F, ratio=0.9, pipeline="qem")
    assert len(F2) <= len(F) // 10 + 2
    _, F2, r = coarsen.remesh(V, F, pipeline="demo")  # the file's own: ratio 0.75
    assert len(F2) <= len(F) // 4 + 2


def test_params_are_typed_toml_values(demo):
    V, F = demo
    _, _, r = coarsen.remesh(
        V,
        F,
        vertices=400,
        pipeline="uniform-cvt",
        params={"relax.sweeps": 2, "cluster.cvt.seed": np.int64(3), "cluster.cvt.fold_guard": True},
    )
    relax = [s for s in r["stages"] if s["kind"] == "relax"][0]
    assert relax["params"]["sweeps"] == 2, relax["params"]
    cvt = [s for s in r["stages"] if s["kind"] == "cluster.cvt"][0]
    assert cvt["params"]["seed"] == 3 and cvt["params"]["fold_guard"] is True
    _, _, r = coarsen.remesh(
        V, F, vertices=400, pipeline="adaptive-cvt", params={"cluster.cvt.r": 0.5, "cluster.cvt.energy": "shu2009"}
    )
    cvt = [s for s in r["stages"] if s["kind"] == "cluster.cvt"][0]
    assert cvt["params"]["r"] == 0.5 and cvt["params"]["energy"] == "shu2009"


def test_read_and_write_round_trip(tmp_path, demo):
    V, F = demo
    for ext in ("ply", "obj", "off", "stl"):
        p = tmp_path / f"demo.{ext}"
        coarsen.write(p, V, F)
        V2, F2 = coarsen.read(str(p))
        if ext == "stl":  # corners stored apart, welded on reading
            assert len(V2) == len(V) and len(F2) == len(F)
        else:
            assert np.array_equal(V2, V) and np.array_equal(F2, F)


def test_attributes_are_read_carried_and_written(tmp_path, demo):
    V, F = demo
    n, m = len(V), len(F)
    attrs = {
        "vertex": {"k": np.linspace(0, 1, n), "normal": V / np.linalg.norm(V, axis=1)[:, None]},
        "face": {"part": (np.arange(m) % 7).astype(np.int64)},
    }
    p = tmp_path / "a.ply"
    coarsen.write(p, V, F, attrs)
    V2, F2, a = coarsen.read(p, attributes=True)
    assert np.array_equal(V2, V)
    assert set(a["vertex"]) == {"k", "normal"} and set(a["face"]) == {"part"}
    assert np.array_equal(a["vertex"]["k"], attrs["vertex"]["k"])
    assert a["vertex"]["normal"].shape == (n, 3)
    assert a["face"]["part"].dtype == np.uint32
    # A run carries them, as the command carries a file's.
    _, F3, _, out = coarsen.remesh(V, F, vertices=400, pipeline="qem", attrs=attrs, attributes=True)
    assert out["vertex"]["k"].shape == (400,) and out["face"]["part"].shape == (len(F3),)
    # The pipeline's own columns come back too.
    _, _, _, out = coarsen.remesh(V, F, vertices=400, attributes=True)
    assert "mean_curvature" in out["vertex"]
    _, _, _, out = coarsen.remesh(V, F, ratio=0.5, pipeline="refine", attributes=True)
    colours = [c for c in out["vertex"].values() if c.dtype == np.uint8]
    assert colours and colours[0].shape[1] == 3


def test_read_of_a_missing_or_bad_file_is_a_coarsen_error(tmp_path):
    with pytest.raises(coarsen.CoarsenError, match="nope.ply"):
        coarsen.read(tmp_path / "nope.ply")
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(coarsen.CoarsenError, match="bad.obj"):
        coarsen.read(bad)
    assert issubclass(coarsen.CoarsenError, RuntimeError)


def test_metrics_are_the_commands_figures(demo):
    V, F = demo
    V2, F2, _ = coarsen.remesh(V, F, vertices=800)
    m = coarsen.metrics(V, F, V2, F2)
    assert set(m) >= {"quality", "fidelity", "validity"}
    assert m["quality"]["alpha_min_deg"] > 10 and m["fidelity"]["hausdorff_pct"] < 2
    assert coarsen.metrics(V, F, V2, F2, samples_per_face=2)["quality"] == m["quality"]


def test_stages_and_pipelines_are_listed():
    kinds = {s["kind"] for s in coarsen.stages()}
    assert {"cluster.cvt", "dual", "relax", "simplify.qem", "curvature"} <= kinds
    relax = [s for s in coarsen.stages() if s["kind"] == "relax"][0]
    sweeps = [p for p in relax["params"] if p["name"] == "sweeps"][0]
    assert sweeps["default"] == "4" and sweeps["type"] == "u32" and sweeps["doc"]
    names = sorted(p["name"] for p in coarsen.pipelines())
    files = sorted(f.stem for f in (REPO / "pipelines").glob("*.toml"))
    assert names == files
    assert all(p["description"] and "[[stage]]" in p["text"] for p in coarsen.pipelines())


def test_a_pipeline_file_by_path(demo, tmp_path):
    p = tmp_path / "mine.toml"
    p.write_text('[pipeline]\nname = "mine"\ndescription = "qem"\n\n[[stage]]\nkind = "simplify.qem"\n')
    V, F = demo
    V2, _, r = coarsen.remesh(V, F, vertices=300, pipeline=p)
    assert r["pipeline"] == "mine" and len(V2) == 300


def test_weld_and_name(tmp_path):
    V, F = torus()
    soup = V[F].reshape(-1, 3)
    tris = np.arange(len(soup)).reshape(-1, 3)
    _, _, r = coarsen.remesh(soup, tris, vertices=200, pipeline="qem", weld=True, name="soup")
    assert r["input"] == "soup" and r["output_vertices"] == 200


def test_the_stubs_name_every_public_function():
    here = Path(coarsen.__file__).parent  # as installed: the wheel ships them
    stub = (here / "__init__.pyi").read_text()
    for name in coarsen.__all__:
        assert name in stub, name
    assert (here / "py.typed").exists()


def test_feature_edges_become_rails_of_the_cad_pipeline():
    # The torus's outer equator, smooth: a rail only when marked.
    n, m = 48, 24
    V, F = torus(n=n, m=m)
    ring = np.stack([np.arange(n) * m, ((np.arange(n) + 1) % n) * m], axis=-1)

    def rails(**kw):
        _, _, r = coarsen.remesh(V, F, vertices=400, pipeline="cad", **kw)
        relax = [s for s in r["stages"] if s["kind"] == "relax"][0]
        return relax["figures"]["feature_rails"]

    assert rails() == [0, 0]
    assert rails(feature_edges=ring) == [1, 1]
    assert rails(feature_edges=ring.tolist()) == [1, 1]
