"""The Python package's benchmark (not a test): coarsen.remesh against pyacvd on the bunny,
their peak memory, and the cost of the Python call over the Rust facade.

    python/bench/run            (sets up a venv with a release wheel, pyacvd and pyvista)
    python bench.py --timer PATH/TO/time_remesh [--bunny FILE] [--runs N] [--pyacvd-runs N]

1. Speed, in this one process, turn about: `coarsen.remesh(V, F, vertices=5000)` (the
   default pipeline, adaptive-cvt; uniform-cvt, pyacvd's own method, beside it) against
   pyacvd's `Clustering(mesh); subdivide(3); cluster(5000)` (and `create_mesh()`, shown
   apart). Medians; the ratio is coarsen's median over pyacvd's (goal <= 0.08).
2. Peak memory: each tool once in a child process of its own, which reports its peak
   resident set (VmHWM of /proc/self/status, native memory included), beside a child that
   only imports and reads the mesh.
3. The Python call over the facade: `time_remesh` (crates/coarsen/examples, a release
   build) runs `Remesher::run` on the same file, pipeline and target, in a process of its
   own that takes turns with this one run by run; the overhead is the median of the
   pairs' ratios (Python over Rust), less one (goal <= 5 %).
4. The conversions of the call alone, on the bunny and on the bunny subdivided 3×.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
VERTICES = 5000


def peak_mib():
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def child(tool, bunny):
    """One run in this (child) process; prints its peak memory as JSON."""
    import warnings

    warnings.simplefilter("ignore")
    if tool == "baseline-coarsen":
        import coarsen

        coarsen.read(bunny)
    elif tool.startswith("coarsen:"):
        import coarsen

        V, F = coarsen.read(bunny)
        coarsen.remesh(V, F, vertices=VERTICES, pipeline=tool.split(":", 1)[1])
    elif tool == "baseline-pyacvd":
        import pyacvd  # noqa: F401
        import pyvista

        pyvista.read(bunny)
    elif tool == "pyacvd":
        import pyacvd
        import pyvista

        clus = pyacvd.Clustering(pyvista.read(bunny))
        clus.subdivide(3)
        clus.cluster(VERTICES)
        clus.create_mesh()
    print(json.dumps({"tool": tool, "peak_mib": peak_mib()}))


def median_of(f, runs):
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return times


def main():
    ap = argparse.ArgumentParser(description="coarsen's Python benchmark")
    ap.add_argument("--bunny", default=str(REPO.parent / "shared" / "data" / "stanford-bunny.obj"))
    ap.add_argument("--timer", help="the time_remesh example binary (release build)")
    ap.add_argument("--runs", type=int, default=7, help="runs per block of coarsen (Python and Rust)")
    ap.add_argument("--pyacvd-runs", type=int, default=3)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.child, args.bunny)

    import warnings

    import coarsen
    import numpy as np

    warnings.simplefilter("ignore")
    V, F = coarsen.read(args.bunny)
    print(f"# coarsen {coarsen.__version__} on {Path(args.bunny).name} ({len(V)} vertices, {len(F)} faces)")
    print(f"# {time.strftime('%Y-%m-%d')}, {platform.machine()}, {os.cpu_count()} cores, "
          f"{platform.processor() or platform.platform()}, Python {platform.python_version()}, "
          f"numpy {np.__version__}")
    remesh = {
        p: (lambda p=p: coarsen.remesh(V, F, vertices=VERTICES, pipeline=p)) for p in ("adaptive-cvt", "uniform-cvt")
    }
    for f in remesh.values():
        f()  # warm: the thread pool, the first allocations

    # 1. Speed against pyacvd, in this process.
    import pyacvd
    import pyvista

    pv_mesh = pyvista.read(args.bunny)
    cluster_times, mesh_times = [], []
    for _ in range(args.pyacvd_runs):
        mesh = pv_mesh.copy()  # subdivide() changes the mesh Clustering was given, in place
        start = time.perf_counter()
        clus = pyacvd.Clustering(mesh)
        clus.subdivide(3)
        clus.cluster(VERTICES)
        middle = time.perf_counter()
        out = clus.create_mesh()
        end = time.perf_counter()
        cluster_times.append(middle - start)
        mesh_times.append(end - start)
    assert out.n_points == VERTICES
    py_times = {p: median_of(f, args.runs) for p, f in remesh.items()}
    pyacvd_med = statistics.median(cluster_times)
    pyacvd_all = statistics.median(mesh_times)
    print(f"\n## Speed, bunny to {VERTICES} vertices (medians; one process)\n")
    print("| tool | median s | runs | ÷ pyacvd (subdivide + cluster) | ÷ pyacvd (with create_mesh) |")
    print("| --- | --- | --- | --- | --- |")
    print(f"| pyacvd {pyacvd.__version__}: Clustering, subdivide(3), cluster | {pyacvd_med:.3f} | {args.pyacvd_runs} | 1.00 | |")
    print(f"| pyacvd, the same and create_mesh() | {pyacvd_all:.3f} | {args.pyacvd_runs} | | 1.00 |")
    for p, t in py_times.items():
        m = statistics.median(t)
        print(f"| coarsen.remesh, {p} | {m:.3f} | {args.runs} | {m / pyacvd_med:.3f} | {m / pyacvd_all:.3f} |")

    # 2. Peak memory, one child process each.
    print("\n## Peak memory (VmHWM of a child process running the tool once)\n")
    print("| child | peak MiB | over its baseline MiB |")
    print("| --- | --- | --- |")
    peaks = {}
    for tool in ("baseline-coarsen", "coarsen:adaptive-cvt", "coarsen:uniform-cvt", "baseline-pyacvd", "pyacvd"):
        o = subprocess.run(
            [sys.executable, __file__, "--child", tool, "--bunny", args.bunny],
            capture_output=True, text=True, check=True,
        )
        peaks[tool] = json.loads(o.stdout.strip().splitlines()[-1])["peak_mib"]
        base = peaks["baseline-pyacvd" if "pyacvd" in tool else "baseline-coarsen"]
        print(f"| {tool} | {peaks[tool]:.0f} | {'' if tool.startswith('baseline') else f'{peaks[tool] - base:.0f}'} |")

    # 3. The Python call over the Rust facade: the timer runs in a process of its own and
    # takes turns with this one run by run (a run of each, then again), so that what else
    # the machine does weighs on both alike; the overhead is the median of the pairs' ratios.
    if not args.timer:
        print("\n(no --timer: the overhead over the Rust facade is not measured)")
        return
    print("\n## The Python call over the Rust facade (release builds; run by run, turn about)\n")
    print("| pipeline | Rust median s | Python median s | overhead (median of pairs) | pairs |")
    print("| --- | --- | --- | --- | --- |")
    pairs = 3 * args.runs
    for p in ("adaptive-cvt", "uniform-cvt"):
        timer = subprocess.Popen(
            [args.timer, args.bunny, str(VERTICES), p, "-"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        )

        def rust_once():
            timer.stdin.write("run\n")
            timer.stdin.flush()
            return float(timer.stdout.readline())

        rust_once(), remesh[p]()  # warm both
        rust, python = [], []
        for i in range(pairs):
            if i % 2:  # which goes first alternates too
                python += median_of(remesh[p], 1)
                rust.append(rust_once())
            else:
                rust.append(rust_once())
                python += median_of(remesh[p], 1)
        timer.stdin.close()
        timer.wait()
        ratio = statistics.median(q / r for q, r in zip(python, rust))
        r, q = statistics.median(rust), statistics.median(python)
        print(f"| {p} | {r:.4f} | {q:.4f} | {100 * (ratio - 1):+.1f} % | {pairs} |")

    conversions(V, F)


def subdivide(V, F):
    """Every triangle split 1-to-4 at its edges' midpoints."""
    import numpy as np

    F = np.asarray(F, dtype=np.int64)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    edges, inv = np.unique(E, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    m, n = len(F), len(V)
    a, b, c = F.T
    ab, bc, ca = n + inv[:m], n + inv[m : 2 * m], n + inv[2 * m :]
    F2 = np.concatenate([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return np.concatenate([V, (V[edges[:, 0]] + V[edges[:, 1]]) / 2]), F2.astype(np.uint32)


def conversions(V, F):
    """What the Python call adds to a run: the arrays checked and turned into bytes, the
    mesh built from them and its bytes turned back into arrays (coarsen._coarsen.echo: the
    same conversions as remesh, without the run), on the bunny and on the bunny subdivided
    three times (4.4M faces)."""
    import coarsen
    from coarsen import _coarsen

    def through(V, F):
        P, T = coarsen._positions(V), coarsen._faces(F)
        positions, triangles, _, _ = _coarsen.echo(P, T)
        return coarsen._arrays(positions, triangles)

    print("\n## The conversions of the Python call alone (arrays in and out, no run)\n")
    print("| mesh | vertices | faces | median ms | runs |")
    print("| --- | --- | --- | --- | --- |")
    def big():
        v, f = V, F
        for _ in range(3):
            v, f = subdivide(v, f)
        return v, f

    for name, make, runs in (("bunny", lambda: (V, F), 21), ("bunny subdivided 3×", big, 5)):
        v, f = make()
        out = through(v, f)
        assert (out[0] == v).all() and (out[1] == f).all()
        t = statistics.median(median_of(lambda: through(v, f), runs))
        print(f"| {name} | {len(v)} | {len(f)} | {1000 * t:.1f} | {runs} |")

if __name__ == "__main__":
    main()
