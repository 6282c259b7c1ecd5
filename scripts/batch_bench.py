"""The batch goals of docs/batch.md, measured in one run (release build):

    cargo build --release && python3 scripts/batch_bench.py [N] [--ray]

Generates N encounters (180 s at 10 Hz, two aircraft over the bundled city, `exact` mode),
runs them with `savsim batch --jobs 1` and `--jobs 2` (and, with --ray, through
examples/ray_batch.py on 2 local Ray workers, which needs `pip install ./python ray duckdb`),
checks that every run gives the same rows, and prints the ratios as a Markdown table.
"""

import os
import subprocess
import sys
import tempfile
import time

import pyarrow.parquet as pq

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The binary: SAVSIM_BIN, or the release build's.
BIN = os.environ.get("SAVSIM_BIN") or os.path.join(ROOT, "target", "release", "savsim")
MEASURED = {"tick_cost_us_median", "tick_cost_us_p99", "wall_s"}


def rows(path):
    t = pq.read_table(path)
    return t.select([c for c in t.column_names if c not in MEASURED]).sort_by("index").to_pylist()


def timed(args):
    started = time.monotonic()
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL)
    return time.monotonic() - started


def main():
    n = int(next((a for a in sys.argv[1:] if a.isdigit()), "400"))
    with_ray = "--ray" in sys.argv
    work = tempfile.mkdtemp(prefix="savsim-batch-bench-")
    manifest = os.path.join(work, "encounters.csv")
    subprocess.run([BIN, "batch", "gen-encounters", "--n", str(n), "--seed", "1", "--scene",
                    os.path.join(ROOT, "scenes", "city.toml"), "--out", manifest], check=True)
    results = {}
    for jobs in ("1", "2"):
        out = os.path.join(work, f"jobs{jobs}")
        results[f"savsim batch --jobs {jobs}"] = (
            timed([BIN, "batch", manifest, "--out", out, "--jobs", jobs, "--no-progress"]), out)
    if with_ray:
        out = os.path.join(work, "ray")
        results["examples/ray_batch.py, 2 workers"] = (
            timed([sys.executable, os.path.join(ROOT, "examples", "ray_batch.py"), manifest, out,
                   "--shards", "8", "--workers", "2"]), out)
    reference = rows(os.path.join(work, "jobs1"))
    for name, (_, out) in results.items():
        assert rows(out) == reference, f"{name}: rows differ from --jobs 1"
    one = results["savsim batch --jobs 1"][0]
    two = results["savsim batch --jobs 2"][0]
    print(f"{n} encounters, 180 s at 10 Hz over scenes/city.toml, exact mode; "
          f"every run's rows identical to --jobs 1\n")
    print("| run | wall s | encounters per core-hour | vs --jobs 1 | vs --jobs 2 |")
    print("|---|---|---|---|---|")
    for name, (wall, _) in results.items():
        cores = 1 if name.endswith("--jobs 1") else 2
        print(f"| {name} | {wall:.1f} | {n / wall / cores * 3600:,.0f} | {one / wall:.2f}x "
              f"| {two / wall:.2f}x |")


if __name__ == "__main__":
    main()
