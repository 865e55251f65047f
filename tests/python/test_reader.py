"""facetree.open against facetree.load: the same nodes, cuts and triangles, read lazily under a cap,
on a whole file and a truncated one; a closed reader and a corrupt file raise."""
import json
import os
import threading

import numpy as np
import pytest

import facetree
from conftest import run_cli


@pytest.fixture(scope="module")
def files(bunny, tmp_path_factory, cli):
    vertices, faces, ids, _ = bunny
    path = tmp_path_factory.mktemp("reader") / "bunny.fch"
    facetree.build(vertices, faces, face_ids=ids, branching=4).save(str(path))
    truncated = path.with_name("bunny_cut.fch")
    run_cli(cli, "truncate", path, "-o", truncated, "--nodes", "5000")
    return path, truncated


@pytest.mark.parametrize("which", [0, 1])
def test_nodes_equal_the_loaded_hierarchys(files, which):
    path = files[which]
    h = facetree.load(str(path))
    with facetree.open(path, memory="1M") as f:
        assert len(f) == len(h) and f.header == h.header
        nodes = f.nodes()
        assert nodes.shape == (len(h),)
        assert np.array_equal(np.stack([nodes["first"], nodes["count"]], axis=1), h.face_ranges)
        assert np.array_equal(nodes["child_count"], h.child_count)
        assert np.array_equal(nodes["children"][:, : h.branching], h.children)
        assert np.array_equal(nodes["cost"], h.cost)
        assert np.array_equal(nodes["box_center"], h.box_center)
        assert np.array_equal(nodes["box_half_extents"], h.box_half_extents)
        # A slice far into the file, after the whole: the same records.
        assert np.array_equal(f.nodes(len(h) - 10, len(h) + 5), nodes[-10:])
        assert f.nodes(len(h) + 1).shape == (0,)


@pytest.mark.parametrize("which", [0, 1])
def test_cuts_and_triangles_equal_the_loaded_hierarchys(files, which):
    path = files[which]
    h = facetree.load(str(path))
    with facetree.open(path) as f:
        for kwargs in ({"clusters": 50}, {"depth": 4}, {"max_cost": float(h.cost[30])}):
            node_ids, ranges = f.cut(**kwargs)
            assert ranges[0, 0] == 0 and (ranges[1:, 0] == ranges[:-1].sum(axis=1)).all()
            assert ranges[:, 1].sum() == h.face_count
            kept = node_ids >= 0
            assert np.array_equal(h.face_ranges[node_ids[kept]], ranges[kept].astype(np.uint32))
        assert len(f.cut(clusters=50)[0]) >= 50
        node = int(f.cut(clusters=20)[0][3])
        vertices, triangles, original = f.mesh(node)
        first, count = h.face_ranges[node]
        assert triangles.shape == (count, 3) and original.shape == (count,)
        assert np.array_equal(original, h.face_order[first: first + count])
        assert np.array_equal(vertices[triangles], h.vertices[h.triangles[first: first + count]])
        # The clusters of a cut, in face order, each with its triangles.
        seen = 0
        for node_id, start, n, v, t, ids in f.clusters(clusters=30):
            assert start == seen and t.shape == (n, 3) and ids.shape == (n,)
            seen += n
        assert seen == h.face_count


def test_decoding_releases_the_gil(files):
    with facetree.open(files[0]) as f:
        ticks = []
        stop = threading.Event()
        ticker = threading.Thread(
            target=lambda: [ticks.append(1) or stop.wait(0.001) for _ in iter(stop.is_set, True)])
        ticker.start()
        try:
            for _ in range(5):
                f.nodes()
        finally:
            stop.set()
            ticker.join()
        assert len(ticks) > 0


def test_closed_reader_bad_arguments_and_corrupt_files_raise(files, tmp_path):
    f = facetree.open(files[0])
    with pytest.raises(facetree.InputError, match="exactly one of clusters, max_cost and depth"):
        f.cut(clusters=3, depth=2)
    with pytest.raises(facetree.InputError, match="past the"):
        f.faces(0, f.header["triangle_count"] + 1)
    f.close()
    assert f.closed
    with pytest.raises(facetree.InputError, match="the reader is closed"):
        len(f)
    bad = tmp_path / "bad.fch"
    data = bytearray(files[0].read_bytes())
    data[-20] ^= 0x40
    bad.write_bytes(bytes(data))
    with facetree.open(bad) as f:  # the header and the index are sound
        with pytest.raises(facetree.InputError, match=": .* frame .*checksum mismatch"):
            f.faces(0, f.header["triangle_count"])
    with pytest.raises(facetree.InputError, match="bad magic"):
        bad.write_bytes(b"nonsense")
        facetree.open(bad)


@pytest.mark.parametrize("which", [0, 1])
def test_the_cli_cut_as_npz_is_the_readers_cut_and_the_json_lines(files, which, cli, tmp_path):
    path = files[which]
    out = tmp_path / "cut.npz"
    run_cli(cli, "cut", path, "--clusters", "300", "-o", out, "--memory", "4M")
    lines = [json.loads(line) for line in run_cli(cli, "cut", path, "--clusters", "300").stdout.splitlines()]
    with facetree.open(path) as f, np.load(out) as arrays:
        node_ids, ranges = f.cut(clusters=300)
        assert np.array_equal(arrays["node"], node_ids)
        assert np.array_equal(np.stack([arrays["first"], arrays["triangles"]], axis=1), ranges)
        kept = node_ids >= 0
        nodes = f.nodes()[node_ids[kept]]
        for name, field in (("cost", "cost"), ("area", "area"), ("perimeter", "perimeter"),
                            ("center", "box_center"), ("half_extents", "box_half_extents")):
            assert np.array_equal(arrays[name][kept], nodes[field]), name
            assert np.isnan(arrays[name][~kept]).all(), name
        assert len(lines) == len(node_ids)
        for line, node, first, count, quaternion in zip(lines, arrays["node"], arrays["first"],
                                                        arrays["triangles"], arrays["orientation"]):
            assert (line["node"] if line["node"] is not None else -1) == node
            assert (line["first"], line["triangles"]) == (first, count)
            if line["node"] is not None:
                assert np.array_equal(np.float32(line["box"]["orientation"]), quaternion)


def test_an_open_descriptor_reads_as_the_path(files):
    path = files[0]
    fd = os.open(path, os.O_RDONLY)
    try:
        with facetree.open(fd, memory="1M") as by_fd, facetree.open(path) as by_path:
            assert len(by_fd) == len(by_path)
            assert np.array_equal(by_fd.nodes(), by_path.nodes())
    finally:
        os.close(fd)
    read, write = os.pipe()
    try:
        with pytest.raises(facetree.InputError, match=f"descriptor {read}: descriptor {read} is not a regular file"):
            facetree.open(read)
    finally:
        os.close(read), os.close(write)


def test_dragon_vrip_built_under_64m_cut_of_1000_gives_the_loaded_arrays(shared_data, cli, tmp_path):
    """open + cut(clusters=1000) + every cluster's mesh() against load() and its cut, on a file the
    CLI built under --memory 64M, read under 16M."""
    path = tmp_path / "dragon.fch"
    run_cli(cli, "build", shared_data / "dragon_vrip.ply.zst", "-o", path, "--memory", "64M")
    h = facetree.load(str(path))
    labels = h.cut(1000)  # the cluster of each input face, numbered along the face order
    with facetree.open(path, memory="16M") as f:
        node_ids, ranges = f.cut(clusters=1000)
        assert len(node_ids) == labels.max() + 1
        kept = node_ids >= 0
        assert np.array_equal(h.face_ranges[node_ids[kept]], ranges[kept].astype(np.uint32))
        seen = 0
        for k, (node_id, first, count) in enumerate(zip(node_ids, ranges[:, 0], ranges[:, 1])):
            if node_id >= 0:
                vertices, triangles, original = f.mesh(int(node_id))
            else:
                vertices, triangles, original = f.faces(int(first), int(count))
            assert first == seen and triangles.shape == (count, 3)
            assert np.array_equal(original, h.face_order[first: first + count])
            assert (labels[original] == k).all()
            assert np.array_equal(vertices[triangles], h.vertices[h.triangles[first: first + count]])
            # Local numbering: the vertices the cluster uses, each once.
            assert len(vertices) == len(np.unique(h.triangles[first: first + count]))
            seen += count
        assert seen == h.face_count


def test_rays_through_the_reader_hit_the_triangles_of_the_loaded_file(files):
    """f.intersect and f.occluded against a NumPy brute force over load()'s triangles (Moller and
    Trumbore in float64), on a whole file and a truncated one, for 1 and 2 threads."""
    for path in files:
        h = facetree.load(str(path))
        corners = h.vertices[h.triangles].astype(np.float64)  # (F, 3, 3), in the file's face order
        lo, hi = h.vertices.min(axis=0), h.vertices.max(axis=0)
        rng = np.random.default_rng(3)
        origins = (lo + (hi - lo) * rng.uniform(-1.0, 2.0, (200, 3))).astype(np.float32)
        targets = lo + (hi - lo) * rng.uniform(0.2, 0.8, (200, 3))
        directions = (targets - origins).astype(np.float32)
        with facetree.open(path, memory="2M") as f:
            t, face, original, uv = f.intersect(origins, directions)
            assert np.array_equal(f.intersect(origins, directions, threads=1)[1], face)
            assert np.array_equal(f.occluded(origins, directions), face >= 0)
            assert np.array_equal(f.occluded(origins, directions, t_max=0.0), np.zeros(200, bool))
        a, e1, e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
        hits = 0
        for i in range(len(origins)):
            o, d = origins[i].astype(np.float64), directions[i].astype(np.float64)
            p = np.cross(d, e2)
            det = (e1 * p).sum(axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = 1.0 / det
                s = o - a
                u = (s * p).sum(axis=1) * inv
                q = np.cross(s, e1)
                v = (q * d).sum(axis=1) * inv
                tt = (e2 * q).sum(axis=1) * inv
            ok = (det != 0) & (u >= 0) & (u <= 1) & (v >= 0) & (u + v <= 1) & (tt >= 0)
            if not ok.any():
                assert face[i] == -1 and np.isinf(t[i])
                continue
            hits += 1
            best = np.flatnonzero(ok)[np.argmin(tt[ok])]
            assert face[i] == best and t[i] == np.float32(tt[best])
            assert original[i] == h.face_order[best]
            assert np.allclose(uv[i], [u[best], v[best]], atol=1e-5)
        assert 20 < hits < 200


def test_boxes_through_the_reader_find_the_triangles_a_numpy_scan_finds(files):
    """f.overlap against the triangles whose corners' bounding box meets the query box and that a
    dense sampling of the triangle puts inside it: every sampled hit is found, and every triangle
    found has its bounds meeting the box."""
    path = files[0]
    h = facetree.load(str(path))
    corners = h.vertices[h.triangles]
    lo_all, hi_all = h.vertices.min(axis=0), h.vertices.max(axis=0)
    rng = np.random.default_rng(5)
    centres = lo_all + (hi_all - lo_all) * rng.uniform(0, 1, (60, 3))
    halves = (hi_all - lo_all) * rng.uniform(0.002, 0.1, (60, 3))
    lo, hi = (centres - halves).astype(np.float32), (centres + halves).astype(np.float32)
    with facetree.open(path, memory="2M") as f:
        offsets, faces = f.overlap(lo, hi)
        assert np.array_equal(f.overlap(lo, hi, threads=1)[1], faces)
    w = rng.dirichlet([1, 1, 1], 64)  # points spread over each triangle
    samples = np.einsum("sk,fkd->fsd", w, corners)
    found_any = 0
    for i in range(len(lo)):
        got = faces[offsets[i]:offsets[i + 1]]
        assert np.all(np.diff(got) > 0)
        tri_lo, tri_hi = corners[got].min(axis=1), corners[got].max(axis=1)
        assert np.all(tri_lo <= hi[i]) and np.all(tri_hi >= lo[i])
        inside = np.all((samples >= lo[i]) & (samples <= hi[i]), axis=2).any(axis=1)
        assert set(np.flatnonzero(inside)) <= set(got.tolist())
        found_any += len(got) > 0
    assert 10 < found_any < 60


def test_oriented_boxes_through_the_reader_find_the_triangles_a_numpy_scan_finds(files):
    """f.overlap_oriented: with identity axes it finds what f.overlap finds; with rotated boxes every
    triangle with a sampled point inside the box is found, and every triangle found meets the box
    on each of the box's own axes. Axes that are not a rotation are refused."""
    path = files[0]
    h = facetree.load(str(path))
    corners = h.vertices[h.triangles].astype(np.float64)
    lo_all, hi_all = h.vertices.min(axis=0), h.vertices.max(axis=0)
    rng = np.random.default_rng(11)
    n = 40
    centres = (lo_all + (hi_all - lo_all) * rng.uniform(0, 1, (n, 3))).astype(np.float32)
    halves = ((hi_all - lo_all).max() * rng.uniform(0.01, 0.15, (n, 3))).astype(np.float32)
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    axes = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    axes[np.linalg.det(axes) < 0, :, 2] *= -1
    axes = axes.astype(np.float32)
    identity = np.repeat(np.eye(3, dtype=np.float32)[None], n, axis=0)
    w = rng.dirichlet([1, 1, 1], 64)
    samples = np.einsum("sk,fkd->fsd", w, corners)
    with facetree.open(path, memory="2M") as f:
        same = f.overlap_oriented(centres, halves, identity)
        expected = f.overlap(centres - halves, centres + halves)
        assert np.array_equal(same[0], expected[0]) and np.array_equal(same[1], expected[1])
        offsets, faces = f.overlap_oriented(centres, halves, axes)
        assert np.array_equal(f.overlap_oriented(centres, halves, axes, threads=1)[1], faces)
        with pytest.raises(ValueError, match=r"overlap_oriented: axes\[0\] is not a rotation"):
            f.overlap_oriented(centres[:1], halves[:1], 2 * identity[:1])
    found_any = 0
    for i in range(n):
        got = faces[offsets[i]:offsets[i + 1]]
        assert np.all(np.diff(got) > 0)
        local = np.einsum("dk,fsd->fsk", axes[i].astype(np.float64), samples - centres[i])
        inside = np.all(np.abs(local) <= halves[i], axis=2).any(axis=1)
        assert set(np.flatnonzero(inside)) <= set(got.tolist())
        along = np.einsum("dk,fcd->fck", axes[i].astype(np.float64), corners[got] - centres[i])
        assert np.all(along.min(axis=1) <= halves[i] * (1 + 1e-5) + 1e-6)
        assert np.all(along.max(axis=1) >= -halves[i] * (1 + 1e-5) - 1e-6)
        found_any += len(got) > 0
    assert 5 < found_any <= n


def test_nearest_points_through_the_reader_are_on_the_nearest_triangle(files):
    """f.nearest: each point found lies on its triangle, no triangle corner is nearer than it, and a
    radius below the distance finds nothing."""
    path = files[1]
    h = facetree.load(str(path))
    corners = h.vertices[h.triangles].astype(np.float64)
    lo, hi = h.vertices.min(axis=0), h.vertices.max(axis=0)
    points = (lo + (hi - lo) * np.random.default_rng(8).uniform(-0.2, 1.2, (100, 3))).astype(np.float32)
    with facetree.open(path, memory="2M") as f:
        distance, face, original, point = f.nearest(points)
        assert (face >= 0).all() and np.array_equal(original, h.face_order[face])
        assert np.allclose(np.linalg.norm(point - points, axis=1), distance, rtol=1e-5)
        nearest_corner = np.linalg.norm(corners - points[:, None, None, :].astype(np.float64), axis=3).min(axis=(1, 2))
        assert (distance <= nearest_corner * (1 + 1e-6) + 1e-7).all()
        for i in range(len(points)):  # the point lies in its triangle's plane, within its bounds
            tri = corners[face[i]]
            n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
            assert abs(np.dot(point[i] - tri[0], n)) <= 1e-4 * np.linalg.norm(n) * (np.abs(tri).max() + 1)
        far, none, _, _ = f.nearest(points, radius=float(distance.min()) * 0.5)
        assert (none == -1).all() and np.isinf(far).all()
