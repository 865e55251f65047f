"""facetree.build on NumPy arrays: the CLI's bytes for the same mesh and options, the input used
in place when its dtypes fit, and one clear exception for each kind of bad array."""
import numpy as np
import pytest

import facetree
from conftest import grid_mesh, run_cli

# Every shared mesh.
SHARED = ["bunny_npm_lowres", "openfoam_flange", "fandisk", "gears_cad", "rocker_arm", "pepper_scan",
          "tigerfighter_31k", "grey_nurse_shark", "bunny_zipper", "horse_97k", "nefertiti_100k",
          "openfoam_dtc_hull", "cura_ultimaker_robot", "turbine_blade_200k", "openfoam_buildings",
          "dragon_vrip", "matterport_cedar_creek", "fg_hawaii"]


@pytest.mark.parametrize("name", SHARED)
def test_arrays_give_the_cli_bytes(name, cli, shared_data, tmp_path):
    path = shared_data / f"{name}.ply.zst"
    vertices, faces, ids = facetree.read_mesh(path)
    h = facetree.build(vertices, faces, face_ids=ids)
    h.save(tmp_path / "py.fch")
    run_cli(cli, "build", path, "-o", tmp_path / "cli.fch")
    assert (tmp_path / "py.fch").read_bytes() == (tmp_path / "cli.fch").read_bytes()
    assert h.report["triangles"] == len(faces)
    assert h.report["input_copied"] == {"vertices": False, "faces": False}


@pytest.mark.parametrize("options,flags", [
    ({"branching": 4}, ["--branching", "4"]),
    ({"branching": 8, "recast": "fewest-nodes"}, ["--branching", "8", "--recast", "fewest-nodes"]),
    ({"metric": "garland"}, ["--metric", "garland"]),
    ({"order": "exact"}, ["--order", "exact"]),
    ({"k": 1e-3, "balance_slack": 0}, ["--k", "0.001", "--balance-slack", "0"]),
    ({"weld": True}, ["--weld"]),
    ({"top": 0}, ["--top", "0"]),
    ({"top": 16, "order": "exact"}, ["--top", "16", "--order", "exact"]),
])
def test_options_give_the_cli_bytes(options, flags, cli, shared_data, tmp_path):
    path = shared_data / "gears_cad.ply.zst"
    vertices, faces, ids = facetree.read_mesh(path)
    facetree.build(vertices, faces, face_ids=ids, **options).save(tmp_path / "py.fch")
    run_cli(cli, "build", path, "-o", tmp_path / "cli.fch", *flags)
    assert (tmp_path / "py.fch").read_bytes() == (tmp_path / "cli.fch").read_bytes()


def test_other_dtypes_are_converted_to_the_same_hierarchy(bunny, tmp_path):
    vertices, faces, _, _ = bunny
    reference = facetree.build(vertices, faces)
    reference.save(tmp_path / "reference.fch")
    for v, f in [(vertices.astype(np.float64), faces.astype(np.int64)),
                 (vertices, faces.astype(np.int32)),
                 (np.asfortranarray(vertices), faces.astype(np.uint64)),
                 (vertices.tolist()[:], faces)]:
        h = facetree.build(v, f)
        h.save(tmp_path / "other.fch")
        assert (tmp_path / "other.fch").read_bytes() == (tmp_path / "reference.fch").read_bytes()
    in_place = facetree.build(vertices, faces.astype(np.int32)).report["input_copied"]
    assert in_place == {"vertices": False, "faces": False}
    copied = facetree.build(vertices.astype(np.float64), faces.astype(np.int64)).report["input_copied"]
    assert copied == {"vertices": True, "faces": True}


def test_the_result_is_the_same_for_every_thread_count(bunny, tmp_path):
    vertices, faces, _, _ = bunny
    for threads in (1, 2, 3):
        facetree.build(vertices, faces, threads=threads).save(tmp_path / f"{threads}.fch")
    assert (tmp_path / "1.fch").read_bytes() == (tmp_path / "2.fch").read_bytes() == (tmp_path / "3.fch").read_bytes()


def bad(vertices, faces, message, **options):
    with pytest.raises(facetree.InputError) as raised:
        facetree.build(vertices, faces, **options)
    assert str(raised.value) == message
    assert raised.value.exit_code == 3 and raised.value.category == "input"
    assert isinstance(raised.value, ValueError)


def test_options_are_keywords_checked_by_name_and_type():
    vertices, faces = grid_mesh(4)
    with pytest.raises(TypeError) as raised:
        facetree.build(vertices, faces, metirc="garland")
    assert str(raised.value) == "build() got an unexpected keyword argument 'metirc'"
    with pytest.raises(TypeError) as raised:
        facetree.build(vertices, faces, k="small")
    assert str(raised.value) == "build(): k must be a float, not str"
    with pytest.raises(TypeError) as raised:
        facetree.build(vertices, faces, branching=4.0)
    assert str(raised.value) == "build(): branching must be a non-negative int, not float"
    with pytest.raises(TypeError) as raised:
        facetree.build(vertices, faces, threads=-1)
    assert str(raised.value) == "build(): threads must be a non-negative int, not int"
    with pytest.raises(TypeError) as raised:
        facetree.build(vertices, faces, 2)
    # The defaults the docstring names are the ones a call without options gets.
    doc = facetree.build.__doc__
    for default in ('metric: "willmott"', '["willmott"]', '["rounds"]', "[0.0001]", "[1.5]", "[0.5]", "[2]",
                    '["largest-area"]', "[False]"):
        assert default in doc, default
    plain = facetree.build(vertices, faces)
    named = facetree.build(vertices, faces, metric="willmott", order="rounds", k=1e-4, balance_slack=1.5,
                           flat_threshold=0.5, branching=2, recast="largest-area", threads=0, weld=False)
    assert np.array_equal(plain.cost, named.cost) and np.array_equal(plain.face_ranges, named.face_ranges)
    assert plain.header == named.header


def test_bad_arrays_raise_one_clear_input_error():
    vertices, faces = grid_mesh(4)
    bad(vertices[:, :2], faces, "vertices: expected shape (N, 3), got (25, 2)")
    bad(vertices.ravel(), faces, "vertices: expected shape (N, 3), got (75,)")
    bad(vertices, faces.reshape(-1, 2), "faces: expected shape (N, 3), got (48, 2)")
    bad(vertices, faces[:0], "faces: no triangles to cluster")
    bad(vertices[:0], faces, "faces: row 0, column 0: vertex index 0 is out of range (0 vertices)")
    negative = faces.copy()
    negative[5, 1] = -7
    bad(vertices, negative, "faces: row 5, column 1: vertex index -7 is negative")
    bad(vertices, negative.astype(np.int64), "faces: row 5, column 1: vertex index -7 is negative")
    high = faces.astype(np.int64)
    high[3, 2] = 25
    bad(vertices, high, "faces: row 3, column 2: vertex index 25 is out of range (25 vertices)")
    bad(vertices, high.astype(np.uint32), "faces: row 3, column 2: vertex index 25 is out of range (25 vertices)")
    nan = vertices.copy()
    nan[7, 2] = np.nan
    bad(nan, faces, "vertices: row 7 is not finite (2, 1, nan)")
    infinite = vertices.astype(np.float64)
    infinite[2, 0] = np.inf
    bad(infinite, faces, "vertices: row 2 is not finite (inf, 0, 0)")
    bad(vertices, faces.astype(np.float32), "faces: expected an integer array, got dtype float32")
    bad(vertices.astype(np.complex64), faces, "vertices: expected a float array, got dtype complex64")
    bad(vertices, faces, "unknown metric 'bogus' (willmott, garland, constant)", metric="bogus")
    bad(vertices, faces, "branching must be 2, 4 or 8", branching=3)
    bad(vertices, faces, "unknown box precision 'tight' (exact, compact)", boxes="tight")
    bad(vertices, faces, "face_ids: expected shape (32,), one id per row of faces", face_ids=np.arange(3))
    bad(vertices, faces, "face_ids: ids must be distinct", face_ids=np.zeros(32, np.int64))
    with pytest.raises(facetree.InputError, match="expected a NumPy array"):
        facetree.build(None, faces)
