"""facetree.distributed: the build's stages as tasks of a dask.distributed LocalCluster give the bytes
of `facetree build` at the same cap, with 1, 2 or 3 worker processes, for a binary PLY or STL read in
ranges and a mesh read whole, and when a worker is killed during the cells stage; a task that fails on bad
input raises the reader's error at the caller and leaves no work directory."""
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


def built(cli, mesh, out, options):
    subprocess.run([str(cli), "build", str(mesh), "-o", str(out), "--memory", "64M", *options],
                   check=True, capture_output=True)
    return out.read_bytes()


def mesh_and_bytes(cli, factory, name, triangles, options=(), suffix=".ply"):
    """A shuffled terrain of about `triangles` faces (a binary PLY, or STL) and the bytes
    `facetree build --memory 64M` makes of it with `options`."""
    directory = factory.mktemp(name)
    mesh = directory / f"{name}{suffix}"
    generate(cli, mesh, triangles)
    return mesh, built(cli, mesh, directory / "whole.fch", options)


# The small mesh fits the cap; cells of at most this many faces take it out of core all the same.
SMALL_CELL_FACES = 8_000


@pytest.fixture(scope="module")
def small_stl(cli, tmp_path_factory):
    return mesh_and_bytes(cli, tmp_path_factory, "stl", 100_000, ["--cell-faces", str(SMALL_CELL_FACES)],
                          suffix=".stl")


@pytest.fixture(scope="module")
def terrain(cli, tmp_path_factory):
    return mesh_and_bytes(cli, tmp_path_factory, "terrain", 2_000_000)


@pytest.fixture(scope="module")
def small(cli, tmp_path_factory):
    return mesh_and_bytes(cli, tmp_path_factory, "small", 100_000,
                          ["--cell-faces", str(SMALL_CELL_FACES)])


def local_client(workers):
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    return distributed.Client(cluster), cluster


def test_two_workers_one_killed_during_the_cells_stage_give_the_bytes_of_build(terrain, tmp_path):
    mesh, whole = terrain
    stages = []
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
            time.sleep(0.02)

    killer = threading.Thread(target=kill_a_worker_once_cells_are_done)
    killer.start()
    try:
        # More tasks than the defaults give 2M faces (2 read tasks, 4 cells tasks, 1 node task).
        report = fd.build(mesh, tmp_path / "dask.fch", client, work_dir=work, memory="64M",
                          read_tasks=4, cell_tasks=8, node_tasks=2,
                          progress=lambda stage, fraction: stages.append(stage))
    finally:
        killer.join()
        client.close()
        cluster.close()
    assert killed, "no worker was killed: the cells stage ended before the test could"
    assert (tmp_path / "dask.fch").read_bytes() == whole
    assert report["out_of_core"] and report["cells_tasks"] == 8
    assert report["file_bytes"] == len(whole)
    tasks = report["tasks"]
    assert list(tasks) == ["read", "count", "grid", "bin", "cells", "upper", "geometry", "boxes",
                           "nodes", "layout", "place", "finish"]
    assert tasks["read"] == 4 and tasks["nodes"] == 2 and tasks["boxes"] == 1
    # Each step's tasks report in turn, after the step before, once each, the killed one included.
    order = [step for i, step in enumerate(stages) if i == 0 or stages[i - 1] != step]
    assert order == ["plan", "read", "count", "grid", "bin", "cells", "upper", "geometry", "boxes",
                     "nodes", "layout", "place", "finish"]
    assert all(stages.count(step) == count for step, count in tasks.items())
    assert not work.exists(), "the work directory goes with the build"


@pytest.mark.parametrize("workers", [1, 3])
def test_any_number_of_workers_gives_the_same_bytes(small, small_stl, tmp_path, workers):
    mesh, whole = small
    client, cluster = local_client(workers)
    try:
        ranges = fd.build(mesh, tmp_path / "dask.fch", client, memory="64M", cell_tasks=7, read_tasks=3,
                          cell_faces=SMALL_CELL_FACES)
        assert (tmp_path / "dask.fch").read_bytes() == whole
        assert ranges["tasks"]["read"] == 3 and ranges["tasks"]["cells"] == 7
        if workers == 1:  # read whole by the plan: the same mesh zstd-compressed
            compressed = tmp_path / "small.ply.zst"
            subprocess.run(["zstd", "-q", "-1", str(mesh), "-o", str(compressed)], check=True)
            one = fd.build(compressed, tmp_path / "dask-zst.fch", client, memory="64M", cell_tasks=7,
                           cell_faces=SMALL_CELL_FACES)
            assert (tmp_path / "dask-zst.fch").read_bytes() == whole
            assert list(one["tasks"]) == ["cells", "upper", "geometry", "boxes", "nodes", "layout",
                                          "place", "finish"]
        else:  # a binary STL: read in ranges, its corners welded by tasks
            stl, stl_whole = small_stl
            soup = fd.build(stl, tmp_path / "dask-stl.fch", client, memory="64M", cell_tasks=5, read_tasks=3,
                            cell_faces=SMALL_CELL_FACES)
            assert (tmp_path / "dask-stl.fch").read_bytes() == stl_whole
            assert list(soup["tasks"])[:5] == ["read", "count", "weld", "grid", "bin"]
            assert soup["tasks"]["weld"] == 3
    finally:
        client.close()
        cluster.close()


def test_reruns_with_keep_work_give_the_same_bytes_and_redo_only_what_is_missing(small, tmp_path):
    """After success, after the layout manifest is lost, and after the output is removed: the same
    bytes; the cells tasks are not made again; the report's times are the tasks'."""
    mesh, whole = small
    work, out = tmp_path / "work", tmp_path / "dask.fch"
    options = dict(work_dir=work, memory="64M", cell_tasks=3, read_tasks=2, cell_faces=SMALL_CELL_FACES,
                   keep_work=True)
    client, cluster = local_client(2)
    try:
        first = fd.build(mesh, out, client, **options)
        assert out.read_bytes() == whole
        assert first["seconds"]["cells"] > 0 and first["peak_rss_bytes"] > 16 << 20
        cells = [(work / f"cells-{t}.manifest").stat().st_mtime_ns for t in range(3)]
        fd.build(mesh, out, client, **options)
        assert out.read_bytes() == whole
        (work / "layout.manifest").unlink()
        fd.build(mesh, out, client, **options)
        assert out.read_bytes() == whole
        out.unlink()
        fd.build(mesh, out, client, **options)
        assert out.read_bytes() == whole
        assert [(work / f"cells-{t}.manifest").stat().st_mtime_ns for t in range(3)] == cells
    finally:
        client.close()
        cluster.close()


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


def test_a_bad_record_read_in_ranges_raises_the_readers_error(cli, small, tmp_path):
    mesh, _ = small
    data = bytearray(mesh.read_bytes())
    header = data.index(b"end_header\n") + len(b"end_header\n")
    vertices = int(data[:header].split(b"element vertex ")[1].split(b"\n")[0])
    record = header + 12 * vertices + 13 * 45_678  # a face in the second of three ranges
    data[record + 5:record + 9] = (vertices + 7).to_bytes(4, "little")
    bad = tmp_path / "bad.ply"
    bad.write_bytes(bytes(data))
    result = subprocess.run([str(cli), "build", str(bad), "-o", str(tmp_path / "x.fch"), "--memory", "64M",
                             "--cell-faces", str(SMALL_CELL_FACES)], capture_output=True, text=True)
    assert result.returncode == 3
    work = tmp_path / "work"
    with pytest.raises(facetree.InputError) as raised:
        fd.build(bad, tmp_path / "x.fch", work_dir=work, memory="64M", read_tasks=3, retries=0,
                 cell_faces=SMALL_CELL_FACES)
    assert str(raised.value) == result.stderr[len("facetree: "):].strip()
    assert f"face 45678: vertex index {vertices + 7} out of range" in str(raised.value)
    assert not work.exists()
    assert not (tmp_path / "x.fch").exists()
