"""Every shipped pipeline runs from Python, on a small generated mesh."""

import pytest

import coarsen

NAMES = [p["name"] for p in coarsen.pipelines()]


@pytest.mark.parametrize("name", NAMES)
def test_every_shipped_pipeline_runs(name, demo):
    V, F = demo
    # Every shipped pipeline takes a vertex target (those that do not need one ignore it).
    V2, F2, report = coarsen.remesh(V, F, vertices=500, pipeline=name)
    assert report["pipeline"] == name
    assert len(F2) > 0 and F2.max() < len(V2)
    assert len(report["stages"]) == report["stages"][-1]["index"]
    exact = ("adaptive-cvt", "adaptive-cvt-r05", "cad", "uniform-cvt", "goal", "lod", "qem", "svec")
    if name in exact + ("svec-then-cvt",):
        assert len(V2) == 500
