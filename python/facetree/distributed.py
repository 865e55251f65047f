"""Builds and tiles past one machine: the out-of-core build's stages, and the tiles of a cluster
file, as tasks of a dask.distributed client.

build() plans the build in a work directory, runs the steps the plan lists (a binary PLY or STL is
read, counted and binned in ranges, an STL's corners welded by tasks, then its cells are built; any
other mesh is read and binned by the plan) as tasks on the client's workers, and finishes it; the file is the bytes
facetree.build_file writes with the same options and cap. Every worker must see the work directory (on a cluster, a shared file
system). tiles() runs `facetree tiles` likewise: the plan, a task per subtree, the finish; the
tileset is the bytes facetree.tiles writes with the same options. A task that fails is retried (a worker lost takes its task with it, and a cells task
already done is skipped); an error of the input reaches the caller as the facetree exception the
reader raised. dask.distributed comes from Debian (python3-distributed); facetree imports without it.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from typing import TYPE_CHECKING, Any, Callable, Optional, Union

from . import Cancelled, parse_size

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from ._facetree import BuildOptions

Path = Union[str, "os.PathLike[str]"]

__all__ = ["build", "tiles"]


def _run_stage(step: str, task: int, arguments: dict) -> Any:
    """One task in a worker process: the plan, a task of a step, or the finish."""
    from facetree import _facetree

    return _facetree._stage(step, task=task, **arguments)


def _run_tiles_stage(step: str, task: int, arguments: dict) -> Any:
    """One task of the tiles in a worker process: the plan, a subtree's tiles, or the finish."""
    from facetree import _facetree

    return _facetree._tiles_stage(step, task=task, **arguments)


def _local_client(distributed: Any) -> tuple:
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    return cluster, distributed.Client(cluster)


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError as error:  # pragma: no cover - depends on the machine
        raise ImportError(
            "facetree.distributed needs dask.distributed (Debian: python3-distributed)") from error
    return distributed


def _open(distributed: Any, client: Any, work_dir: Optional[Path], tmp: Optional[Path],
          prefix: str) -> tuple:
    """The work directory (a new one under `tmp` when none is given) and the client (a
    LocalCluster of 2 worker processes when none is given): (client, cluster or None, work)."""
    work = tempfile.mkdtemp(prefix=prefix, dir=tmp) if work_dir is None else os.fspath(work_dir)
    os.makedirs(work, exist_ok=True)
    cluster = None
    if client is None:
        cluster, client = _local_client(distributed)
    return client, cluster, work


def _close(client: Any, cluster: Any, work: str, keep_work: bool) -> None:
    """Closes the client _open started, and removes the work directory unless keep_work."""
    if cluster is not None:
        client.close()
        cluster.close()
    if not keep_work:
        shutil.rmtree(work, ignore_errors=True)


def _reporter(progress: Optional[Callable[[str, Optional[float]], Optional[bool]]]) -> Callable:
    """report(step, fraction): calls progress, and raises Cancelled when it returns False."""
    def report(stage: str, fraction: Optional[float]) -> None:
        if progress is not None and progress(stage, fraction) is False:
            raise Cancelled("cancelled")
    return report


def build(
    input: Path,
    output: Path,
    client: Any = None,
    *,
    work_dir: Optional[Path] = None,
    memory: Union[int, str, None] = None,
    tmp: Optional[Path] = None,
    max_tmp: Union[int, str, None] = None,
    zstd_level: int = 0,
    cell_faces: int = 0,
    cell_tasks: int = 0,
    read_tasks: int = 0,
    node_tasks: int = 0,
    retries: int = 2,
    keep_work: bool = False,
    progress: Optional[Callable[[str, Optional[float]], Optional[bool]]] = None,
    **options: Unpack[BuildOptions],
) -> dict:
    """Builds the cluster file of a mesh file as tasks of a dask.distributed client.

    input, output: paths every worker sees. client: a distributed.Client; None starts a
    LocalCluster of 2 worker processes for the call. work_dir: the directory the tasks share
    (default: a new one under `tmp`); it is removed when the build ends, succeeded or failed,
    unless keep_work is true (then a rerun of the same job with the same work_dir makes neither the
    plan nor the cells tasks done again).
    memory: the cap of every task, bytes or a string like "4G" (default: half the memory of the
    machine running the task). cell_tasks: how many cells tasks (default one per 16 cells);
    read_tasks: how many ranges a binary PLY or STL is read in (default one per 2^20 faces, for an
    STL at least enough to keep each range's ids within an eighth of the cap); node_tasks:
    how many tasks write the nodes (default one per 2^20 node positions); the file depends on none
    of them. retries: how many times a failed task is run again. progress: called as
    progress(step, fraction) with the step's name ("plan", "read", "count", "weld", "grid", "bin",
    "cells", ..., "finish");
    returning False cancels the build (Cancelled). Other arguments and options as
    facetree.build_file's.

    Returns the report of facetree.build_file, with "cells_tasks" and "tasks" (each step's count). Raises the facetree error of a
    task that failed (InputError for bad input, as the command line would name it).
    """
    distributed = _import_distributed()
    client, cluster, work = _open(distributed, client, work_dir, tmp, "facetree-work-")
    arguments = dict(
        input=os.path.abspath(os.fspath(input)), output=os.path.abspath(os.fspath(output)),
        work=os.path.abspath(work), memory=parse_size(memory),
        tmp=os.fspath(tmp) if tmp is not None else "", max_tmp=parse_size(max_tmp),
        zstd_level=zstd_level, cell_faces=cell_faces, cell_tasks=cell_tasks, read_tasks=read_tasks,
        node_tasks=node_tasks, **options)

    report = _reporter(progress)

    futures: list = []
    try:
        report("plan", None)
        plan = client.submit(_run_stage, "plan", 0, arguments, pure=False, retries=retries).result()
        steps = list(plan["next"])
        counts: dict = {}
        while steps:
            step, count = steps.pop(0)
            counts[step] = count
            if step == "finish":
                report("finish", None)
                result = client.submit(_run_stage, "finish", 0, arguments, pure=False,
                                       retries=retries).result()
                result["cells_tasks"] = counts.get("cells", 0)
                result["tasks"] = counts
                return result
            # A step's tasks run in any order once the step before is done; a step of one task (the
            # grid) lists the steps after it.
            futures = [client.submit(_run_stage, step, task, arguments, pure=False, retries=retries,
                                     key=f"facetree-{step}-{task}-{os.path.basename(work)}")
                       for task in range(count)]
            done = 0
            for future in distributed.as_completed(futures):
                out = future.result()  # the task's error, if it failed every retry
                done += 1
                report(step, done / count)
                if out["next"]:
                    steps = list(out["next"])
            futures = []
        raise RuntimeError("facetree.distributed.build: the plan's steps end without a finish")
    except BaseException:
        if futures:
            client.cancel(futures)
        # The file being placed lives beside the output when the work directory is on another
        # file system (else in the work directory): a failed build leaves neither.
        partial = arguments["output"] + ".partial"
        if os.path.exists(partial):
            os.remove(partial)
        raise
    finally:
        _close(client, cluster, work, keep_work)


def tiles(
    path: Path,
    dir: Path,
    client: Any = None,
    *,
    work_dir: Optional[Path] = None,
    tile_faces: int = 65536,
    memory: Union[int, str, None] = None,
    tmp: Optional[Path] = None,
    draco: bool = False,
    tasks: int = 0,
    retries: int = 2,
    keep_work: bool = False,
    progress: Optional[Callable[[str, Optional[float]], Optional[bool]]] = None,
) -> dict:
    """Writes a cluster file as 3D Tiles 1.1, as facetree.tiles does, as tasks of a
    dask.distributed client: the plan (the tiles, where they meet, the subtrees), one task per
    subtree in any order on any worker, then the tiles above them; dir is the bytes facetree.tiles
    writes with the same options.

    path, dir: paths every worker sees. client: a distributed.Client; None starts a LocalCluster of
    2 worker processes for the call. work_dir: the directory the tasks share (default: a new one
    under `tmp`), removed at the end unless keep_work (then a rerun with the same work_dir keeps the
    plan and the tasks done). memory: the cap of every task (default: the cap the file was built
    under). tasks: how many subtrees (default one per 2^21 faces, at least 4); the tiles do not
    depend on it. retries: how many times a failed task is run again. progress: called as
    progress(step, fraction) with "plan", "tiles" or "finish"; returning False cancels (Cancelled).

    Returns facetree.tiles' report, with "tasks". Raises the facetree error of a task that failed.
    """
    distributed = _import_distributed()
    client, cluster, work = _open(distributed, client, work_dir, tmp, "facetree-tiles-")
    arguments = dict(
        path=os.path.abspath(os.fspath(path)), dir=os.path.abspath(os.fspath(dir)),
        work=os.path.abspath(work), tile_faces=tile_faces, memory=parse_size(memory),
        tmp=os.fspath(tmp) if tmp is not None else "", draco=draco, tasks=tasks)
    report = _reporter(progress)

    futures: list = []
    try:
        report("plan", None)
        plan = client.submit(_run_tiles_stage, "plan", 0, arguments, pure=False,
                             retries=retries).result()
        count = plan["tasks"]
        futures = [client.submit(_run_tiles_stage, "tiles", task, arguments, pure=False,
                                 retries=retries,
                                 key=f"facetree-tiles-{task}-{os.path.basename(work)}")
                   for task in range(count)]
        done = 0
        for future in distributed.as_completed(futures):
            future.result()  # the task's error, if it failed every retry
            done += 1
            report("tiles", done / count)
        futures = []
        report("finish", None)
        result = client.submit(_run_tiles_stage, "finish", 0, arguments, pure=False,
                               retries=retries).result()
        result["tasks"] = count
        return result
    except BaseException:
        if futures:
            client.cancel(futures)
        raise
    finally:
        _close(client, cluster, work, keep_work)
