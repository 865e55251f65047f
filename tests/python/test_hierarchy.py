"""A Hierarchy's arrays against the format's promises: face ranges partitioned by the children,
parents before children, exact boxes, costs in file order; cuts against `facetree export`;
truncation against `facetree truncate`; load and save round trips."""
import numpy as np
import pytest

import facetree
from conftest import run_cli


@pytest.fixture(scope="module")
def hierarchy(bunny):
    vertices, faces, ids, _ = bunny
    return facetree.build(vertices, faces, face_ids=ids, branching=4)


def test_children_partition_their_parents_face_range(hierarchy):
    h = hierarchy
    ranges = h.face_ranges.astype(np.int64)
    assert ranges.shape == (len(h), 2) and tuple(ranges[0]) == (0, h.face_count)
    parent, children = h.parent, h.children
    assert parent[0] == -1 and (parent[1:] >= 0).all() and (parent[1:] < np.arange(1, len(h))).all()
    for node in range(0, len(h), 97):
        first, count = ranges[node]
        # Node children and single faces tile [first, first + count) in order.
        covered = first
        for child in children[node][: h.child_count[node]]:
            if child >= 0:
                assert ranges[child, 0] == covered and parent[child] == node
                covered += ranges[child, 1]
            else:
                covered += 1
        assert covered == first + count
    assert np.array_equal(np.sort(h.face_order), np.arange(h.face_count))


def test_boxes_contain_their_faces_and_touch_them(hierarchy):
    h = hierarchy
    vertices, triangles = h.vertices, h.triangles
    axes, centre, half = h.box_axes, h.box_center, h.box_half_extents
    for node in list(range(0, len(h), 211)) + [0]:
        first, count = h.face_ranges[node]
        points = vertices[np.unique(triangles[first:first + count])]
        local = (points - centre[node]) @ axes[node].T
        slack = 1e-5 * (np.abs(local).max() + 1e-30) + 1e-6 * np.abs(centre[node]).max()
        assert (np.abs(local) <= half[node] + slack).all()
        assert np.allclose(np.abs(local).max(axis=0), half[node], atol=2 * slack)
        assert np.allclose(axes[node] @ axes[node].T, np.eye(3), atol=1e-5)


def test_nodes_are_in_decreasing_effective_cost(hierarchy, bunny):
    assert (hierarchy.effective_cost >= hierarchy.cost).all()
    binary = facetree.build(bunny[0], bunny[1])
    effective = binary.effective_cost
    assert (np.diff(effective) <= 0).all() and (effective >= binary.cost).all()
    # The effective cost is the cost's running maximum up from the faces: a node's is its own or a child's.
    children = binary.children
    best_child = np.where(children >= 0, effective[np.maximum(children, 0)], -np.inf).max(axis=1)
    assert np.array_equal(effective, np.maximum(binary.cost, best_child).astype(np.float32))


def test_arrays_are_read_only_views_that_keep_the_hierarchy_alive(bunny):
    vertices, faces, _, _ = bunny
    cost = facetree.build(vertices, faces).cost
    assert not cost.flags.writeable
    with pytest.raises(ValueError):
        cost[0] = 1
    assert np.isfinite(cost).all() and len(cost) == len(faces) - 1


def test_cut_matches_facetree_export(hierarchy, cli, tmp_path):
    hierarchy.save(tmp_path / "h.fch")
    for clusters in (1, 64, 1000):
        labels = hierarchy.cut(clusters)
        assert labels.shape == (hierarchy.input_face_count,) and labels.min() == 0
        assert labels.max() + 1 >= min(clusters, hierarchy.face_count)
        run_cli(cli, "export", tmp_path / "h.fch", "--cut", clusters, "-o", tmp_path / "cut.ply")
        exported = read_coloured_ply(tmp_path / "cut.ply")
        # The export lists faces in hierarchy order; labels are per input face.
        expected = facetree.cluster_colours(labels[hierarchy.face_order.astype(np.int64)])
        assert np.array_equal(exported, expected)


def read_coloured_ply(path):
    """Face colours of `facetree export`'s binary PLY (uchar 3, int a, b, c, uchar r, g, b)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    vertices = int(next(line for line in header if line.startswith("element vertex")).split()[2])
    faces = int(next(line for line in header if line.startswith("element face")).split()[2])
    record = np.dtype([("n", "u1"), ("v", "<i4", 3), ("rgb", "u1", 3)])
    return np.frombuffer(data, record, faces, end + 12 * vertices)["rgb"]


def assert_stored_as(loaded, memory):
    """`loaded` read from a file of `memory` with exact boxes: S within 2^-12 of the area a component,
    side areas within 2^-11 of it, half extents at most 2^-17 of the largest above (docs/FORMAT.md)."""
    area = memory.area.astype(np.float64)
    assert np.all(np.abs(loaded.sum_normal - memory.sum_normal) <= 2.0**-12 * 1.001 * area[:, None])
    assert np.all(np.abs(loaded.box_side_areas - memory.box_side_areas) <= 2.0**-11 * 1.001 * area[:, None])
    over = loaded.box_half_extents.astype(np.float64) - memory.box_half_extents
    largest = memory.box_half_extents.max(axis=1).astype(np.float64)
    assert np.all(over >= 0) and np.all(over <= 2.0**-17 * largest[:, None])


def test_truncate_is_the_cli_truncate_and_load_reads_it(hierarchy, cli, tmp_path):
    hierarchy.save(tmp_path / "h.fch")
    run_cli(cli, "truncate", tmp_path / "h.fch", "--nodes", 500, "-o", tmp_path / "t.fch")
    loaded = facetree.load(tmp_path / "t.fch")
    truncated = hierarchy.truncate(500)
    assert len(loaded) == len(truncated) == 500 and loaded.truncated and truncated.truncated
    for field in ("face_ranges", "children", "parent", "cost", "flags", "box_center", "box_axes", "face_order",
                  "vertices", "triangles"):
        assert np.array_equal(getattr(loaded, field), getattr(truncated, field)), field
    assert_stored_as(loaded, truncated)
    truncated.verify()
    assert np.array_equal(loaded.cut(100), truncated.cut(100))


def test_load_round_trip(hierarchy, tmp_path):
    hierarchy.save(tmp_path / "h.fch")
    loaded = facetree.load(tmp_path / "h.fch")
    assert loaded.report is None and loaded.height == hierarchy.height and loaded.branching == 4
    assert loaded.header["metric"] == "willmott" and loaded.header["triangle_count"] == hierarchy.face_count
    for field in ("face_ranges", "children", "cost", "effective_cost", "box_axes", "box_center", "area"):
        assert np.array_equal(getattr(loaded, field), getattr(hierarchy, field)), field
    assert_stored_as(loaded, hierarchy)
    fit = loaded.cut_fit(1000)
    assert fit["clusters"] >= 1000 and fit["sum_area_fit"] > 0
    assert 0 < fit["sum_box_area"] and 0 < fit["morton_box_area"]


def test_bad_cluster_files_raise_input_errors(tmp_path, hierarchy):
    with pytest.raises(facetree.InputError) as raised:
        facetree.load(tmp_path / "missing.fch")
    assert str(tmp_path / "missing.fch") in str(raised.value)
    hierarchy.save(tmp_path / "h.fch")
    data = (tmp_path / "h.fch").read_bytes()
    (tmp_path / "cut.fch").write_bytes(data[: len(data) // 2])
    with pytest.raises(facetree.InputError, match="cut.fch"):
        facetree.load(tmp_path / "cut.fch")
    with pytest.raises(facetree.OutputError) as raised:
        hierarchy.save(tmp_path / "no" / "such" / "dir.fch")
    assert raised.value.exit_code == 4
