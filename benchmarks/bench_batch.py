"""``lightprobe batch``: throughput against a shell loop of single-file commands and against one worker, and the
exactly-once fault scenario of tests/test_batch.py at a larger scale. Ratios in one run.

    python benchmarks/bench_batch.py [--part throughput|faults|all] [--copies 3 9] [--faults-maps 400]

Throughput: SH order 8 + lights on the eight 1024×512 Poly Haven probes of ../shared/data and rotated copies of
them (``--copies`` turns each; one table per value given), the same maps for each way: (a) a shell loop running ``lightprobe sh F --order 8 -o …``
and ``lightprobe lights F -o …`` per map (start-up and numba's cache load paid per command), (b) ``lightprobe batch
--workers 1``, (c) ``--workers 2``. Peak resident memory per worker is read from the table. Each worker pays numba's import and kernel-cache load
(~0.5 s) on its first map and the driver its own start, so the ratio to one worker grows with the dataset: the
tables at two sizes show how.
Faults: ``--faults-maps`` small synthetic maps plus the real ICT probes and 11 corrupt files, the driver killed with
SIGKILL at 5 random moments and resumed, a worker killed mid-task; the final table is checked against an
uninterrupted run's.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED, require  # sets the environment first

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

EXE = str(Path(sys.executable).with_name("lightprobe"))


def _maps(folder: Path, copies: int) -> list[Path]:
    from lightprobe.maps import read_envmap

    out = []
    for source in sorted((SHARED / "polyhaven_1k").glob("*.hdr")):
        env = read_envmap(source)
        for k in range(copies):
            path = folder / f"{source.stem}_{k}.exr"
            (env if k == 0 else env.rotated((360.0 * k / copies, 0.0, 0.0))).save(path)
            out.append(path)
    return out


def throughput(copies: int) -> None:
    import pyarrow.parquet as pq

    with tempfile.TemporaryDirectory() as temp:
        temp = Path(temp)
        maps = _maps(temp, copies)
        print(f"\n{len(maps)} maps 1024×512, jobs sh (order 8) + lights")
        t0 = time.perf_counter()
        for i, m in enumerate(maps):
            subprocess.run([EXE, "sh", str(m), "--order", "8", "-o", str(temp / f"sh{i}.json")], check=True,
                           capture_output=True)
            subprocess.run([EXE, "lights", str(m), "-o", str(temp / f"l{i}.json")], check=True, capture_output=True)
        loop = time.perf_counter() - t0
        rows = [("shell loop of single-file commands", loop, None)]
        for workers in (1, 2):
            out = temp / f"batch{workers}"
            t0 = time.perf_counter()
            subprocess.run([EXE, "batch", *map(str, maps), "--out", str(out), "--jobs", "sh,lights", "--order", "8",
                            "--workers", str(workers)], check=True, capture_output=True)
            seconds = time.perf_counter() - t0
            peak = max(r["peak_rss"] for r in pq.read_table(out / "results.parquet").to_pylist())
            rows.append((f"lightprobe batch --workers {workers}", seconds, peak))
    print(f"\n{'way':<38}{'seconds':>9}{'maps/s':>9}{'vs loop':>9}{'vs 1 worker':>13}{'peak RSS/worker':>17}")
    for name, seconds, peak in rows:
        print(f"{name:<38}{seconds:>9.1f}{len(maps) / seconds:>9.2f}{loop / seconds:>8.1f}×"
              f"{rows[1][1] / seconds:>12.2f}×{'' if peak is None else f'{peak / 2**20:>13.0f} MiB':>17}")


def faults(count: int) -> int:
    from test_batch import ARGS, check_exactly_once, kill_and_resume, make_dataset

    real = [SHARED / "ict_lowres" / n for n in ("grace.hdr", "pisa.hdr", "uffizi.hdr", "ennis.hdr")]
    if not require(*real):
        return 2
    with tempfile.TemporaryDirectory() as temp:
        temp = Path(temp)
        (temp / "data").mkdir()
        data = make_dataset(temp / "data", count, real)
        t0 = time.perf_counter()
        subprocess.run([EXE, "batch", str(data["list"]), "--out", str(temp / "reference"), *ARGS], check=True,
                       capture_output=True)
        print(f"uninterrupted: {len(data['good'])} good + {len(data['bad'])} corrupt inputs in "
              f"{time.perf_counter() - t0:.1f} s")
        summary, killed = kill_and_resume(data["list"], temp / "killed", ARGS)
        check_exactly_once(temp / "killed", data, temp / "reference")
        print(f"5 SIGKILLs of the driver, resumed each time, worker {killed} killed mid-task in the last run: "
              f"every good input once, every bad one once in errors.parquet, rows equal to the uninterrupted run's")
        print(f"  last run: {summary}")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("throughput", "faults", "all"), default="all")
    parser.add_argument("--copies", type=int, nargs="+", default=[3, 9])
    parser.add_argument("--faults-maps", type=int, default=400)
    args = parser.parse_args()
    if args.part in ("throughput", "all"):
        if not require(*sorted((SHARED / "polyhaven_1k").glob("*.hdr"))[:1]):
            return 2
        for copies in args.copies:
            throughput(copies)
    if args.part in ("faults", "all"):
        return faults(args.faults_maps)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
