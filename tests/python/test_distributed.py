"""facetree.distributed: the build's stages as tasks of a dask.distributed LocalCluster give the bytes
of `facetree build` at the same cap, with 1, 2 or 3 worker processes, and when a worker is killed
during the cells stage; a task that fails on bad input raises the reader's error at the caller and
leaves no work directory."""
import os
import signal
import subprocess
import threading
import time

import pytest

import facetree

distributed = pytest.importorskip("distributed")
import facetree.distributed as fd  # noqa: E402


def generate(cli, path, triangles):
    subprocess.run([str(cli), "gen", "terrain", "-n", str(triangles), "-o", str(path), "--shuffle-faces"],
                   check=True, capture_output=True)


def built(cli, mesh, out):
    subprocess.run([str(cli), "build", str(mesh), "-o", str(out), "--memory", "64M"], check=True,
                   capture_output=True)
    return out.read_bytes()


def mesh_and_bytes(cli, factory, name, triangles):
    """A shuffled terrain of about `triangles` faces and the bytes `facetree build --memory 64M`
    makes of it."""
    directory = factory.mktemp(name)
    mesh = directory / f"{name}.ply"
    generate(cli, mesh, triangles)
    return mesh, built(cli, mesh, directory / "whole.fch")


@pytest.fixture(scope="module")
def terrain(cli, tmp_path_factory):
    return mesh_and_bytes(cli, tmp_path_factory, "terrain", 2_000_000)


@pytest.fixture(scope="module")
def small(cli, tmp_path_factory):
    return mesh_and_bytes(cli, tmp_path_factory, "small", 300_000)


def local_client(workers):
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    return distributed.Client(cluster), cluster


def test_two_workers_give_the_bytes_of_build(terrain, tmp_path):
    mesh, whole = terrain
    stages = []
    work = tmp_path / "work"
    report = fd.build(mesh, tmp_path / "dask.fch", work_dir=work, memory="64M",
                      progress=lambda stage, fraction: stages.append(stage))
    assert (tmp_path / "dask.fch").read_bytes() == whole
    assert report["out_of_core"] and report["cells_tasks"] >= 8
    assert report["file_bytes"] == len(whole)
    assert stages[0] == "plan" and stages[-1] == "finish" and stages.count("cells") == report["cells_tasks"]
    assert not work.exists(), "the work directory goes with the build"


@pytest.mark.parametrize("workers", [1, 3])
def test_any_number_of_workers_gives_the_same_bytes(small, tmp_path, workers):
    mesh, whole = small
    client, cluster = local_client(workers)
    try:
        fd.build(mesh, tmp_path / "dask.fch", client, memory="64M", cell_tasks=7)
    finally:
        client.close()
        cluster.close()
    assert (tmp_path / "dask.fch").read_bytes() == whole


def test_a_worker_killed_during_the_cells_stage_loses_nothing(terrain, tmp_path):
    mesh, whole = terrain
    work = tmp_path / "work"
    client, cluster = local_client(2)
    killed = []

    def kill_a_worker_once_cells_are_done():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if work.exists() and any(p.name.endswith(".manifest") and p.name.startswith("cells-")
                                     for p in work.iterdir()):
                pids = client.run(os.getpid)
                pid = sorted(pids.values())[0]
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
            time.sleep(0.05)

    killer = threading.Thread(target=kill_a_worker_once_cells_are_done)
    killer.start()
    try:
        report = fd.build(mesh, tmp_path / "dask.fch", client, work_dir=work, memory="64M", cell_tasks=24)
    finally:
        killer.join()
        client.close()
        cluster.close()
    assert killed, "no worker was killed: the cells stage ended before the test could"
    assert report["cells_tasks"] == 24
    assert (tmp_path / "dask.fch").read_bytes() == whole


def test_bad_input_raises_the_readers_error_and_leaves_no_work(cli, shared_data, tmp_path):
    truncated = tmp_path / "truncated.ply"
    truncated.write_bytes((shared_data / "bunny_zipper.ply.zst").read_bytes()[:5000])
    result = subprocess.run([str(cli), "build", str(truncated), "-o", str(tmp_path / "x.fch")],
                            capture_output=True, text=True)
    assert result.returncode == 3
    work = tmp_path / "work"
    with pytest.raises(facetree.InputError) as raised:
        fd.build(truncated, tmp_path / "x.fch", work_dir=work, memory="64M", retries=0)
    assert str(raised.value) == result.stderr[len("facetree: "):].strip()
    assert raised.value.exit_code == 3
    assert not work.exists()
    assert not (tmp_path / "x.fch").exists()
