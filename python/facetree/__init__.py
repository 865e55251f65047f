"""Face cluster hierarchies of large triangle meshes.

facetree groups a mesh's faces into a hierarchy of clusters by greedy dual-edge merging with
Willmott's cost (Willmott 2000, ch. 5): each node has an oriented box with exact extents and
projected side areas, and nodes are ordered so that any prefix is a coarser hierarchy.

    import facetree
    vertices, faces, face_ids = facetree.read_mesh("scan.ply")
    h = facetree.build(vertices, faces)
    labels = h.cut(1000)          # a cluster per input face
    h.save("scan.fch")
    report = facetree.build_file("big.ply", "big.fch", memory="256M", progress=print)

Errors raise facetree.Error subclasses: InputError (bad input or options), OutputError,
ResourceError (memory or temporary-space limits) and Cancelled; their `exit_code` is the
command-line tool's for the same failure.
"""

from __future__ import annotations

import builtins
import os
import shutil
import tempfile
from typing import IO, TYPE_CHECKING, Callable, Optional, Union

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from ._facetree import BuildOptions

from ._facetree import (
    Cancelled,
    Error,
    Hierarchy,
    InputError,
    OutputError,
    Reader,
    ResourceError,
    __version__,
    build,
    cluster_colours,
    load,
    read_mesh,
)
from . import _facetree

__all__ = [
    "Cancelled", "Error", "Hierarchy", "InputError", "OutputError", "Reader", "ResourceError", "__version__",
    "build", "build_file", "cluster_colours", "load", "open", "read_mesh", "parse_size", "tiles",
]

Path = Union[str, "os.PathLike[str]"]
Progress = Callable[[str, Optional[float]], Optional[bool]]

_SUFFIXES = {"": 1, "k": 1 << 10, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
_COPY_BYTES = 1 << 20


def parse_size(size: Union[int, str, None]) -> int:
    """Bytes from an int or a string with an optional k, M or G suffix (binary: "256M" is 256 MiB),
    as the command line's --memory takes them; None is 0."""
    if size is None:
        return 0
    if isinstance(size, bool):
        raise InputError(f"a size must be a whole number of bytes, got {size!r}")
    if isinstance(size, int):
        if size < 0:
            raise InputError(f"a size must not be negative, got {size}")
        return size
    text = str(size).strip()
    number, suffix = (text[:-1], text[-1]) if text and text[-1] in _SUFFIXES else (text, "")
    if not number.isdigit():
        raise InputError(f"a size must be a whole number with an optional suffix k, M or G, got {size!r}")
    return int(number) * _SUFFIXES[suffix]


def open(path: Union[Path, int], memory: Union[int, str, None] = None, tmp: Optional[Path] = None) -> Reader:
    """Opens a cluster file (.fch) for reading under a memory cap, without loading it.

    path: a file name, or the descriptor of an open regular file (read through a duplicate of it;
    the caller keeps and closes its own).

    memory: the cap, bytes or "64M" (default: the cap the file was built under, else half the RAM);
    a quarter caches decoded frames and a quarter holds a pass over the nodes, the rest of which goes
    to a temporary file in tmp (default the system's). Only the header and the frame index are read
    here; an unreadable or corrupt frame raises InputError when it is first needed.

        with facetree.open("scan.fch", memory="64M") as f:
            node_ids, ranges = f.cut(clusters=1000)
            vertices, triangles, ids = f.mesh(node_ids[0])
    """
    directory = os.fspath(tmp) if tmp is not None else ""
    if isinstance(path, int):
        return _facetree._open_fd(path, f"descriptor {path}", parse_size(memory), directory)
    return _facetree._open(os.fspath(path), parse_size(memory), directory)


def tiles(path: Path, dir: Path, *, tile_faces: int = 65536, memory: Union[int, str, None] = None,
          tmp: Optional[Path] = None, threads: int = 0, draco: bool = False) -> dict:
    """Writes a cluster file as 3D Tiles 1.1 with levels of detail: dir/tileset.json and a glb per
    tile under dir/tiles/, as `facetree tiles` does, with the same bytes.

    Leaf tiles are the highest nodes of at most tile_faces faces, at full resolution; an inner tile's
    content is its children's simplified with the points it shares with other tiles locked (so
    levels meet without cracks), its geometric error in the model's units, above its children's. One pass
    bottom-up under memory (bytes or "64M"; default the cap the file was built under); the same bytes
    for every thread count. An existing dir is replaced only if it holds a tileset.json. Returns the
    report (tiles, leaf_tiles, levels, triangles, bytes, leaf_bytes, seconds, ...); Ctrl-C stops it
    and leaves nothing behind.

        facetree.tiles("scan.fch", "scan_tiles", tile_faces=16384, memory="256M")

    Past one machine, facetree.distributed.tiles runs the same work as tasks of a Dask client, with
    the same bytes.
    """
    return _facetree._tiles(os.fspath(path), os.fspath(dir), tile_faces, parse_size(memory),
                            os.fspath(tmp) if tmp is not None else "", threads, draco)


def _clusters(self: Reader, *, clusters: Optional[int] = None, max_cost: Optional[float] = None,
              depth: Optional[int] = None):
    """The clusters of a cut in face order (see cut()): (node_id, first, count, vertices, triangles,
    original_ids) for each, its triangles decoded as it comes."""
    node_ids, ranges = self.cut(clusters=clusters, max_cost=max_cost, depth=depth)
    for node, (first, count) in zip(node_ids.tolist(), ranges.tolist()):
        yield (node, first, count, *self.faces(first, count))


Reader.clusters = _clusters  # type: ignore[attr-defined]


def _is_file_object(value: object) -> bool:
    return hasattr(value, "read") or hasattr(value, "write")


def build_file(
    input: Union[Path, IO[bytes]],
    output: Union[Path, IO[bytes], None] = None,
    *,
    memory: Union[int, str, None] = None,
    tmp: Optional[Path] = None,
    max_tmp: Union[int, str, None] = None,
    progress: Optional[Progress] = None,
    zstd_level: int = 0,
    cell_faces: int = 0,
    **options: Unpack[BuildOptions],
) -> dict:
    """Runs the whole job of `facetree build`: a mesh file to a cluster file (.fch).

    In core when the build fits `memory`, else out of core: faces are binned into spatial cells
    spilled to temporary files under `tmp`, and the merge continues above the cells. Returns the
    report, the fields of `facetree build --json`.

    input: a path, or a binary file object (read to its end; one without a file descriptor is
      first copied to a temporary file under `tmp`).
    output: a path (written atomically), a binary file object (the file is written under `tmp`,
      then copied into it), or None to build without writing (the mesh must then fit in core).
    memory: the cap, bytes or a string like "256M" (default: half the physical memory).
    tmp: directory for temporary files (default: the system's); max_tmp: their limit.
    progress: called as progress(stage, fraction) with stage "read", "bin", "cells", "merge" or
      "write" and the fraction done (None when unknown), a few times a second; returning False
      cancels the job (Cancelled). Ctrl-C cancels it as well (KeyboardInterrupt). Either way the
      temporary files and any partial output are removed.
    cell_faces: force an out-of-core build with cells of at most this many faces (for tests).
    zstd_level: compression level of the file's frames, 1 to 19 (0: 3).

    options: build()'s, by keyword (BuildOptions). Raises InputError, OutputError, ResourceError or Cancelled.
    """
    with tempfile.TemporaryDirectory(prefix="facetree-py-", dir=tmp) as scratch:
        input_path = _input_path(input, scratch)
        output_path = ""
        if output is not None:
            output_path = os.path.join(scratch, "out.fch") if _is_file_object(output) else os.fspath(output)
        report = _facetree._build_file(
            input_path, output_path, parse_size(memory), os.fspath(tmp) if tmp is not None else "",
            parse_size(max_tmp), zstd_level, progress, cell_faces, **options)
        if output is not None and _is_file_object(output):
            with builtins.open(output_path, "rb") as built:
                shutil.copyfileobj(built, output, _COPY_BYTES)
    if not isinstance(input, (str, os.PathLike)):
        report["mesh"] = getattr(input, "name", "<file object>")
    return report


def _input_path(input: Union[Path, IO[bytes]], scratch: str) -> str:
    if isinstance(input, (str, os.PathLike)):
        return os.fspath(input)
    if not hasattr(input, "read"):
        raise InputError(f"input: expected a path or a binary file object, got {type(input).__name__}")
    try:
        descriptor = input.fileno()
    except (AttributeError, OSError, ValueError):
        descriptor = None
    # The reader opens /dev/fd/N afresh: from the start of a regular file, or where a pipe stands.
    if descriptor is not None and (not input.seekable() or input.tell() == 0):
        return f"/dev/fd/{descriptor}"
    copy = os.path.join(scratch, "input")
    with builtins.open(copy, "wb") as spooled:
        shutil.copyfileobj(input, spooled, _COPY_BYTES)
    return copy
