#!/usr/bin/env python3
"""Writes the small valid samples next to this script. All describe the same square pyramid
(tests/stream/test_util.cpp: pyramid()): a quad base (face 0) and four triangles."""
import os
import struct
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))
VERTICES = [(0.0, 0.0, 0.0), (1.5, 0.0, 0.0), (1.5, 1.25, 0.0), (0.0, 1.25, -0.0), (0.75, 0.5, 2.0)]
FACES = [[0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]
TRIANGLES = [(f[0], f[k - 1], f[k]) for f in FACES for k in range(2, len(f))]


def write(name, data):
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


def ply(fmt, eol="\n", extra=False):
    h = [f"ply", f"format {fmt} 1.0", "comment facetree test sample", f"element vertex {len(VERTICES)}"]
    h += ["property float32 x", "property float32 y", "property float32 z"]
    if extra:
        h += ["property uchar red", "property list uchar int16 junk"]
    h += [f"element face {len(FACES)}", "property list uint8 uint32 vertex_indices"]
    if extra:
        h += ["property float quality", "element edge 1", "property int vertex1", "property int vertex2"]
    h += ["end_header"]
    head = eol.join(h) + eol
    if fmt == "ascii":
        body = ""
        for v in VERTICES:
            body += " ".join(repr(c) for c in v) + (" 7 2 -1 1" if extra else "") + "\n"
        for f in FACES:
            body += f"{len(f)} " + " ".join(map(str, f)) + (" 0.5" if extra else "") + "\n"
        if extra:
            body += "0 1\n"
        return head + body
    e = "<" if fmt == "binary_little_endian" else ">"
    body = b""
    for v in VERTICES:
        body += struct.pack(e + "3f", *v) + (struct.pack(e + "BBhh", 7, 2, -1, 1) if extra else b"")
    for f in FACES:
        body += struct.pack(e + "B", len(f)) + struct.pack(e + f"{len(f)}I", *f) + (struct.pack(e + "f", 0.5) if extra else b"")
    if extra:
        body += struct.pack(e + "ii", 0, 1)
    return head.encode() + body


write("pyramid_ascii.ply", ply("ascii"))
write("pyramid_ascii_crlf_extra.ply", ply("ascii", "\r\n", True))
write("pyramid_binary_le.ply", ply("binary_little_endian"))
write("pyramid_binary_be_extra.ply", ply("binary_big_endian", extra=True))
write("pyramid.ply.zst", subprocess.run(["zstd", "-q", "-c"], input=ply("binary_little_endian"),
                                        capture_output=True, check=True).stdout)

obj = "# facetree test sample\no pyramid\n" + "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in VERTICES)
obj += "vt 0 0\nvn 0 0 1\n"
obj += "f 1//1 4//1 3//1 2//1\n" + "".join("f " + " ".join(f"{i + 1}/1" for i in f) + "\n" for f in FACES[1:3])
obj += "".join("f " + " ".join(str(i - len(VERTICES)) for i in f) + "\n" for f in FACES[3:])  # negative indices
write("pyramid.obj", obj)

stl = "solid pyramid\n"
for t in TRIANGLES:
    stl += " facet normal 0 0 0\n  outer loop\n"
    stl += "".join("   vertex {!r} {!r} {!r}\n".format(*VERTICES[i]) for i in t)
    stl += "  endloop\n endfacet\n"
write("pyramid_ascii.stl", stl + "endsolid pyramid\n")

binary = b"solid pyramid (binary, despite the header)".ljust(80, b" ") + struct.pack("<I", len(TRIANGLES))
for t in TRIANGLES:
    binary += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *VERTICES[i]) for i in t) + b"\0\0"
write("pyramid_binary_solid_header.stl", binary)

# pyramid.drc is not written here (no Python Draco encoder): it was made once with draco's
# C++ encoder, MESH_SEQUENTIAL_ENCODING, no quantization, from the six fan triangles above
# (see encodeDraco in tests/stream/draco_test.cpp).
