"""Coarsens every mesh file of a folder, one file per process, from Python.

    python batch.py IN_DIR OUT_DIR [--vertices N | --ratio R] [--pipeline NAME] [--workers K]

Writes OUT_DIR/<name>.ply for every .obj/.ply/.stl/.off of IN_DIR and prints one line per
file (its counts and seconds, or its error); a file that fails does not stop the others.
The exit code is 1 when any file failed.

The same `coarsen_one` runs unchanged as a Dask or Ray task (docs/python.md).
"""

import argparse
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

EXTENSIONS = {".obj", ".ply", ".stl", ".off"}


def init_worker(threads):
    """Runs first in every worker process: the threads each run may use (RAYON_NUM_THREADS
    is read when the first run starts)."""
    os.environ["RAYON_NUM_THREADS"] = str(threads)


def coarsen_one(src, dst, target, pipeline=None, params=None):
    """Reads `src`, remeshes it to `target` (e.g. {"vertices": 5000}), writes `dst`.
    Returns a small dict (picklable, JSON-able); raises on failure."""
    import coarsen  # imported in the worker

    start = time.perf_counter()
    V, F, attrs = coarsen.read(src, attributes=True)
    V2, F2, report, out_attrs = coarsen.remesh(
        V, F, attrs=attrs, pipeline=pipeline, params=params, name=str(src), attributes=True, **target
    )
    coarsen.write(dst, V2, F2, out_attrs)
    return {
        "input": str(src),
        "output": str(dst),
        "vertices": [report["input_vertices"], report["output_vertices"]],
        "faces": [report["input_faces"], report["output_faces"]],
        "seconds": time.perf_counter() - start,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("input", type=Path)
    ap.add_argument("output", type=Path)
    t = ap.add_mutually_exclusive_group(required=True)
    t.add_argument("--vertices", type=int)
    t.add_argument("--ratio", type=float)
    ap.add_argument("--pipeline", default=None)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args(argv)

    target = {"vertices": args.vertices} if args.vertices is not None else {"ratio": args.ratio}
    files = sorted(p for p in args.input.iterdir() if p.suffix.lower() in EXTENSIONS)
    args.output.mkdir(parents=True, exist_ok=True)
    # The cores shared out between the workers, so that they do not oversubscribe them.
    threads = max(1, (os.cpu_count() or 1) // args.workers)
    # "spawn": fresh interpreters. A forked child of a process that has already run
    # coarsen would inherit a thread pool whose threads it does not have.
    ctx = multiprocessing.get_context("spawn")
    failed = 0
    with ProcessPoolExecutor(args.workers, mp_context=ctx, initializer=init_worker, initargs=(threads,)) as pool:
        jobs = {
            pool.submit(coarsen_one, src, args.output / (src.stem + ".ply"), target, args.pipeline): src
            for src in files
        }
        for job in as_completed(jobs):
            src = jobs[job]
            try:
                r = job.result()
                print(
                    f"{src.name}: {r['vertices'][0]} -> {r['vertices'][1]} vertices, "
                    f"{r['faces'][0]} -> {r['faces'][1]} faces in {r['seconds']:.2f} s"
                )
            except Exception as e:  # one file's failure is reported; the rest go on
                failed += 1
                print(f"{src.name}: failed: {type(e).__name__}: {e}")
    print(f"{len(files) - failed} done, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
