"""coarsen: turns big, badly shaped triangle meshes into small, well-shaped ones that stay
close to the input.

The same clean-up, pipelines and output bytes as the ``coarsen`` command, on numpy arrays
(or a ``trimesh.Trimesh`` / ``pyvista.PolyData``)::

    import coarsen

    V, F = coarsen.read("bunny.obj")
    V2, F2, report = coarsen.remesh(V, F, vertices=5000)
    coarsen.write("bunny-5k.ply", V2, F2)
    print(coarsen.metrics(V, F, V2, F2)["quality"]["alpha_min_deg"])

Arrays: positions ``V`` are float64 ``(n, 3)``, faces ``F`` are ``(m, 3)`` vertex indices
(uint32 on the way out; any integer dtype on the way in). Attribute columns, where asked
for, are a dict ``{"vertex": {name: array}, "face": {name: array}}``: scalars float64
``(n,)``, 2-D and 3-D vectors float64 ``(n, 2)``/``(n, 3)``, labels uint32 ``(n,)``,
colours uint8 ``(n, 3)``.

Errors: ``ValueError`` for bad arguments (arrays of the wrong shape or dtype, indices out
of range, non-finite coordinates, an unknown pipeline, a bad parameter or target),
``CoarsenError`` (a ``RuntimeError``) for failed runs and files that cannot be read or
written; the messages are the ``coarsen`` command's. Ctrl-C cancels a run and raises
``KeyboardInterrupt``. Every call releases the GIL while it works.

The whole API, with examples: ``docs/python.md`` in the repository.
"""

from __future__ import annotations

import json
import math
import numbers
import os

import numpy as np

from . import _coarsen
from ._coarsen import DEFAULT_PIPELINE, CoarsenError

__version__ = _coarsen.__version__

__all__ = [
    "CoarsenError",
    "DEFAULT_PIPELINE",
    "demo",
    "metrics",
    "pipelines",
    "read",
    "remesh",
    "stages",
    "write",
]

_U32_MAX = 0xFFFFFFFF

# Attribute kinds: numpy dtype and values per element.
_KINDS = {
    "scalar": (np.float64, 1),
    "vec2": (np.float64, 2),
    "vec3": (np.float64, 3),
    "label": (np.uint32, 1),
    "color": (np.uint8, 3),
}


# ---------------------------------------------------------------------------------------
# Arrays in and out


def _positions(V, name="V"):
    """``V`` as a C-contiguous float64 (n, 3) array, or a ValueError naming it."""
    try:
        a = np.asarray(V)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{name}: not an array of shape (n, 3): {e}") from None
    if a.dtype.kind not in "fiu":
        raise ValueError(
            f"{name}: expected real numbers (float or integer dtype), got dtype {a.dtype}"
        )
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (n, 3), got {a.shape}")
    return np.ascontiguousarray(a, dtype=np.float64)


def _faces(F, name="F", width=3, what="face"):
    """``F`` as a C-contiguous uint32 (m, ``width``) array of vertex indices (faces, or
    edges with ``width=2``), or a ValueError naming it. Indices beyond the vertices are
    refused later, by the mesh's own check."""
    try:
        a = np.asarray(F)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{name}: not an array of shape (m, {width}): {e}") from None
    if a.dtype.kind not in "iu":
        raise ValueError(f"{name}: expected integer vertex indices, got dtype {a.dtype}")
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{name}: expected shape (m, {width}), got {a.shape}")
    if a.size and a.dtype != np.uint32:
        if a.dtype.kind == "i" and a.min() < 0:
            f = int(np.flatnonzero((a < 0).any(axis=1))[0])
            raise ValueError(f"{name}: {what} {f} is {a[f].tolist()}: a negative vertex index")
        if a.max() > _U32_MAX:
            f = int(np.flatnonzero((a > _U32_MAX).any(axis=1))[0])
            raise ValueError(
                f"{name}: {what} {f} is {a[f].tolist()}: an index beyond 32 bits "
                f"(coarsen meshes have at most {_U32_MAX} vertices)"
            )
    return np.ascontiguousarray(a, dtype=np.uint32)


def _column(domain, name, values, n):
    """One attribute column as ``(name, kind, bytes)``."""
    if not isinstance(name, str):
        raise ValueError(f"{domain} attribute names must be str, got {name!r}")
    what = f"{domain} attribute `{name}`"
    try:
        a = np.asarray(values)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{what}: not an array: {e}") from None
    if a.shape[:1] != (n,):
        raise ValueError(f"{what}: expected {n} values (one per {domain}), got shape {a.shape}")
    if a.dtype == np.uint8 and a.shape == (n, 3):
        kind = "color"
    elif a.dtype.kind in "iu" and a.ndim == 1:
        kind = "label"
        if a.size and (a.min() < 0 or a.max() > _U32_MAX):
            raise ValueError(f"{what}: labels must be in 0..=4294967295")
    elif a.dtype.kind == "f" and a.ndim == 1:
        kind = "scalar"
    elif a.dtype.kind == "f" and a.shape == (n, 2):
        kind = "vec2"
    elif a.dtype.kind == "f" and a.shape == (n, 3):
        kind = "vec3"
    else:
        raise ValueError(
            f"{what}: expected float (n,), (n, 2) or (n, 3), integer labels (n,) or uint8 "
            f"colours (n, 3); got dtype {a.dtype}, shape {a.shape}"
        )
    dtype, _ = _KINDS[kind]
    return (name, kind, np.ascontiguousarray(a, dtype=dtype).tobytes())


def _columns(attrs, n_vertices, n_faces):
    """The vertex and face columns of an attribute dict, for the native side."""
    if attrs is None:
        return [], []
    if not isinstance(attrs, dict) or not set(attrs) <= {"vertex", "face"}:
        raise ValueError('attrs: expected a dict {"vertex": {name: array}, "face": {name: array}}')
    return tuple(
        [_column(d, k, v, n) for k, v in (attrs.get(d) or {}).items()]
        for d, n in (("vertex", n_vertices), ("face", n_faces))
    )


def _arrays(positions, faces):
    """(n, 3) and (m, 3) views of the flat arrays the native side hands back (no copy)."""
    return positions.reshape(-1, 3), faces.reshape(-1, 3)


def _attrs(vertex_columns, face_columns):
    out = {}
    for domain, columns in (("vertex", vertex_columns), ("face", face_columns)):
        out[domain] = {}
        for name, kind, values in columns:
            width = _KINDS[kind][1]
            out[domain][name] = values if width == 1 else values.reshape(-1, width)
    return out


# ---------------------------------------------------------------------------------------
# trimesh and pyvista, duck-typed (neither is a dependency)


def _library(obj):
    """``"trimesh"`` or ``"pyvista"`` when ``obj`` is one of their meshes, else None."""
    for cls in type(obj).__mro__:
        root = (getattr(cls, "__module__", "") or "").split(".")[0]
        if root == "trimesh" and hasattr(obj, "vertices") and hasattr(obj, "faces"):
            return "trimesh"
        if root == "pyvista" and hasattr(obj, "points") and hasattr(obj, "faces"):
            return "pyvista"
    return None


def _pyvista_triangles(mesh):
    """The (m, 3) triangles of a pyvista.PolyData, refusing any other cell."""
    what = type(mesh).__name__
    if getattr(mesh, "n_strips", 0):
        raise ValueError(
            f"pyvista.{what}: has triangle strips; only triangles are supported: "
            "call mesh.triangulate() first"
        )
    flat = np.asarray(mesh.faces)
    whole = flat.size // 4
    heads = flat[: whole * 4].reshape(-1, 4)[:, 0]
    bad = np.flatnonzero(heads != 3)
    if bad.size:
        cell = int(bad[0])
        raise ValueError(
            f"pyvista.{what}: only triangle faces are supported, but face {cell} has "
            f"{int(heads[cell])} points: call mesh.triangulate() first"
        )
    if flat.size != whole * 4:
        raise ValueError(f"pyvista.{what}: its faces array is cut short ({flat.size} values)")
    return flat.reshape(-1, 4)[:, 1:]


def _unwrap(V, F, names=("V", "F")):
    """Positions, faces and a function that builds the caller's type from output arrays."""
    library = _library(V)
    if library is None:
        if F is None:
            raise ValueError(
                f"{names[1]}: missing (give positions and faces, or a trimesh.Trimesh or "
                "pyvista.PolyData)"
            )
        return _positions(V, names[0]), _faces(F, names[1]), None
    if F is not None:
        raise ValueError(f"{names[1]}: must be left out when {names[0]} is a {library} mesh")
    cls = type(V)
    if library == "trimesh":
        P, T = _positions(V.vertices, "trimesh.vertices"), _faces(V.faces, "trimesh.faces")

        def wrap(V2, F2):
            return cls(vertices=V2, faces=F2, process=False)

    else:
        P = _positions(V.points, "pyvista.points")
        T = _faces(_pyvista_triangles(V), "pyvista.faces")

        def wrap(V2, F2):
            flat = np.empty((len(F2), 4), dtype=np.int64)
            flat[:, 0] = 3
            flat[:, 1:] = F2
            return cls(V2, flat.ravel())

    return P, T, wrap


# ---------------------------------------------------------------------------------------
# Parameters


def _toml(path, value):
    """``value`` as the TOML literal ``--set PATH=VALUE`` would take."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        v = float(value)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    raise ValueError(
        f"params[{path!r}]: expected a bool, int, float or str, got {type(value).__name__}"
    )


def _sets(params):
    if params is None:
        return []
    if not isinstance(params, dict):
        raise ValueError('params: expected a dict such as {"relax.sweeps": 4}')
    out = []
    for path, value in params.items():
        if not isinstance(path, str):
            raise ValueError(f"params: keys are STAGE.PARAM strings, got {path!r}")
        out.append((path, _toml(path, value)))
    return out


def _count(name, value):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ValueError(f"{name}: expected a non-negative integer, got {value!r}")
    return int(value)


# ---------------------------------------------------------------------------------------
# The API


def remesh(
    V,
    F=None,
    *,
    vertices=None,
    faces=None,
    ratio=None,
    pipeline=None,
    params=None,
    attrs=None,
    attributes=False,
    weld=False,
    sanity=None,
    name="mesh",
    feature_edges=None,
):
    """Runs a pipeline on a mesh: the same clean-up, stages and output as ``coarsen run``.

    ``V, F``: positions (n, 3) and faces (m, 3); or a ``trimesh.Trimesh`` or
    ``pyvista.PolyData`` as ``V`` alone, and the output comes back as the same type.

    ``vertices=``, ``faces=`` or ``ratio=``: the target (one at most; none keeps the
    pipeline file's own). ``pipeline``: a shipped pipeline's name (``pipelines()``) or a
    pipeline file's path; default ``DEFAULT_PIPELINE``. ``params``: overrides as the
    command line's ``--set``, ``{"relax.sweeps": 4, "cluster.cvt.r": 0.5}`` (bool, int,
    float or str values). ``attrs``: input attribute columns, carried through the run as
    the command carries a file's. ``attributes=True`` also returns the output's columns.
    ``weld``: weld vertices at bit-identical positions first (``--weld``). ``sanity``:
    check the mesh after every stage (default: only in debug builds). ``name``: the input's
    name in the report and in errors. ``feature_edges``: (k, 2) vertex pairs the input
    marks as feature edges, whatever their angle (an OBJ file's ``l`` lines do the same):
    the stages that keep features (``pipeline="cad"``, ``params={"relax.features": True}``,
    ``simplify.qem.features``) keep them.

    Returns ``(V2, F2, report)`` (``(mesh2, report)`` for a trimesh or pyvista mesh), with
    the output's attribute dict appended when ``attributes=True``. ``report`` is the
    run report as a dict (the content of ``coarsen run --report``).

    Raises ``ValueError`` for bad arrays and requests, ``CoarsenError`` when the run fails,
    ``KeyboardInterrupt`` when Ctrl-C cancels it (the run stops at its next progress
    report).
    """
    P, T, wrap = _unwrap(V, F)
    if sum(t is not None for t in (vertices, faces, ratio)) > 1:
        raise ValueError("give one target at most: vertices=, faces= or ratio=")
    if ratio is not None and (isinstance(ratio, bool) or not isinstance(ratio, numbers.Real)):
        raise ValueError(f"ratio: expected a number, got {ratio!r}")
    if pipeline is not None and not isinstance(pipeline, (str, os.PathLike)):
        raise ValueError(f"pipeline: expected a name or a path, got {pipeline!r}")
    vertex_columns, face_columns = _columns(attrs, len(P), len(T))
    edges = None
    if feature_edges is not None:
        edges = _faces(feature_edges, "feature_edges", width=2, what="edge")
    (positions, triangles, vc, fc), report = _coarsen.remesh(
        P,
        T,
        vertex_attrs=vertex_columns,
        face_attrs=face_columns,
        name=str(name),
        pipeline=None if pipeline is None else os.fspath(pipeline),
        vertices=_count("vertices", vertices),
        faces_target=_count("faces", faces),
        ratio=None if ratio is None else float(ratio),
        sets=_sets(params),
        weld=bool(weld),
        sanity=None if sanity is None else bool(sanity),
        attributes=bool(attributes),
        feature_edges=edges,
    )
    V2, F2 = _arrays(positions, triangles)
    out = (V2, F2) if wrap is None else (wrap(V2, F2),)
    out += (json.loads(report),)
    if attributes:
        out += (_attrs(vc, fc),)
    return out


def read(path, attributes=False):
    """Reads a mesh file (OBJ, PLY, STL or OFF, by its extension), an STL file's coincident
    corners welded as a run welds them.

    Returns ``(V, F)``, or ``(V, F, attrs)`` with ``attributes=True`` (the file's vertex
    and face attribute columns: normals, texture coordinates, colours, scalars).
    Raises ``CoarsenError`` when the file cannot be read (the message names the file and
    where it is wrong).
    """
    positions, triangles, vc, fc = _coarsen.read(os.fspath(path), bool(attributes))
    V, F = _arrays(positions, triangles)
    return (V, F, _attrs(vc, fc)) if attributes else (V, F)


def write(path, V, F=None, attrs=None):
    """Writes a mesh file in the format of its extension (binary PLY for ``.ply``, the
    bytes ``coarsen run -o`` writes), through a temporary file and a rename: a failure
    never leaves a half-written file.

    ``V, F`` as for ``remesh`` (or a trimesh / pyvista mesh as ``V``); ``attrs``: attribute
    columns to write where the format holds them.
    """
    P, T, _ = _unwrap(V, F)
    vertex_columns, face_columns = _columns(attrs, len(P), len(T))
    _coarsen.write(os.fspath(path), P, T, vertex_columns, face_columns)


def metrics(*meshes, samples_per_face=None):
    """Measures an output mesh against its input: ``metrics(V0, F0, V1, F1)`` or
    ``metrics(mesh0, mesh1)`` for trimesh / pyvista meshes. Both are cleaned as a run's
    input is, then measured as ``coarsen metrics --json`` measures them.

    Returns the report as a dict: ``quality`` (angles, shape quality), ``fidelity``
    (Hausdorff and mean distances, in % of the input's bounding-box diagonal), ``validity``,
    ``features`` (how far the input's sharp edges lie from the output, and how many of their
    corners it keeps as vertices).
    ``samples_per_face``: fidelity samples per face (default 10, the command's).
    """
    if len(meshes) == 4:
        (P0, T0, _), (P1, T1, _) = (
            _unwrap(meshes[0], meshes[1], ("V0", "F0")),
            _unwrap(meshes[2], meshes[3], ("V1", "F1")),
        )
    elif len(meshes) == 2:
        (P0, T0, _), (P1, T1, _) = (
            _unwrap(meshes[0], None, ("mesh0", "F0")),
            _unwrap(meshes[1], None, ("mesh1", "F1")),
        )
    else:
        raise ValueError(
            f"metrics: expected (V0, F0, V1, F1) or (mesh0, mesh1), got {len(meshes)} arguments"
        )
    k = _count("samples_per_face", samples_per_face)
    return json.loads(
        _coarsen.metrics(P0, T0, P1, T1, k)
    )


def stages():
    """Every registered stage, as ``coarsen stages`` lists them: a list of dicts with
    ``kind``, ``summary``, ``crate`` and ``params`` (each ``name``, ``type``, ``default``
    as TOML or None, ``doc``)."""
    return _coarsen.stages()


def pipelines():
    """The shipped pipelines: a list of dicts with ``name`` (for ``remesh(pipeline=…)``),
    ``description`` and ``text`` (the pipeline file)."""
    return _coarsen.pipelines()


def demo():
    """The built-in demo mesh, a bumpy sphere of 10,242 vertices: ``(V, F)``."""
    positions, triangles, _, _ = _coarsen.demo()
    return _arrays(positions, triangles)
