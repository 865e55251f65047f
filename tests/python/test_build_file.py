"""facetree.build_file: the CLI's job from Python, in core and out of core, with its report,
file objects, progress, cancellation (callback and Ctrl-C) and errors."""
import io
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import facetree
from conftest import run_cli


def test_in_core_job_gives_the_cli_bytes_and_report_fields(bunny, cli, tmp_path):
    path = bunny[3]
    report = facetree.build_file(path, tmp_path / "py.fch")
    cli_report = json.loads(run_cli(cli, "build", path, "-o", tmp_path / "cli.fch", "--json").stdout)
    assert (tmp_path / "py.fch").read_bytes() == (tmp_path / "cli.fch").read_bytes()
    assert report.keys() == cli_report.keys()
    for key in ("triangles", "vertices", "nodes", "height", "balanced_height", "out_of_core", "file_bytes"):
        assert report[key] == cli_report[key], key


def test_out_of_core_job_holds_its_cap_and_gives_the_cli_bytes(shared_data, cli, tmp_path):
    mesh = shared_data / "dragon_vrip.ply.zst"
    script = textwrap.dedent(f"""
        import json, resource, facetree
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        report = facetree.build_file({str(mesh)!r}, {str(tmp_path / 'py.fch')!r}, memory="64M",
                                     tmp={str(tmp_path)!r})
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        print(json.dumps({{"before": before, "after": after, "report": report}}))
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    measured = json.loads(result.stdout)
    report = measured["report"]
    assert report["out_of_core"] and report["cells"] > 1 and report["memory_cap_bytes"] == 64 << 20
    # The job's own peak, above what the interpreter and NumPy held before it started.
    assert measured["after"] - measured["before"] <= 64 << 20
    run_cli(cli, "build", mesh, "-o", tmp_path / "cli.fch", "--memory", "64M")
    assert (tmp_path / "py.fch").read_bytes() == (tmp_path / "cli.fch").read_bytes()
    # The job's and build_file's temporary folders are gone.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cli.fch", "py.fch"]


def test_file_objects_in_and_out(bunny, tmp_path):
    path = bunny[3]
    facetree.build_file(path, tmp_path / "reference.fch")
    reference = (tmp_path / "reference.fch").read_bytes()
    with open(path, "rb") as opened:
        facetree.build_file(opened, tmp_path / "from_file.fch")
    assert (tmp_path / "from_file.fch").read_bytes() == reference
    memory_in, memory_out = io.BytesIO(path.read_bytes()), io.BytesIO()
    report = facetree.build_file(memory_in, memory_out, tmp=tmp_path)
    assert memory_out.getvalue() == reference and report["file_bytes"] == len(reference)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["from_file.fch", "reference.fch"]


def test_progress_reports_each_stage_and_can_cancel(bunny, tmp_path):
    path = bunny[3]
    seen = []
    facetree.build_file(path, tmp_path / "out.fch", cell_faces=5000, tmp=tmp_path,
                        progress=lambda stage, fraction: seen.append((stage, fraction)))
    stages = [stage for stage, _ in seen]
    assert [s for i, s in enumerate(stages) if i == 0 or stages[i - 1] != s] == ["read", "bin", "cells", "merge", "write"]
    for stage in ("bin", "cells", "write"):
        fractions = [f for s, f in seen if s == stage]
        assert all(0 <= f <= 1 for f in fractions) and fractions == sorted(fractions)
    for stop_at in ("read", "bin", "cells", "write"):
        out = tmp_path / f"cancelled_{stop_at}.fch"
        with pytest.raises(facetree.Cancelled) as raised:
            facetree.build_file(path, out, cell_faces=5000, tmp=tmp_path,
                                progress=lambda stage, fraction, stop_at=stop_at: stage != stop_at)
        assert raised.value.exit_code == 130
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out.fch"]


def test_an_exception_in_the_callback_cancels_and_is_raised(bunny, tmp_path):
    def progress(stage, fraction):
        if stage == "cells":
            raise ZeroDivisionError("from the callback")
    with pytest.raises(ZeroDivisionError, match="from the callback"):
        facetree.build_file(bunny[3], tmp_path / "out.fch", cell_faces=5000, tmp=tmp_path, progress=progress)
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_cancels_and_leaves_nothing_behind(shared_data, tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    script = textwrap.dedent(f"""
        import sys, facetree
        def progress(stage, fraction):
            if stage == "cells":
                print("cells", flush=True)
        try:
            facetree.build_file({str(shared_data / 'dragon_vrip.ply.zst')!r}, {str(work / 'out.fch')!r},
                                cell_faces=20000, tmp={str(work)!r}, progress=progress)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(0)
        print("finished", flush=True)
    """)
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline() == "cells\n"
    child.send_signal(signal.SIGINT)
    output = child.stdout.read()
    assert child.wait(timeout=60) == 0
    assert output.strip().split("\n")[-1] == "interrupted"
    assert list(work.iterdir()) == []


def test_the_gil_is_released_while_the_library_works(shared_data):
    vertices, faces, _ = facetree.read_mesh(shared_data / "turbine_blade_200k.ply.zst")
    counted, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            counted[0] += 1

    counter = threading.Thread(target=count)
    counter.start()
    try:
        before = counted[0]
        facetree.build(vertices, faces)
        during = counted[0] - before
    finally:
        stop.set()
        counter.join()
    # Holding the GIL, the library would leave the counter no turn until it returned.
    assert during > 10000


def message_of(cli, *args):
    result = run_cli(cli, *args, check=False)
    assert result.stderr.startswith("facetree: ")
    return result.returncode, result.stderr[len("facetree: "):].strip()


def test_errors_carry_the_cli_categories_and_messages(cli, test_data, shared_data, tmp_path):
    missing = tmp_path / "missing.ply"
    code, message = message_of(cli, "build", missing, "-o", tmp_path / "x.fch")
    with pytest.raises(facetree.InputError) as raised:
        facetree.build_file(missing, tmp_path / "x.fch")
    assert (raised.value.exit_code, str(raised.value)) == (code, message)

    truncated = tmp_path / "truncated.ply"
    truncated.write_bytes((shared_data / "bunny_zipper.ply.zst").read_bytes()[:5000])
    code, message = message_of(cli, "build", truncated, "-o", tmp_path / "x.fch")
    with pytest.raises(facetree.InputError) as raised:
        facetree.build_file(truncated, tmp_path / "x.fch")
    assert (raised.value.exit_code, str(raised.value)) == (code, message)

    dragon = shared_data / "dragon_vrip.ply.zst"
    code, message = message_of(cli, "build", dragon, "--memory", "64M")
    with pytest.raises(facetree.ResourceError) as raised:
        facetree.build_file(dragon, None, memory="64M")
    assert (raised.value.exit_code, str(raised.value)) == (code, message)

    with pytest.raises(facetree.ResourceError) as raised:
        facetree.build_file(dragon, tmp_path / "x.fch", memory="64M", max_tmp="1M", tmp=tmp_path)
    assert raised.value.exit_code == 5
    assert str(raised.value).endswith(": temporary files would exceed --max-tmp 1048576 bytes")

    for output in (tmp_path / "no" / "dir" / "x.fch", tmp_path):
        code, message = message_of(cli, "build", shared_data / "fandisk.ply.zst", "-o", output)
        with pytest.raises(facetree.OutputError) as raised:
            facetree.build_file(shared_data / "fandisk.ply.zst", output)
        assert (raised.value.exit_code, str(raised.value)) == (code, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["truncated.ply"]

    with pytest.raises(facetree.InputError, match="a size must be a whole number"):
        facetree.build_file(dragon, tmp_path / "x.fch", memory="lots")
    with pytest.raises(facetree.InputError, match="memory must be at least 16M"):
        facetree.build_file(dragon, tmp_path / "x.fch", memory="1M")
    with pytest.raises(TypeError) as raised:
        facetree.build_file(dragon, tmp_path / "x.fch", brnaching=4)
    assert str(raised.value) == "build_file() got an unexpected keyword argument 'brnaching'"
