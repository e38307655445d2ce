"""Bad input raises a Python exception with the command's message, and never takes the
interpreter down."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import coarsen
from conftest import torus

TRI_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
TRI_F = np.array([[0, 1, 2]])


def raises(exc, match, *args, **kwargs):
    with pytest.raises(exc, match=match) as e:
        coarsen.remesh(*args, **kwargs)
    return str(e.value)


def test_non_finite_coordinates_name_the_vertex():
    for bad in (np.nan, np.inf, -np.inf):
        V = TRI_V.copy()
        V[1, 1] = bad
        raises(ValueError, r"^mesh: vertex 1", V, TRI_F, vertices=3)


def test_indices_out_of_range():
    m = raises(ValueError, "face 0 is", TRI_V, [[0, 1, 3]], vertices=3)
    assert m == "face 0 is [0, 1, 3], but there are only 3 vertices (indices 0 to 2)"
    raises(ValueError, r"^F: face 0 is \[0, -1, 2\]: a negative vertex index", TRI_V, [[0, -1, 2]])
    raises(ValueError, r"^F: face 0 is .*beyond 32 bits", TRI_V, np.array([[0, 1, 2**32]]))


def test_empty_arrays():
    v = {"vertices": 3}
    raises(ValueError, "^mesh: no face left after clean-up", np.zeros((0, 3)), np.zeros((0, 3), int), **v)
    raises(ValueError, "but there are only 0 vertices", np.zeros((0, 3)), TRI_F, **v)
    raises(ValueError, "^mesh: no face left after clean-up", TRI_V, np.zeros((0, 3), int), **v)
    # Zero-area faces only: nothing is left either.
    raises(ValueError, "^mesh: no face left after clean-up", np.zeros((3, 3)), TRI_F, **v)


@pytest.mark.parametrize(
    "V, F, match",
    [
        (np.array([["a", "b", "c"]] * 3), TRI_F, r"^V: expected real numbers .* got dtype <U1"),
        (TRI_V.astype(complex), TRI_F, r"^V: expected real numbers .* got dtype complex128"),
        (np.array([[None] * 3] * 3), TRI_F, r"^V: expected real numbers .* got dtype object"),
        (TRI_V > 0, TRI_F, r"^V: expected real numbers .* got dtype bool"),
        (TRI_V, TRI_F.astype(float), r"^F: expected integer vertex indices, got dtype float64"),
        (TRI_V, np.array([["0", "1", "2"]]), r"^F: expected integer vertex indices, got dtype <U1"),
        (TRI_V[:, :2], TRI_F, r"^V: expected shape \(n, 3\), got \(3, 2\)"),
        (TRI_V.ravel(), TRI_F, r"^V: expected shape \(n, 3\), got \(9,\)"),
        (TRI_V[None], TRI_F, r"^V: expected shape \(n, 3\), got \(1, 3, 3\)"),
        (TRI_V, [[0, 1, 2, 0]], r"^F: expected shape \(m, 3\), got \(1, 4\)"),
        (TRI_V, [0, 1, 2], r"^F: expected shape \(m, 3\), got \(3,\)"),
        ([[0, 0, 0], [1, 0]], TRI_F, r"^V: not an array of shape \(n, 3\)"),
        (TRI_V, None, r"^F: missing"),
    ],
)
def test_wrong_dtypes_and_shapes_name_the_argument(V, F, match):
    raises(ValueError, match, V, F)


def test_bad_targets_and_params(demo):
    V, F = demo
    raises(ValueError, "one target at most", V, F, vertices=10, ratio=0.5)
    raises(ValueError, r"^vertices: expected a non-negative integer", V, F, vertices=-1)
    raises(ValueError, r"^vertices: expected a non-negative integer", V, F, vertices=10.5)
    raises(ValueError, r"^params\['relax.sweeps'\]: expected a bool", V, F, params={"relax.sweeps": [1]})
    raises(ValueError, "^params: keys are", V, F, params={1: 2})
    raises(ValueError, r"^ratio: expected a number", V, F, ratio="half")
    raises(ValueError, "attribute `k`: expected 10242 values", V, F, attrs={"vertex": {"k": [1.0]}})


def test_unknown_pipeline_and_bad_params_have_the_commands_message(demo, cli, tmp_path):
    V, F = demo
    v = {"vertices": 100}
    cases = [
        (dict(v, pipeline="nope"), ["--vertices", "100"]),
        (dict(v, pipeline="uniform-cvt", params={"relax.sweeps": 5000}), ["--vertices", "100", "--set", "relax.sweeps=5000"]),
        (dict(v, pipeline="uniform-cvt", params={"relax.sweepz": 5}), ["--vertices", "100", "--set", "relax.sweepz=5"]),
        (dict(pipeline="qem", ratio=1.5), ["--ratio", "1.5"]),
        (dict(pipeline="qem"), []),
    ]
    for kwargs, args in cases:
        with pytest.raises(ValueError) as e:
            coarsen.remesh(V, F, **kwargs)
        cmd = [cli, "run", kwargs["pipeline"], "-o", str(tmp_path / "x.ply"), *args]
        o = subprocess.run(cmd, capture_output=True, text=True, stdin=subprocess.DEVNULL)
        assert o.returncode == 2, o.stderr
        assert o.stderr.strip() == f"error: {e.value}", (o.stderr, str(e.value))


def test_hostile_arrays_never_take_the_interpreter_down():
    """Random small meshes with every kind of damage, in a child interpreter: each call
    returns or raises ValueError / CoarsenError, and the child exits normally."""
    script = textwrap.dedent(
        """
        import numpy as np, coarsen
        rng = np.random.default_rng(7)
        outcomes = {}
        pipelines = [p["name"] for p in coarsen.pipelines()]
        for i in range(150):
            n = int(rng.integers(0, 40))
            m = int(rng.integers(0, 60))
            V = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-300, 300)
            if n and rng.random() < 0.2:
                V[rng.integers(n), rng.integers(3)] = rng.choice([np.nan, np.inf, -np.inf])
            F = rng.integers(0, max(n, 1) + (2 if rng.random() < 0.2 else 0), size=(m, 3))
            if rng.random() < 0.3 and n > 2:
                F[:, 1] = F[:, 0]  # degenerate
            target = [{"vertices": int(rng.integers(0, 50))}, {"ratio": float(rng.random())},
                      {"faces": int(rng.integers(0, 80))}, {}][i % 4]
            try:
                V2, F2, r = coarsen.remesh(V, F, pipeline=pipelines[i % len(pipelines)], **target)
                assert len(F2) == 0 or F2.max() < len(V2)
                kind = "ok"
            except (ValueError, coarsen.CoarsenError) as e:
                kind = type(e).__name__
            outcomes[kind] = outcomes.get(kind, 0) + 1
        print(outcomes)
        """
    )
    o = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert o.returncode == 0, o.stderr[-3000:]
    assert "ValueError" in o.stdout, o.stdout


def test_bad_feature_edges_are_named():
    V, F = torus()
    raises(ValueError, r"^feature_edges: expected shape \(m, 2\)", V, F, feature_edges=F)
    raises(ValueError, r"^feature_edges: edge 1 is \[0, -1\]", V, F, feature_edges=[[0, 1], [0, -1]])
    raises(ValueError, r"^feature_edges: expected integer", V, F, feature_edges=[[0.5, 1.0]])
    raises(ValueError, r"^feature_edges: marked edge 0 names vertex", V, F, feature_edges=[[0, len(V)]])
