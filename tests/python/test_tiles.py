"""facetree.tiles and `facetree tiles`: a valid 3D Tiles 1.1 tileset (tests/tiles/check_tileset.py:
geometric errors, boxes, URIs, glb structure), leaves holding every triangle once, the same bytes
from Python and the command line and for every thread count, external tilesets, the memory cap,
and bad input failing with one message and nothing left behind."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

import facetree
from conftest import run_cli

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tiles"))
import check_tileset  # noqa: E402


def files_of(directory: Path) -> dict:
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def horse_file(cli, shared_data, tmp_path_factory):
    path = tmp_path_factory.mktemp("tiles") / "horse.fch"
    run_cli(cli, "build", shared_data / "horse_97k.ply.zst", "-o", path)
    return path


def test_a_valid_tileset_whose_leaves_hold_every_triangle(cli, horse_file, tmp_path):
    triangles = facetree.open(horse_file).header["triangle_count"]
    report = facetree.tiles(horse_file, tmp_path / "tiles", tile_faces=4096)
    summary = check_tileset.check(str(tmp_path / "tiles"), triangles)
    assert summary["tiles"] == report["tiles"] > 20
    assert summary["leaf_triangles"] == report["leaf_triangles"] == triangles
    assert summary["levels"] == report["levels"] >= 3
    assert report["bytes"] <= 1.6 * report["leaf_bytes"]
    # The command line writes the same bytes, and so does every thread count.
    run_cli(cli, "tiles", horse_file, "-o", tmp_path / "cli", "--tile-faces", "4096", "--threads", "1")
    run_cli(cli, "tiles", horse_file, "-o", tmp_path / "cli3", "--tile-faces", "4096", "--threads", "3")
    assert files_of(tmp_path / "tiles") == files_of(tmp_path / "cli") == files_of(tmp_path / "cli3")


def test_draco_and_external_tilesets(cli, horse_file, tmp_path):
    run_cli(cli, "tiles", horse_file, "-o", tmp_path / "split", "--tile-faces", "2048", "--tiles-per-json", "6",
            "--draco")
    summary = check_tileset.check(str(tmp_path / "split"))
    assert summary["draco"] and summary["json_files"] > 3
    report = json.loads(run_cli(cli, "tiles", horse_file, "-o", tmp_path / "one", "--tile-faces", "2048",
                                "--json").stdout)
    assert summary["tiles"] == report["tiles"]


def test_a_checker_that_fails_on_a_broken_tileset(horse_file, tmp_path):
    facetree.tiles(horse_file, tmp_path / "t", tile_faces=4096)
    tileset = json.loads((tmp_path / "t" / "tileset.json").read_text())
    child = tileset["root"]["children"][0]
    child["geometricError"] = tileset["root"]["geometricError"] * 2
    (tmp_path / "t" / "tileset.json").write_text(json.dumps(tileset))
    with pytest.raises(check_tileset.Invalid, match="not below its parent"):
        check_tileset.check(str(tmp_path / "t"))


def test_under_the_memory_cap(cli, shared_data, tmp_path):
    # dragon_vrip (871k faces) tiled under 48M: the process's peak resident set stays under it.
    fch = tmp_path / "dragon.fch"
    run_cli(cli, "build", shared_data / "dragon_vrip.ply.zst", "-o", fch)
    # The command's own getrusage, run from a shell that forks it: Linux keeps a process's peak across
    # exec, so a command started straight from this Python process would count the interpreter's.
    command = f'"{cli}" tiles "{fch}" -o "{tmp_path / "tiles"}" --tile-faces 16384 --memory 48M --json; exit $?'
    report = json.loads(subprocess.run(["/bin/sh", "-c", command], capture_output=True, text=True, check=True).stdout)
    assert 0 < report["peak_rss_bytes"] <= 48 << 20, f"peak {report['peak_rss_bytes'] / 2**20:.1f} MiB"


def test_bad_input_fails_with_one_message_and_leaves_nothing(cli, horse_file, tmp_path):
    missing = run_cli(cli, "tiles", tmp_path / "missing.fch", "-o", tmp_path / "out", check=False)
    assert missing.returncode == 3
    assert "missing.fch" in missing.stderr and len(missing.stderr.strip().splitlines()) == 1
    corrupt = tmp_path / "corrupt.fch"
    corrupt.write_bytes(horse_file.read_bytes()[:5000])
    broken = run_cli(cli, "tiles", corrupt, "-o", tmp_path / "out", check=False)
    assert broken.returncode == 3 and "corrupt.fch" in broken.stderr
    (tmp_path / "plain").write_text("in the way")
    blocked = run_cli(cli, "tiles", horse_file, "-o", tmp_path / "plain", check=False)
    assert blocked.returncode == 4
    assert blocked.stderr.strip() == f"facetree: {tmp_path / 'plain'}: exists and is not a directory"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corrupt.fch", "plain"]
    with pytest.raises(facetree.InputError):
        facetree.tiles(tmp_path / "missing.fch", tmp_path / "out")
    with pytest.raises(ValueError):
        facetree.tiles(horse_file, tmp_path / "out", tile_faces=4)


def test_as_tasks_of_the_stage_commands_and_dask_the_same_bytes(cli, horse_file, tmp_path):
    distributed = pytest.importorskip("distributed")
    import facetree.distributed as fd

    facetree.tiles(horse_file, tmp_path / "one", tile_faces=2048, draco=True)
    whole = files_of(tmp_path / "one")
    # The stage commands, tasks in reverse order, one run twice (done already), one with another
    # task alongside it.
    work = tmp_path / "work"
    plan = json.loads(run_cli(cli, "stage", "tiles-plan", horse_file, "--work", work, "-o", tmp_path / "staged",
                              "--tile-faces", "2048", "--draco", "--tasks", "5", "--json").stdout)
    assert plan["tasks"] >= 5 and plan["next"] == f"tiles:{plan['tasks']} tiles-finish:1" and plan["planned"]
    for task in reversed(range(plan["tasks"])):
        run_cli(cli, "stage", "tiles", "--work", work, "--task", task, *(["--alongside", "2"] if task == 1 else []))
    again = run_cli(cli, "stage", "tiles", "--work", work, "--task", "0")
    assert again.stdout.strip() == "tiles task 0: done already"
    early = run_cli(cli, "stage", "tiles", "--work", work, "--task", plan["tasks"], check=False)
    assert early.returncode == 2 and f"of a plan of {plan['tasks']} tasks" in early.stderr
    replanned = json.loads(run_cli(cli, "stage", "tiles-plan", horse_file, "--work", work, "-o", tmp_path / "staged",
                                   "--tile-faces", "2048", "--draco", "--tasks", "5", "--json").stdout)
    assert not replanned["planned"], "the same plan is kept with its tasks done"
    report = json.loads(run_cli(cli, "stage", "tiles-finish", "--work", work, "--json").stdout)
    assert files_of(tmp_path / "staged") == whole
    assert report["tiles"] == len([name for name in whole if name.endswith(".glb")])
    # A finish without every task: the missing one named.
    work2 = tmp_path / "work2"
    run_cli(cli, "stage", "tiles-plan", horse_file, "--work", work2, "-o", tmp_path / "half", "--tile-faces", "2048")
    run_cli(cli, "stage", "tiles", "--work", work2, "--task", "0")
    half = run_cli(cli, "stage", "tiles-finish", "--work", work2, check=False)
    assert half.returncode == 3 and "tiles-1.manifest: missing (tiles task 1 not done for this plan)" in half.stderr
    assert not (tmp_path / "half").exists()
    # Dask with 2 worker processes, and progress that reports every task.
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = distributed.Client(cluster)
    steps = []
    try:
        dask = fd.tiles(horse_file, tmp_path / "dask", client, tile_faces=2048, draco=True, tasks=6,
                        progress=lambda step, fraction: steps.append(step))
        with pytest.raises(facetree.InputError, match="missing.fch"):
            fd.tiles(tmp_path / "missing.fch", tmp_path / "nothing", client, retries=0, tmp=tmp_path)
    finally:
        client.close()
        cluster.close()
    assert files_of(tmp_path / "dask") == whole
    assert steps.count("tiles") == dask["tasks"] >= 6 and steps[0] == "plan" and steps[-1] == "finish"
    assert not (tmp_path / "nothing").exists()
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith("facetree-tiles-")], "work left behind"
