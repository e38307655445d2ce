"""The batch example of docs/python.md runs on a folder of small generated meshes."""

import subprocess
import sys
from pathlib import Path

import coarsen
from conftest import REPO, subdivide, torus

BATCH = REPO / "python" / "examples" / "batch.py"


def test_the_batch_example_coarsens_a_folder_in_worker_processes(tmp_path, demo):
    src = tmp_path / "in"
    src.mkdir()
    coarsen.write(src / "torus.obj", *subdivide(*torus()))
    coarsen.write(src / "sphere.ply", *demo)
    (src / "broken.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    (src / "notes.txt").write_text("not a mesh")
    out = tmp_path / "out"
    o = subprocess.run(
        [sys.executable, str(BATCH), str(src), str(out), "--vertices", "400", "--workers", "2"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert o.returncode == 1, o.stdout + o.stderr  # the broken file fails, alone
    lines = o.stdout.splitlines()
    assert lines[-1] == "2 done, 1 failed", o.stdout
    assert any(line.startswith("broken.off: failed: CoarsenError:") for line in lines), o.stdout
    for name in ("torus", "sphere"):
        V, F = coarsen.read(out / f"{name}.ply")
        assert len(V) == 400 and len(F) > 0
    assert not (out / "broken.ply").exists()
