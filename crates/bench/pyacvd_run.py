"""One pyacvd run for `coarsen-bench pyacvd`: read a mesh, optionally subdivide it, cluster
its points, build the remesh and save it; print one line of `key=value` timings.

    python3 pyacvd_run.py IN CLUSTERS SUBDIVISIONS OUT

Times are seconds from `time.perf_counter`, taken around pyacvd's own calls: `read` (pyvista
reads the file), `setup` (pyacvd's `Clustering`: its point weights and neighbour lists),
`subdivide` (which sets up the subdivided mesh's weights and neighbour lists again),
`cluster` and `mesh` (`create_mesh`). Saving the output is not timed.
"""

import sys
import time
import warnings


def main() -> None:
    path, clusters, subdivisions, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    warnings.simplefilter("ignore")
    import pyacvd
    import pyvista

    t = [time.perf_counter()]
    mesh = pyvista.read(path)
    t.append(time.perf_counter())
    clus = pyacvd.Clustering(mesh)
    t.append(time.perf_counter())
    if subdivisions > 0:
        clus.subdivide(subdivisions)
    t.append(time.perf_counter())
    clus.cluster(clusters)
    t.append(time.perf_counter())
    remesh = clus.create_mesh()
    t.append(time.perf_counter())
    remesh.save(out)
    names = ["read", "setup", "subdivide", "cluster", "mesh"]
    parts = " ".join(f"{n}={b - a}" for n, a, b in zip(names, t, t[1:]))
    print(f"{parts} total={t[-1] - t[0]} vertices={remesh.n_points} faces={remesh.n_cells}")


if __name__ == "__main__":
    main()
