#!/usr/bin/env python3
"""Writes the malformed-mesh corpus next to this script: one small file per failure.

The expected error of each file is in tests/stream/malformed_test.cpp. Run from anywhere:
    python3 tests/data/malformed/make_corpus.py
Needs the `zstd` command line tool for the compressed cases.
"""
import os
import struct
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, data):
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


def zstd(data):
    if isinstance(data, str):
        data = data.encode()
    return subprocess.run(["zstd", "-q", "-c", "--no-check"], input=data, capture_output=True, check=True).stdout


XYZ = "property float x\nproperty float y\nproperty float z\n"
FACE = "element face {}\nproperty list uchar int vertex_indices\n"


def header(fmt, vertices, faces, extra=""):
    return Text(f"ply\nformat {fmt} 1.0\nelement vertex {vertices}\n{XYZ}" + FACE.format(faces) + extra + "end_header\n")


def binary_vertices(points):
    return b"".join(struct.pack("<3f", *p) for p in points)


def binary_face(indices, count_format="<B", index_format="<i"):
    return struct.pack(count_format, len(indices)) + b"".join(struct.pack(index_format, i) for i in indices)


class Text(str):
    """A str that concatenates with bytes (header + binary payload)."""

    def __add__(self, other):
        if isinstance(other, bytes):
            return self.encode() + other
        return Text(str.__add__(self, other))


QUAD = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
ASCII_QUAD = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
LE = "binary_little_endian"

# ---- PLY header
write("ply_only_magic.ply", "ply\n")
write("ply_missing_end_header.ply", f"ply\nformat ascii 1.0\nelement vertex 4\n{XYZ}" + FACE.format(1))
write("ply_missing_format.ply", f"ply\nelement vertex 4\n{XYZ}" + FACE.format(1) + "end_header\n" + ASCII_QUAD + "3 0 1 2\n")
write("ply_unknown_format.ply", header("binary_middle_endian", 4, 1) + ASCII_QUAD + "3 0 1 2\n")
write("ply_unknown_property_type.ply",
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float128 x\nproperty float y\nproperty float z\n"
      + FACE.format(1) + "end_header\n" + ASCII_QUAD + "3 0 1 2\n")
write("ply_unknown_keyword.ply", "ply\nformat ascii 1.0\nelemnet vertex 4\n")
write("ply_property_before_element.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n")
write("ply_invalid_element_count.ply", "ply\nformat ascii 1.0\nelement vertex -4\n" + XYZ + FACE.format(1) + "end_header\n")
write("ply_no_vertex_element.ply", "ply\nformat ascii 1.0\n" + FACE.format(1) + "end_header\n3 0 1 2\n")
write("ply_no_face_element.ply", f"ply\nformat ascii 1.0\nelement vertex 4\n{XYZ}end_header\n" + ASCII_QUAD)
write("ply_zero_faces.ply", header("ascii", 4, 0) + ASCII_QUAD)
write("ply_vertex_missing_z.ply",
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n" + FACE.format(1)
      + "end_header\n0 0\n1 0\n1 1\n0 1\n3 0 1 2\n")
write("ply_face_without_vertex_indices.ply",
      f"ply\nformat ascii 1.0\nelement vertex 4\n{XYZ}element face 1\nproperty list uchar int corners\nend_header\n"
      + ASCII_QUAD + "3 0 1 2\n")
write("ply_vertex_indices_float.ply",
      f"ply\nformat ascii 1.0\nelement vertex 4\n{XYZ}element face 1\nproperty list uchar float vertex_indices\n"
      "end_header\n" + ASCII_QUAD + "3 0 1 2\n")
write("ply_vertex_indices_not_list.ply",
      f"ply\nformat ascii 1.0\nelement vertex 4\n{XYZ}element face 1\nproperty int vertex_indices\n"
      "end_header\n" + ASCII_QUAD + "0\n")

# ---- PLY counts against the data
write("ply_huge_vertex_count.ply", header(LE, 10**18, 1) + binary_vertices(QUAD) + binary_face([0, 1, 2]))
write("ply_count_size_overflow.ply",
      f"ply\nformat {LE} 1.0\nelement vertex 1000000000000000000\nproperty double x\nproperty double y\n"
      "property double z\n" + FACE.format(1) + "end_header\n" + "\0" * 24)
write("ply_header_counts_exceed_data.ply", header("ascii", 100, 1) + ASCII_QUAD + "3 0 1 2\n")
write("ply_huge_face_count.ply", header(LE, 4, 10**15) + binary_vertices(QUAD) + binary_face([0, 1, 2]))
write("ply_huge_vertex_count.ply.zst", zstd(header(LE, 10**18, 1) + "\0" * 60))
write("ply_huge_face_count.ply.zst",
      zstd(header(LE, 4, 10**15).encode() + binary_vertices(QUAD) + binary_face([0, 1, 2])))

# ---- PLY data
write("ply_truncated_vertex.ply", header(LE, 4, 1).encode() + binary_vertices(QUAD)[:30])
# Compressed, the size is unknown: the truncation is found where the data ends.
write("ply_truncated_vertex.ply.zst", zstd(header(LE, 4, 1).encode() + binary_vertices(QUAD)[:30]))
# The quad passes the size check (13 bytes per face at least) but the second face is cut.
write("ply_truncated_face.ply", header(LE, 4, 2).encode() + binary_vertices(QUAD) + binary_face([0, 1, 2, 3])
      + binary_face([0, 1, 2])[:10])
write("ply_ascii_truncated_face.ply", header("ascii", 4, 3) + "0.000 0.000 0.000\n1.000 0.000 0.000\n"
      "1.000 1.000 0.000\n0.000 1.000 0.000\n3 0 1 2\n3 0 2 3\n")
write("ply_ascii_too_few_indices.ply", header("ascii", 4, 1) + ASCII_QUAD + "4 0 1 2\n")
write("ply_face_two_vertices.ply", header(LE, 4, 2).encode() + binary_vertices(QUAD) + binary_face([0, 1, 2])
      + binary_face([0, 1]) + b"\0" * 8)
LONG_QUAD = "0.000 0.000 0.000\n1.000 0.000 0.000\n1.000 1.000 0.000\n0.000 1.000 0.000\n"
write("ply_face_zero_vertices.ply", header("ascii", 4, 2) + LONG_QUAD + "3 0 1 2\n0\n")
write("ply_negative_list_count.ply",
      f"ply\nformat {LE} 1.0\nelement vertex 4\n{XYZ}element face 1\nproperty list char int vertex_indices\n"
      "end_header\n".encode() + binary_vertices(QUAD) + struct.pack("<b", -1) + b"\0" * 12)
write("ply_negative_extra_list_length.ply",
      f"ply\nformat {LE} 1.0\nelement vertex 4\n{XYZ}element face 1\nproperty list uchar int vertex_indices\n"
      "property list char float uv\nend_header\n".encode() + binary_vertices(QUAD) + binary_face([0, 1, 2])
      + struct.pack("<b", -3) + b"\0" * 12)
write("ply_index_out_of_range.ply", header(LE, 4, 2).encode() + binary_vertices(QUAD) + binary_face([0, 1, 2])
      + binary_face([0, 2, 4]))
write("ply_negative_index.ply", header("ascii", 4, 1) + ASCII_QUAD + "3 0 -1 2\n")
write("ply_ascii_bad_number.ply", header("ascii", 4, 1) + "0 0 0\n1 0 0\n1 one 0\n0 1 0\n3 0 1 2\n")
write("ply_ascii_extra_value.ply", header("ascii", 4, 1) + ASCII_QUAD + "3 0 1 2 3\n")
write("ply_trailing_data.ply", header(LE, 4, 1).encode() + binary_vertices(QUAD) + binary_face([0, 1, 2]) + b"junk")
write("ply_strip_bad_index.ply",
      f"ply\nformat ascii 1.0\nelement vertex 4\n{XYZ}element tristrips 1\nproperty list int int vertex_indices\n"
      "end_header\n" + ASCII_QUAD + "5 0 1 2 -2 3\n")
write("ply_binary_header_line_too_long.ply.zst", zstd("ply\ncomment " + "x" * (1 << 20) + "\n"))

# ---- OBJ
OBJ_QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
write("obj_index_zero.obj", OBJ_QUAD + "f 1 2 3\nf 0 1 2\n")
write("obj_negative_index_out_of_range.obj", OBJ_QUAD + "f -1 -2 -3\nf -1 -2 -5\n")
write("obj_index_out_of_range.obj", OBJ_QUAD + "f 1 2 5\nv 2 2 2\n")
write("obj_face_two_vertices.obj", OBJ_QUAD + "f 1 2\n")
write("obj_vertex_two_coordinates.obj", "v 0 0 0\nv 1 0\n")
write("obj_bad_number.obj", "v 0 0 0\nv 1 0 1,5\n")
write("obj_bad_index.obj", OBJ_QUAD + "f 1/1 x/2 3/3\n")
write("obj_no_faces.obj", "# only vertices\n" + OBJ_QUAD)
write("obj_line_too_long.obj.zst", zstd(OBJ_QUAD + "f" + " 1" * (1 << 19) + "\n"))

# ---- STL
def binary_stl(header80, count, triangles):
    data = header80.ljust(80, b" ") + struct.pack("<I", count)
    for t in triangles:
        data += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *p) for p in t) + b"\0\0"
    return data


TRI = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
write("stl_binary_count_mismatch.stl", binary_stl(b"solid but actually binary", 3, [TRI, TRI]))
write("stl_binary_zero_triangles.stl", binary_stl(b"\0binary", 0, []))
FACET = "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n endloop\nendfacet\n"
write("stl_ascii_truncated.stl", "solid t\n" + FACET + "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n")
write("stl_ascii_four_vertices.stl",
      "solid t\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n  vertex 1 1 0\n"
      " endloop\nendfacet\nendsolid t\n")
write("stl_ascii_bad_number.stl", "solid t\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 zero\n")
write("stl_ascii_missing_endsolid.stl", "solid t\n" + FACET)
write("stl_ascii_no_facets.stl", "solid empty\nendsolid empty\n")
write("stl_ascii_unexpected_keyword.stl", "solid t\n" + FACET + "facet normal 0 0 1\n inner loop\n")

# ---- detection, zstd, draco
write("empty.ply", "")
write("unknown_format.bin", "MZ\x90\0" + "\0" * 100)
write("unknown_text.txt", "hello, this is not a mesh\n")
PLY = header("ascii", 4, 1) + ASCII_QUAD + "3 0 1 2\n"
write("zstd_truncated.ply.zst", zstd(PLY)[:-5])
write("zstd_garbage_after_frame.ply.zst", zstd(PLY) + b"garbage!")
corrupt = bytearray(zstd(PLY * 3))
corrupt[8:14] = b"\xff" * 6
write("zstd_corrupt.ply.zst", bytes(corrupt))
write("zstd_empty.zst", zstd(""))
write("draco_garbage.drc", b"DRACO" + bytes(range(40)))
