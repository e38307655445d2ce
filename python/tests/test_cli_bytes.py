"""Python writes the command's bytes: every shipped pipeline on the bunny."""

import subprocess

import pytest

import coarsen


@pytest.fixture(scope="module")
def bunny(data_dir):
    path = data_dir / "stanford-bunny.obj"
    V, F, attrs = coarsen.read(path, attributes=True)
    return path, V, F, attrs


@pytest.mark.parametrize("name", [p["name"] for p in coarsen.pipelines()])
def test_python_and_the_command_write_the_same_bytes(name, bunny, cli, tmp_path):
    path, V, F, attrs = bunny
    by_cli = tmp_path / "cli.ply"
    o = subprocess.run(
        [cli, "run", name, str(path), "-o", str(by_cli), "-q", "--vertices", "3000"],
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
    )
    assert o.returncode == 0, o.stderr
    V2, F2, report, out_attrs = coarsen.remesh(
        V, F, attrs=attrs, vertices=3000, pipeline=name, attributes=True
    )
    by_python = tmp_path / "python.ply"
    coarsen.write(by_python, V2, F2, out_attrs)
    assert by_cli.read_bytes() == by_python.read_bytes(), f"{name}: Python's output differs"
