//! The native half of the Python package `coarsen` (`coarsen._coarsen`): a thin layer over
//! the facade crate `coarsen`. The Python half (`python/coarsen/__init__.py`) checks and
//! converts the arrays (dtype, shape, index range) and hands them over as C-contiguous
//! `(n, 3)` float64 positions and `(m, 3)` uint32 faces (attribute columns as bytes); what
//! comes back are flat numpy arrays that own the run's output (no copy), reshaped there.
//!
//! A run goes on a worker thread while the calling thread waits with the GIL released, in
//! short slices, taking the GIL back between them to look for signals: Ctrl-C raises the
//! facade's cancel flag, waits for the run to stop and re-raises `KeyboardInterrupt`.

use coarsen::plugin::AttrValues;
use coarsen::{DVec3, Error, Mesh, Target};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

pyo3::create_exception!(
    coarsen,
    CoarsenError,
    PyRuntimeError,
    "A run, a read, a write or a measurement failed (a bad mesh file, a stage's error, a bug); \
     the message is the one the `coarsen` command prints."
);

/// How long the waiting thread lets the GIL go before it looks for signals again.
const SLICE: Duration = Duration::from_millis(20);

/// The worker's stack: as big as a main thread's and more, since a stack overflow would
/// abort the interpreter (only its pages in use are ever committed).
const WORKER_STACK: usize = 64 << 20;

/// A facade error as a Python exception: the request's own errors (a bad pipeline,
/// parameter or target) are `ValueError`, and so are an input mesh's when it came as
/// arrays (`arrays`: they are bad arguments); every other is `CoarsenError`.
fn py_err(e: Error, arrays: bool) -> PyErr {
    let message = e.to_string();
    if e.is_usage() || (arrays && matches!(e, Error::Input { .. })) {
        PyValueError::new_err(message)
    } else {
        CoarsenError::new_err(message)
    }
}

/// The rows of a C-contiguous `(n, 3)` array.
fn rows<T: numpy::Element + Copy, const N: usize>(
    a: &PyReadonlyArray2<'_, T>,
    what: &str,
) -> PyResult<Vec<[T; N]>> {
    let flat = a
        .as_slice()
        .map_err(|_| PyValueError::new_err(format!("{what}: not a C-contiguous array")))?;
    if a.shape()[1] != N {
        return Err(PyValueError::new_err(format!(
            "{what}: not of shape (n, {N})"
        )));
    }
    Ok(flat
        .chunks_exact(N)
        .map(|c| std::array::from_fn(|i| c[i]))
        .collect())
}

/// A flat numpy array that takes `values` over (no copy).
fn flat<'py, T: numpy::Element>(py: Python<'py>, values: Vec<T>) -> Bound<'py, PyArray1<T>> {
    values.into_pyarray(py)
}

/// One attribute column as `(kind, flat values)`: `scalar` (float64), `vec2`/`vec3`
/// (float64 pairs/triples), `label` (uint32) or `color` (uint8 triples).
fn column_array<'py>(py: Python<'py>, v: &AttrValues) -> (&'static str, Bound<'py, PyAny>) {
    match v {
        AttrValues::Scalar(x) => ("scalar", flat(py, x.clone()).into_any()),
        AttrValues::Vec2(x) => (
            "vec2",
            flat(py, x.iter().flat_map(|p| p.to_array()).collect()).into_any(),
        ),
        AttrValues::Vec3(x) => (
            "vec3",
            flat(py, x.iter().flat_map(|p| p.to_array()).collect()).into_any(),
        ),
        AttrValues::Label(x) => ("label", flat(py, x.clone()).into_any()),
        AttrValues::Color(x) => (
            "color",
            flat(py, x.iter().flatten().copied().collect()).into_any(),
        ),
    }
}

/// A column from its kind (as [`column_array`] names them) and its values' bytes.
fn column_from(name: &str, kind: &str, bytes: &[u8]) -> PyResult<AttrValues> {
    let width = match kind {
        "scalar" | "vec2" | "vec3" => 8,
        "label" => 4,
        "color" => 1,
        _ => {
            return Err(PyValueError::new_err(format!(
                "attribute `{name}`: unknown kind `{kind}` (scalar, vec2, vec3, label, color)"
            )));
        }
    };
    let f64s = || -> Vec<f64> {
        bytes
            .chunks_exact(width)
            .map(|c| f64::from_ne_bytes(c.try_into().expect("8 bytes")))
            .collect()
    };
    Ok(match kind {
        "scalar" => AttrValues::Scalar(f64s()),
        "vec2" => AttrValues::Vec2(
            f64s()
                .chunks_exact(2)
                .map(|c| coarsen::plugin::DVec3::new(c[0], c[1], 0.0).truncate())
                .collect(),
        ),
        "vec3" => AttrValues::Vec3(
            f64s()
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0], c[1], c[2]))
                .collect(),
        ),
        "label" => AttrValues::Label(
            bytes
                .chunks_exact(4)
                .map(|c| u32::from_ne_bytes(c.try_into().expect("4 bytes")))
                .collect(),
        ),
        _ => AttrValues::Color(bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()),
    })
}

/// Attribute columns as `(name, kind, bytes)` triples.
type Columns<'py> = Vec<(String, String, Bound<'py, PyBytes>)>;

/// Positions as the Python half hands them over.
type Positions<'py> = PyReadonlyArray2<'py, f64>;
/// Faces as the Python half hands them over.
type Faces<'py> = PyReadonlyArray2<'py, u32>;

/// A mesh from the arrays and attribute columns; errors are `ValueError`s.
fn mesh_from(
    positions: &Positions<'_>,
    faces: &Faces<'_>,
    vertex_attrs: Columns<'_>,
    face_attrs: Columns<'_>,
) -> PyResult<Mesh> {
    let mut mesh = coarsen::mesh_from_arrays(rows(positions, "positions")?, rows(faces, "faces")?)
        .map_err(|e| py_err(e, true))?;
    for (domain, columns, n) in [
        ("vertex", vertex_attrs, mesh.n_vertices()),
        ("face", face_attrs, mesh.n_faces()),
    ] {
        for (name, kind, bytes) in columns {
            let values = column_from(&name, &kind, bytes.as_bytes())?;
            if values.len() != n {
                return Err(PyValueError::new_err(format!(
                    "{domain} attribute `{name}` has {} values for {n} {domain}s",
                    values.len()
                )));
            }
            match domain {
                "vertex" => mesh.vertex_attrs.insert(name, values),
                _ => mesh.face_attrs.insert(name, values),
            }
        }
    }
    Ok(mesh)
}

/// `(positions, faces, vertex columns, face columns)`: flat positions and faces, and each
/// column as `(name, kind, flat values)`.
type MeshArrays<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyList>,
    Bound<'py, PyList>,
);

/// The mesh as numpy arrays (its columns too when `attributes`).
fn mesh_arrays(py: Python<'_>, mesh: Mesh, attributes: bool) -> PyResult<MeshArrays<'_>> {
    let columns = |attrs: Vec<(&str, &AttrValues)>| -> PyResult<Bound<'_, PyList>> {
        let list = PyList::empty(py);
        if attributes {
            for (name, values) in attrs {
                let (kind, array) = column_array(py, values);
                list.append((name, kind, array))?;
            }
        }
        Ok(list)
    };
    let vertex_columns = columns(mesh.vertex_attrs.iter().collect())?;
    let face_columns = columns(mesh.face_attrs.iter().collect())?;
    let positions = flat(
        py,
        mesh.positions.iter().flat_map(|p| p.to_array()).collect(),
    );
    let faces = flat(py, mesh.faces.into_iter().flatten().collect());
    Ok((positions, faces, vertex_columns, face_columns))
}

/// How a run on the worker thread ended, seen from the calling thread.
enum Ended<T> {
    /// The work returned (or panicked: the panic comes back as an error).
    Done(T),
    /// A signal handler raised this exception (Ctrl-C's `KeyboardInterrupt`) while the
    /// work went on; the cancel flag was raised and the work's own end is `T`.
    Interrupted(PyErr, T),
}

/// Runs `work` on a worker thread while this thread waits with the GIL released, taking
/// it back every [`SLICE`] to run the signal handlers. When one raises an exception (Ctrl-C's
/// `KeyboardInterrupt`), it raises `cancel`, waits for the worker to stop and hands back
/// both. A panic of the work comes back as `CoarsenError`, the interpreter untouched.
fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &AtomicBool,
    work: impl FnOnce() -> T + Send,
) -> PyResult<Ended<T>> {
    let done: (Mutex<Option<std::thread::Result<T>>>, Condvar) = (Mutex::new(None), Condvar::new());
    // Waits up to `slice` (None: for good) for the worker's end; true when it has ended.
    let wait = |slice: Option<Duration>| -> bool {
        let (lock, cv) = &done;
        let guard = lock.lock().unwrap_or_else(|e| e.into_inner());
        let guard = match slice {
            Some(d) => {
                cv.wait_timeout_while(guard, d, |r| r.is_none())
                    .unwrap_or_else(|e| e.into_inner())
                    .0
            }
            None => cv
                .wait_while(guard, |r| r.is_none())
                .unwrap_or_else(|e| e.into_inner()),
        };
        guard.is_some()
    };
    let take = || -> PyResult<T> {
        let result = done
            .0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
            .expect("the worker left its result");
        result.map_err(|payload| {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic with no message".into());
            CoarsenError::new_err(format!(
                "internal error (a bug in coarsen; please report it with the input): {message}"
            ))
        })
    };
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("coarsen-run".into())
            .stack_size(WORKER_STACK)
            .spawn_scoped(s, || {
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
                let (lock, cv) = &done;
                *lock.lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
                cv.notify_all();
            })
            .map_err(|e| CoarsenError::new_err(format!("could not start a thread: {e}")))?;
        loop {
            if py.detach(|| wait(Some(SLICE))) {
                return Ok(Ended::Done(take()?));
            }
            if let Err(interrupt) = py.check_signals() {
                cancel.store(true, Ordering::Relaxed);
                py.detach(|| wait(None));
                return Ok(Ended::Interrupted(interrupt, take()?));
            }
        }
    })
}

/// What `remesh` hands back: the mesh's bytes and columns, and the run report as JSON.
type Remeshed<'py> = (MeshArrays<'py>, String);

/// Runs a pipeline on a mesh given as arrays (see `coarsen.remesh`).
#[pyfunction]
#[pyo3(signature = (positions, faces, *, vertex_attrs, face_attrs, name, pipeline, vertices, faces_target, ratio, sets, weld, sanity, attributes, feature_edges=None))]
#[allow(clippy::too_many_arguments)]
fn remesh<'py>(
    py: Python<'py>,
    positions: Positions<'py>,
    faces: Faces<'py>,
    vertex_attrs: Columns<'py>,
    face_attrs: Columns<'py>,
    name: String,
    pipeline: Option<String>,
    vertices: Option<u64>,
    faces_target: Option<u64>,
    ratio: Option<f64>,
    sets: Vec<(String, String)>,
    weld: bool,
    sanity: Option<bool>,
    attributes: bool,
    feature_edges: Option<Faces<'py>>,
) -> PyResult<Remeshed<'py>> {
    let target = match (vertices, faces_target, ratio) {
        (None, None, None) => None,
        (Some(n), None, None) => Some(Target::Vertices(n)),
        (None, Some(n), None) => Some(Target::Faces(n)),
        (None, None, Some(r)) => Some(Target::Ratio(r)),
        _ => {
            return Err(PyValueError::new_err(
                "give one target at most: vertices=, faces= or ratio=",
            ));
        }
    };
    let mut mesh = mesh_from(&positions, &faces, vertex_attrs, face_attrs)?;
    if let Some(edges) = &feature_edges {
        mesh.marked_edges = rows(edges, "feature_edges")?;
        mesh.validate_indices()
            .map_err(|e| PyValueError::new_err(format!("feature_edges: {e}")))?;
    }
    let cancel = AtomicBool::new(false);
    let run = run_interruptible(py, &cancel, || {
        let mut r = coarsen::Remesher::new().weld(weld).cancel(&cancel);
        if let Some(p) = &pipeline {
            r = r.pipeline(p.as_str());
        }
        if let Some(t) = target {
            r = r.target(t);
        }
        if let Some(s) = sanity {
            r = r.sanity(s);
        }
        for (path, value) in &sets {
            r = r.set(path, value);
        }
        r.run_input(coarsen::Input::new(mesh, name))
    })?;
    let done = match run {
        Ended::Done(run) => run.map_err(|e| py_err(e, true))?,
        Ended::Interrupted(interrupt, run) => {
            // The interrupt is what the caller sees; the run's own end (cancelled inside
            // a stage, or finished just before) is its context.
            if let Err(e) = run {
                interrupt.set_context(py, Some(py_err(e, true)));
            }
            return Err(interrupt);
        }
    };
    Ok((
        mesh_arrays(py, done.mesh, attributes)?,
        done.report.to_json(),
    ))
}

/// Reads a mesh file (see `coarsen.read`).
#[pyfunction]
fn read<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    attributes: bool,
) -> PyResult<MeshArrays<'py>> {
    let mesh = py
        .detach(|| coarsen::read(&path))
        .map_err(|e| py_err(e, false))?;
    mesh_arrays(py, mesh, attributes)
}

/// Writes a mesh file (see `coarsen.write`).
#[pyfunction]
fn write(
    py: Python<'_>,
    path: std::path::PathBuf,
    positions: Positions<'_>,
    faces: Faces<'_>,
    vertex_attrs: Columns<'_>,
    face_attrs: Columns<'_>,
) -> PyResult<()> {
    let mesh = mesh_from(&positions, &faces, vertex_attrs, face_attrs)?;
    py.detach(|| coarsen::write(&path, &mesh))
        .map_err(|e| py_err(e, false))
}

/// Measures an output mesh against its input (see `coarsen.metrics`); the report as JSON.
#[pyfunction]
#[pyo3(signature = (positions0, faces0, positions1, faces1, samples_per_face=None))]
fn metrics(
    py: Python<'_>,
    positions0: Positions<'_>,
    faces0: Faces<'_>,
    positions1: Positions<'_>,
    faces1: Faces<'_>,
    samples_per_face: Option<u32>,
) -> PyResult<String> {
    let input = mesh_from(&positions0, &faces0, vec![], vec![])?;
    let output = mesh_from(&positions1, &faces1, vec![], vec![])?;
    let mut opts = coarsen::MetricsOptions::default();
    if let Some(k) = samples_per_face {
        opts.fidelity.samples_per_face = k;
    }
    let report = py
        .detach(|| coarsen::metrics(&input, &output, &opts))
        .map_err(|e| py_err(e, true))?;
    serde_json::to_string(&report).map_err(|e| CoarsenError::new_err(e.to_string()))
}

/// Every registered stage with its parameters (see `coarsen.stages`).
#[pyfunction]
fn stages(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for s in coarsen::stages().map_err(|e| py_err(e, false))? {
        let params = PyList::empty(py);
        for p in &s.params {
            let d = PyDict::new(py);
            d.set_item("name", p.name)?;
            d.set_item("type", p.ty)?;
            d.set_item("default", p.default.as_deref())?;
            d.set_item("doc", p.doc.as_str())?;
            params.append(d)?;
        }
        let d = PyDict::new(py);
        d.set_item("kind", s.kind)?;
        d.set_item("summary", s.summary)?;
        d.set_item("crate", s.crate_name)?;
        d.set_item("params", params)?;
        list.append(d)?;
    }
    Ok(list)
}

/// The shipped pipelines (see `coarsen.pipelines`).
#[pyfunction]
fn pipelines(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for p in coarsen::pipelines() {
        let d = PyDict::new(py);
        d.set_item("name", p.name)?;
        d.set_item("description", p.description)?;
        d.set_item("text", p.text)?;
        list.append(d)?;
    }
    Ok(list)
}

/// The arrays through the conversions of a run, without the run (a mesh built from their
/// bytes, and its bytes handed back): what `python/bench/bench.py` measures the Python
/// call's own cost with.
#[pyfunction]
fn echo<'py>(
    py: Python<'py>,
    positions: Positions<'py>,
    faces: Faces<'py>,
) -> PyResult<MeshArrays<'py>> {
    let mesh = mesh_from(&positions, &faces, vec![], vec![])?;
    mesh_arrays(py, mesh, false)
}

/// The built-in demo mesh (see `coarsen.demo`).
#[pyfunction]
fn demo(py: Python<'_>) -> PyResult<MeshArrays<'_>> {
    mesh_arrays(py, coarsen::demo(), false)
}

/// The native half of the `coarsen` package: use `coarsen`, not this module.
#[pymodule]
mod _coarsen {
    #[pymodule_export]
    use super::{CoarsenError, demo, echo, metrics, pipelines, read, remesh, stages, write};

    #[pymodule_export]
    const DEFAULT_PIPELINE: &str = coarsen::DEFAULT_PIPELINE;

    #[pymodule_export]
    #[allow(non_upper_case_globals)]
    const __version__: &str = env!("CARGO_PKG_VERSION");
}
