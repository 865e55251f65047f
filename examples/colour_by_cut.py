#!/usr/bin/env python3
"""Colours a scan by a cut of its face cluster hierarchy and saves it as a coloured PLY.

    python3 examples/colour_by_cut.py MESH [--clusters N] [-o OUT.ply]

Reads the mesh with meshio when it can (any format meshio knows, e.g. from a pipeline's own files),
else with facetree's streaming reader (PLY, OBJ, STL, Draco, zstd-compressed); builds the hierarchy
from the NumPy arrays; cuts it into N clusters; and writes each face in its cluster's colour
(faces are split so that each keeps its own colour; meshio writes the PLY).
"""
import argparse

import meshio
import numpy as np

import facetree


def read(path: str):
    try:
        mesh = meshio.read(path)
        faces = mesh.cells_dict.get("triangle")
        if faces is not None:
            return np.asarray(mesh.points, dtype=np.float32), faces
    except Exception:  # a format or compression meshio does not read: facetree's reader does
        pass
    vertices, faces, _ = facetree.read_mesh(path)
    return vertices, faces


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mesh")
    parser.add_argument("--clusters", type=int, default=256)
    parser.add_argument("-o", "--output", default="clusters.ply")
    args = parser.parse_args()

    vertices, faces = read(args.mesh)
    hierarchy = facetree.build(vertices, faces)
    labels = hierarchy.cut(args.clusters)            # one cluster per input face
    colours = facetree.cluster_colours(labels)       # as `facetree render` colours them

    corners = vertices[faces.reshape(-1)]            # every face with its own three corners
    split = np.arange(len(corners), dtype=np.int32).reshape(-1, 3)
    per_corner = np.repeat(colours, 3, axis=0)
    meshio.write(args.output, meshio.Mesh(corners, [("triangle", split)],
                                          point_data={"red": per_corner[:, 0], "green": per_corner[:, 1],
                                                      "blue": per_corner[:, 2]}), binary=True)
    print(f"{args.mesh}: {len(faces)} faces, {hierarchy.node_count} nodes, height {hierarchy.height}; "
          f"{labels.max() + 1} clusters -> {args.output}")


if __name__ == "__main__":
    main()
