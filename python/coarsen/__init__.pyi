"""Type stubs of the `coarsen` package (the docstrings are in `__init__.py`)."""

import os
from typing import Any, Dict, List, Literal, Mapping, Optional, Protocol, Tuple, TypeVar, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str
DEFAULT_PIPELINE: str

class CoarsenError(RuntimeError):
    """A run, a read, a write or a measurement failed; the message is the command's."""

Positions = npt.NDArray[np.float64]
"""(n, 3) float64 vertex positions."""
Faces = npt.NDArray[np.uint32]
"""(m, 3) uint32 vertex indices."""
Attrs = Dict[str, Dict[str, npt.NDArray[Any]]]
"""``{"vertex": {name: array}, "face": {name: array}}``."""
Report = Dict[str, Any]
"""A run report: the content of ``coarsen run --report``."""
Metrics = Dict[str, Any]
"""A metrics report: the content of ``coarsen metrics --json``."""
Param = Union[bool, int, float, str]
PathLike = Union[str, "os.PathLike[str]"]

class _Trimesh(Protocol):
    """A ``trimesh.Trimesh`` (duck-typed: trimesh is not a dependency)."""

    vertices: Any
    faces: Any

class _PolyData(Protocol):
    """A ``pyvista.PolyData`` of triangles (duck-typed: pyvista is not a dependency)."""

    points: Any
    faces: Any

MeshT = TypeVar("MeshT", _Trimesh, _PolyData)

@overload
def remesh(
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    *,
    vertices: Optional[int] = ...,
    faces: Optional[int] = ...,
    ratio: Optional[float] = ...,
    pipeline: Optional[PathLike] = ...,
    params: Optional[Mapping[str, Param]] = ...,
    attrs: Optional[Mapping[str, Mapping[str, npt.ArrayLike]]] = ...,
    attributes: Literal[False] = ...,
    weld: bool = ...,
    sanity: Optional[bool] = ...,
    name: str = ...,
    feature_edges: Optional[npt.ArrayLike] = ...,
) -> Tuple[Positions, Faces, Report]: ...
@overload
def remesh(
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    *,
    vertices: Optional[int] = ...,
    faces: Optional[int] = ...,
    ratio: Optional[float] = ...,
    pipeline: Optional[PathLike] = ...,
    params: Optional[Mapping[str, Param]] = ...,
    attrs: Optional[Mapping[str, Mapping[str, npt.ArrayLike]]] = ...,
    attributes: Literal[True],
    weld: bool = ...,
    sanity: Optional[bool] = ...,
    name: str = ...,
    feature_edges: Optional[npt.ArrayLike] = ...,
) -> Tuple[Positions, Faces, Report, Attrs]: ...
@overload
def remesh(
    V: MeshT,
    F: None = ...,
    *,
    vertices: Optional[int] = ...,
    faces: Optional[int] = ...,
    ratio: Optional[float] = ...,
    pipeline: Optional[PathLike] = ...,
    params: Optional[Mapping[str, Param]] = ...,
    attrs: Optional[Mapping[str, Mapping[str, npt.ArrayLike]]] = ...,
    attributes: Literal[False] = ...,
    weld: bool = ...,
    sanity: Optional[bool] = ...,
    name: str = ...,
    feature_edges: Optional[npt.ArrayLike] = ...,
) -> Tuple[MeshT, Report]: ...
@overload
def remesh(
    V: MeshT,
    F: None = ...,
    *,
    vertices: Optional[int] = ...,
    faces: Optional[int] = ...,
    ratio: Optional[float] = ...,
    pipeline: Optional[PathLike] = ...,
    params: Optional[Mapping[str, Param]] = ...,
    attrs: Optional[Mapping[str, Mapping[str, npt.ArrayLike]]] = ...,
    attributes: Literal[True],
    weld: bool = ...,
    sanity: Optional[bool] = ...,
    name: str = ...,
    feature_edges: Optional[npt.ArrayLike] = ...,
) -> Tuple[MeshT, Report, Attrs]: ...
@overload
def read(path: PathLike, attributes: Literal[False] = ...) -> Tuple[Positions, Faces]: ...
@overload
def read(path: PathLike, attributes: Literal[True]) -> Tuple[Positions, Faces, Attrs]: ...
@overload
def write(
    path: PathLike,
    V: npt.ArrayLike,
    F: npt.ArrayLike,
    attrs: Optional[Mapping[str, Mapping[str, npt.ArrayLike]]] = ...,
) -> None: ...
@overload
def write(
    path: PathLike,
    V: Union[_Trimesh, _PolyData],
    F: None = ...,
    attrs: Optional[Mapping[str, Mapping[str, npt.ArrayLike]]] = ...,
) -> None: ...
@overload
def metrics(
    V0: npt.ArrayLike,
    F0: npt.ArrayLike,
    V1: npt.ArrayLike,
    F1: npt.ArrayLike,
    /,
    *,
    samples_per_face: Optional[int] = ...,
) -> Metrics: ...
@overload
def metrics(
    mesh0: Union[_Trimesh, _PolyData],
    mesh1: Union[_Trimesh, _PolyData],
    /,
    *,
    samples_per_face: Optional[int] = ...,
) -> Metrics: ...
def stages() -> List[Dict[str, Any]]: ...
def pipelines() -> List[Dict[str, str]]: ...
def demo() -> Tuple[Positions, Faces]: ...
