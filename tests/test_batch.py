"""``lightprobe batch``: single-file results bit for bit, exactly-once under SIGKILL of the driver and of a worker,
Dask's table equal to the local pool's, and bad input refused with one line and nothing written."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import shared
from lightprobe.cli import main
from lightprobe.maps.images import write_image

pytestmark = pytest.mark.xdist_group("batch")
EXE = str(Path(sys.executable).with_name("lightprobe"))
COMPARED = ("path", "sha256", "size", "layout", "width", "height", "integral", "sh", "sh_order", "light_count",
            "lights", "lights_json", "thumbnail")


def table(folder: Path, name: str = "results.parquet") -> list[dict]:
    import pyarrow.parquet as pq

    return pq.read_table(folder / name).to_pylist()


def make_dataset(folder: Path, synthetic: int = 196, real: tuple = ()) -> dict:
    """``synthetic`` small maps (noise and one or two suns), the ``real`` probe files, and 11 corrupt files (5 % of
    211): truncated, garbage, empty, lying headers. Returns the good and bad paths and a list file of all."""
    rng = np.random.default_rng(7)
    good, bad = [], []
    for i in range(synthetic):
        img = rng.uniform(0.05, 0.5, (16, 32, 3)).astype(np.float32)
        for _ in range(1 + i % 2):
            img[rng.integers(1, 8), rng.integers(0, 32)] = rng.uniform(50, 500, 3)
        path = folder / f"synthetic_{i:03d}.{'exr' if i % 3 else 'hdr'}"
        write_image(path, img)
        good.append(path)
    good += [Path(p) for p in real]
    valid = good[1].read_bytes()
    corrupt = {"truncated.exr": valid[: len(valid) // 3], "garbage.hdr": os.urandom(3000), "empty.exr": b"",
               "text.hdr": b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 99999999 +X 99999999\n",
               "header_only.exr": valid[:40], "zeros.hdr": bytes(5000), "png_named.exr": b"\x89PNG\r\n\x1a\n" * 10,
               "half.exr": valid[: len(valid) // 2], "tiny.hdr": b"#?", "nul.exr": b"\x00" * 17,
               "lies.hdr": b"#?RADIANCE\n\n-Y 2 +X 4\n" + b"\xff" * 3}
    for name, data in corrupt.items():
        (folder / name).write_bytes(data)
        bad.append(folder / name)
    listing = folder / "inputs.txt"
    listing.write_text("\n".join(str(p) for p in good + bad) + "\n")
    return {"good": [str(p) for p in good], "bad": [str(p) for p in bad], "list": listing}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """≥ 200 inputs: 196 synthetic maps, 4 real probes, and 11 corrupt files (5 %)."""
    return make_dataset(tmp_path_factory.mktemp("dataset"), 196,
                        [shared(f"ict_lowres/{n}") for n in ("grace.hdr", "pisa.hdr", "uffizi.hdr", "ennis.hdr")])


def batch(args, **kw):
    return subprocess.run([EXE, "batch", *map(str, args)], capture_output=True, text=True, timeout=600, **kw)


ARGS = ("--jobs", "sh,thumbnail", "--order", "3", "--workers", "2", "--chunk", "8")


@pytest.fixture(scope="module")
def reference(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("reference") / "run"
    res = batch([dataset["list"], "--out", out, *ARGS])
    assert res.returncode == 0, res.stderr
    return out


def check_exactly_once(out: Path, dataset, reference: Path) -> None:
    rows, errors = table(out), table(out, "errors.parquet")
    paths = [r["path"] for r in rows]
    assert sorted(paths) == sorted(dataset["good"]) and len(set(paths)) == len(paths)
    assert sorted(e["path"] for e in errors) == sorted(dataset["bad"])
    ours = {r["path"]: {k: r[k] for k in COMPARED} for r in rows}
    theirs = {r["path"]: {k: r[k] for k in COMPARED} for r in table(reference)}
    assert ours == theirs
    for r in rows:
        assert (out / r["thumbnail"]).is_file() and len(r["sh"]) == 3 * 16
    leftovers = [str(p.relative_to(out)) for p in out.rglob(".*tmp*")]
    assert not leftovers, leftovers


def test_uninterrupted_batch_records_every_input_once(dataset, reference):
    check_exactly_once(reference, dataset, reference)
    errors = {Path(e["path"]).name: e for e in table(reference, "errors.parquet")}
    assert all(e["message"] and "\n" not in e["message"] for e in errors.values())
    assert errors["empty.exr"]["sha256"] is not None and errors["empty.exr"]["size"] == 0


def _workers_of(pid: int) -> list[int]:
    """The pool's worker processes among ``pid``'s children (spawned interpreters, not the resource tracker)."""
    try:
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return []
    out = []
    for child in map(int, children):
        try:
            cmd = Path(f"/proc/{child}/cmdline").read_bytes().replace(b"\0", b" ")
        except OSError:
            continue
        if b"spawn_main" in cmd and b"resource_tracker" not in cmd:
            out.append(child)
    return out


def _gone(pid: int) -> bool:
    """True once process ``pid`` has exited (a zombie waiting for its reaper counts as gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return True


def wait_until(condition, what: str, seconds: float = 600) -> None:
    """Poll ``condition`` until it holds; fail naming ``what`` after ``seconds`` (generous: a deadline, not a speed)."""
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, f"still waiting after {seconds} s for {what}"
        time.sleep(0.05)


def kill_and_resume(listing: Path, out: Path, args, kills: int = 5, seed: int = 2026) -> tuple[str, int | None]:
    """The driver killed with SIGKILL at ``kills`` random moments and resumed each time, then resumed to the end
    with one worker killed mid-task. Returns the last run's summary line and the killed worker's pid."""
    rng = np.random.default_rng(seed)
    parts = out / "parts"
    committed = lambda: len(list(parts.glob("*.parquet"))) if parts.is_dir() else 0  # noqa: E731
    for k in range(kills):
        before = committed()
        proc = subprocess.Popen([EXE, "batch", str(listing), "--out", str(out), *args, *(["--resume"] if k else [])],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        # once this run has committed something, at a random moment after
        wait_until(lambda: proc.poll() is not None or committed() > before, "a part committed by the run")
        time.sleep(float(rng.uniform(0.0, 0.3)))
        workers = _workers_of(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        wait_until(lambda: all(map(_gone, workers)), "the kernel to end the orphaned workers (PR_SET_PDEATHSIG)")
    before = committed()
    proc = subprocess.Popen([EXE, "batch", str(listing), "--out", str(out), *args, "--resume"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed = None
    # a worker killed mid-task: once the run has committed a part, its workers are past their start-up and busy
    wait_until(lambda: proc.poll() is not None or committed() > before, "a part committed by the last run")
    workers = _workers_of(proc.pid)
    if workers and proc.poll() is None:
        try:
            os.kill(workers[0], signal.SIGKILL)
            killed = workers[0]
        except ProcessLookupError:
            pass
    stdout, stderr = proc.communicate(timeout=900)
    assert proc.returncode == 0, stderr
    assert "already there" in stdout  # the killed runs had committed work that this one kept
    assert killed is not None, "the last run ended before a worker could be killed"
    return stdout.strip(), killed


def test_sigkill_of_the_driver_and_of_a_worker_loses_and_duplicates_nothing(dataset, reference, tmp_path):
    summary, killed = kill_and_resume(dataset["list"], tmp_path / "killed", ARGS)
    print(summary, f"(worker {killed} killed)" if killed else "(the run ended before a worker was killed)")
    check_exactly_once(tmp_path / "killed", dataset, reference)


def test_dask_local_cluster_gives_the_local_pools_table(dataset, tmp_path):
    inputs = dataset["good"][:24] + dataset["bad"][:2]
    local, dask = tmp_path / "local", tmp_path / "dask"
    assert batch([*inputs, "--out", local, "--jobs", "sh,lights,thumbnail", *ARGS[2:]]).returncode == 0
    res = batch([*inputs, "--out", dask, "--jobs", "sh,lights,thumbnail", "--order", "3", "--dask-local", "2"])
    assert res.returncode == 0, res.stderr
    assert "Dask distributed" in res.stdout
    strip = lambda rows: sorted(({k: r[k] for k in COMPARED if k != "thumbnail"} for r in rows),  # noqa: E731
                                key=lambda r: r["path"])
    assert strip(table(local)) == strip(table(dask))
    assert [e["path"] for e in table(local, "errors.parquet")] == [e["path"] for e in table(dask, "errors.parquet")]


def test_batch_equals_the_single_file_commands_bit_for_bit(tmp_path):
    probe = shared("ict_lowres/grace.hdr")
    out = tmp_path / "b"
    assert main(["batch", str(probe), "--out", str(out), "--jobs", "sh,lights,irradiance,radiance,thumbnail",
                 "--order", "4", "--size", "8", "--workers", "1"]) == 0
    row = table(out)[0]
    # the single-file command as a user runs it: its own process (the CLI sets single-threaded BLAS at start)
    assert subprocess.run([EXE, "sh", str(probe), "--order", "4", "-o", str(tmp_path / "sh.json")]).returncode == 0
    single = json.loads((tmp_path / "sh.json").read_text())
    assert row["sh"] == [v for rgb in single["coefficients"] for v in rgb]  # rows of R, G, B; floats round-trip
    assert subprocess.run([EXE, "lights", str(probe), "-o", str(tmp_path / "lights.json")]).returncode == 0
    a, b = json.loads((out / row["lights_json"]).read_text()), json.loads((tmp_path / "lights.json").read_text())
    for doc in (a, b):
        doc.pop("timings"), doc.pop("source")
    assert a == b and row["light_count"] == len(b["lights"])
    assert subprocess.run([EXE, "irradiance", str(probe), "-o", str(tmp_path / "irr.exr"), "--order", "4"]
                          ).returncode == 0
    from lightprobe.maps.images import read_image

    assert np.array_equal(read_image(out / row["irradiance"]), read_image(tmp_path / "irr.exr"))
    assert subprocess.run([EXE, "radiance", str(probe), "--brdf", "ggx:alpha=0.2", "--size", "8", "-o",
                           str(tmp_path / "rad")]).returncode == 0
    for k in (0, 5, 11):
        name = f"view_{k:03d}.exr"
        assert np.array_equal(read_image(out / row["radiance"] / name), read_image(tmp_path / "rad" / name))
    assert row["width"] == 256 and row["layout"] == "latlong" and len(row["sh"]) == 3 * 25
    assert (out / row["thumbnail"]).stat().st_size > 100


def test_report_shows_thumbnails_histograms_and_failures(reference, tmp_path):
    assert main(["batch", "--report", str(reference)]) == 0
    page = (reference / "report.html").read_text()
    assert page.count("<img") >= 200 and "<svg" in page and "garbage.hdr" in page and "Lights per map" in page


# ---- bad input ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, words", [
    (["/nonexistent/*.hdr", "--out", "{tmp}/o"], "no file matches"),
    (["@{tmp}/empty.txt", "--out", "{tmp}/o"], "names no file"),
    (["{tmp}/x.hdr", "--out", "{tmp}/file/sub"], "not a writable folder"),
    (["{tmp}/x.hdr", "--out", "{tmp}/o", "--scheduler", "tcp://127.0.0.1:{closed}", "--timeout", "1"],
     "cannot reach"),
    (["{tmp}/x.hdr", "--out", "{tmp}/o", "--jobs", "sh,nope"], "unknown nope"),
    (["{tmp}/x.hdr"], "--out DIR is needed"),
])
def test_bad_batch_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, words):
    (tmp_path / "empty.txt").write_text("\n# nothing\n")
    (tmp_path / "file").write_text("x")
    write_image(tmp_path / "x.hdr", np.ones((8, 16, 3), np.float32))
    with socket.socket() as closed:  # bound and never listening: a connection to it is refused
        closed.bind(("127.0.0.1", 0))
        port = str(closed.getsockname()[1])
        assert main(["batch", *(a.replace("{tmp}", str(tmp_path)).replace("{closed}", port) for a in argv)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "o").exists()


def test_resume_refuses_another_version_unless_forced(tmp_path, capsys):
    write_image(tmp_path / "x.hdr", np.ones((8, 16, 3), np.float32))
    out = tmp_path / "o"
    args = [str(tmp_path / "x.hdr"), "--out", str(out), "--jobs", "sh", "--workers", "1"]
    assert main(["batch", *args]) == 0
    assert main(["batch", *args]) == 2 and "--resume" in capsys.readouterr().err
    doc = json.loads((out / "batch.json").read_text())
    doc["lightprobe"] = "0.0.1"
    (out / "batch.json").write_text(json.dumps(doc))
    assert main(["batch", *args, "--resume"]) == 2
    assert "0.0.1" in capsys.readouterr().err
    assert main(["batch", *args, "--resume", "--force"]) == 0
    assert len(table(out)) == 1
    assert main(["batch", *args[:3], "--jobs", "sh,lights", "--resume", "--force"]) == 2  # other options


@pytest.mark.parametrize("damage", ["truncated", "not parquet", "other columns", "foreign name"])
def test_resume_on_a_damaged_part_is_one_line_and_redoes_it_once_set_aside(tmp_path, capsys, damage):
    """Parts are renamed into place whole, so only something outside the batch damages one; --resume then stops
    with one line naming the file (no traceback, nothing changed), and once the file is moved out, redoes the
    inputs it held — each input still once in the table."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    for i in range(3):
        write_image(tmp_path / f"m{i}.hdr", np.full((8, 16, 3), 1.0 + i, np.float32))
    out = tmp_path / "o"
    args = [*(str(tmp_path / f"m{i}.hdr") for i in range(3)), "--out", str(out), "--jobs", "sh", "--workers", "1"]
    assert main(["batch", *args]) == 0
    capsys.readouterr()
    part = sorted((out / "parts").glob("rows-*.parquet"))[0]
    if damage == "truncated":
        part.write_bytes(part.read_bytes()[:100])
    elif damage == "not parquet":
        part.write_text("hello")
    elif damage == "other columns":
        pq.write_table(pa.table({"path": ["x"], "nonsense": [1]}), part)
    else:
        part = out / "parts" / "rows-abc-x.parquet"
        part.write_text("x")
    before = sorted(p.name for p in (out / "parts").iterdir())
    assert main(["batch", *args, "--resume"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(part) in err[0] and "Traceback" not in err[0], err
    assert sorted(p.name for p in (out / "parts").iterdir()) == before
    part.rename(tmp_path / "set-aside.parquet")
    assert main(["batch", *args, "--resume"]) == 0
    rows = table(out)
    assert sorted(Path(r["path"]).name for r in rows) == ["m0.hdr", "m1.hdr", "m2.hdr"]


def test_impossible_paths_in_a_list_are_errors_of_their_own(tmp_path, capsys):
    """A listed path no file can have (a NUL byte, a name over the system's limit) or a folder is that input's
    error in errors.parquet, and the run goes on (it used to end with a traceback on the NUL byte)."""
    write_image(tmp_path / "good.hdr", np.ones((8, 16, 3), np.float32))
    (tmp_path / "folder.hdr").mkdir()
    listing = tmp_path / "inputs.txt"
    listing.write_text(f"a\x00b.hdr\n{'n' * 5000}.hdr\nfolder.hdr\ngood.hdr\n")
    out = tmp_path / "o"
    assert main(["batch", f"@{listing}", "--out", str(out), "--jobs", "sh", "--workers", "1"]) == 0
    assert [Path(r["path"]).name for r in table(out)] == ["good.hdr"]
    errors = table(out, "errors.parquet")
    assert len(errors) == 3 and {e["error_class"] for e in errors} == {"InputError"}
    assert any("null byte" in e["message"] for e in errors)


def test_report_on_a_damaged_table_is_one_line_and_resume_writes_it_again(tmp_path, capsys):
    import pyarrow as pa
    import pyarrow.parquet as pq

    write_image(tmp_path / "m.hdr", np.ones((8, 16, 3), np.float32))
    out = tmp_path / "o"
    args = [str(tmp_path / "m.hdr"), "--out", str(out), "--jobs", "sh", "--workers", "1"]
    assert main(["batch", *args]) == 0
    for damage in (b"garbage", None):
        if damage is None:
            pq.write_table(pa.table({"path": ["x"]}), out / "results.parquet")  # a table, not ours
        else:
            (out / "results.parquet").write_bytes(damage)
        capsys.readouterr()
        assert main(["batch", "--report", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "results.parquet is not a lightprobe batch table" in err[0], err
    assert main(["batch", *args, "--resume"]) == 0
    assert main(["batch", "--report", str(out)]) == 0 and len(table(out)) == 1


def test_devices_and_fifos_are_refused_not_read_forever(tmp_path):
    """``@/dev/zero`` as the list, or a FIFO, would never end (or block): one line. ``/dev/zero`` or a FIFO among
    the inputs is that input's error; the others are done. (Each run is a process of its own: one that read
    forever would fail at batch()'s timeout.)"""
    os.mkfifo(tmp_path / "fifo.txt")
    for listing in ("/dev/zero", str(tmp_path / "fifo.txt")):
        res = batch([f"@{listing}", "--out", tmp_path / "o", "--jobs", "sh"])
        err = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(err) == 1 and "not a regular file" in err[0], res.stderr
    write_image(tmp_path / "good.hdr", np.ones((8, 16, 3), np.float32))
    os.mkfifo(tmp_path / "pipe.hdr")
    out = tmp_path / "o2"
    res = batch(["/dev/zero", tmp_path / "pipe.hdr", tmp_path / "good.hdr", "--out", out, "--jobs", "sh",
                 "--workers", "1"])
    assert res.returncode == 0, res.stderr
    assert [Path(r["path"]).name for r in table(out)] == ["good.hdr"]
    errors = table(out, "errors.parquet")
    assert len(errors) == 2 and all("not a regular file" in e["message"] for e in errors), errors
