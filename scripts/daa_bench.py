"""The cost goals of docs/daa.md, measured in one run (release build):

    cargo build --release && python3 scripts/daa_bench.py [--n N] [--sets K] [--set-n M]

1. Well clear's cost: N generated encounters (180 s at 10 Hz, two aircraft over the bundled
   city, `exact` mode) run by `savsim batch --jobs 1` twice, with `well_clear = none` and with
   the default (`small-uas`); every column but the well-clear ones must agree.
2. Model encounters at scale: K sets of M encounters sampled from the bundled MIT LL model and
   paired by importance sampling (`--pairing scenes/encounter-models/pairing.ini`, 180 s at
   10 Hz, open air), each generated and then run by `savsim batch --jobs 2`; the manifest is
   removed after its run (each is about 1 GB for M = 100,000).

Prints both as Markdown tables.
"""

import argparse
import csv
import os
import shutil
import subprocess
import tempfile
import time

import pyarrow.parquet as pq

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("SAVSIM_BIN") or os.path.join(ROOT, "target", "release", "savsim")
MEASURED = {"tick_cost_us_median", "tick_cost_us_p99", "wall_s"}
WELL_CLEAR = {"well_clear", "lowc", "lowc_first_t_s", "lowc_duration_s", "lowc_min_horizontal_m",
              "lowc_min_vertical_m", "min_taumod_s"}


def timed(args):
    started = time.monotonic()
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL)
    return time.monotonic() - started


def rows(out, skip):
    t = pq.read_table(out)
    keep = [c for c in t.column_names if c not in MEASURED and c not in skip]
    return t.select(keep).sort_by("index").to_pylist()


def without_well_clear(src, dst):
    with open(src, newline="") as f, open(dst, "w", newline="") as g:
        reader = csv.DictReader(f)
        writer = csv.DictWriter(g, fieldnames=reader.fieldnames)
        writer.writeheader()
        for row in reader:
            row["well_clear"] = "none"
            writer.writerow(row)


def well_clear_cost(work, n):
    manifest = os.path.join(work, "encounters.csv")
    subprocess.run([BIN, "batch", "gen-encounters", "--n", str(n), "--seed", "1", "--scene",
                    os.path.join(ROOT, "scenes", "city.toml"), "--out", manifest], check=True)
    plain = os.path.join(work, "no-well-clear.csv")
    without_well_clear(manifest, plain)
    walls = {}
    for name, path in (("well_clear = none", plain), ("well_clear = small-uas (default)", manifest)):
        out = os.path.join(work, name.split()[2])
        walls[name] = (timed([BIN, "batch", path, "--out", out, "--jobs", "1", "--no-progress"]), out)
    a, b = (rows(out, WELL_CLEAR) for _, out in walls.values())
    assert a == b, "rows differ beyond the well-clear columns"
    lowc = sum(r["lowc"] for r in pq.read_table(walls["well_clear = small-uas (default)"][1])
               .select(["lowc"]).to_pylist())
    base = walls["well_clear = none"][0]
    print(f"{n} encounters, 180 s at 10 Hz over scenes/city.toml, exact mode, --jobs 1; "
          f"{lowc} losses of well clear; rows identical beyond the well-clear columns\n")
    print("| run | wall s | encounters per core-hour | vs none |")
    print("|---|--:|--:|--:|")
    for name, (wall, _) in walls.items():
        print(f"| {name} | {wall:.1f} | {n / wall * 3600:,.0f} | {base / wall:.2f}x |")
    print()


def model_sets(work, sets, per_set):
    model = os.path.join(ROOT, "scenes", "encounter-models", "uncor_1200code_v2p1.txt")
    pairing = os.path.join(ROOT, "scenes", "encounter-models", "pairing.ini")
    gen_s = run_s = 0.0
    runs = failed = nmac = 0
    for k in range(sets):
        manifest = os.path.join(work, f"model-{k}.csv")
        gen_s += timed([BIN, "batch", "gen-encounters", "--n", str(per_set), "--seed", str(k + 1),
                        "--model", model, "--pairing", pairing, "--out", manifest])
        out = os.path.join(work, f"model-out-{k}")
        run_s += timed([BIN, "batch", manifest, "--out", out, "--jobs", "2", "--no-progress"])
        os.remove(manifest)
        t = pq.read_table(out, columns=["error", "nmac"]).to_pylist()
        runs += len(t)
        failed += sum(r["error"] is not None for r in t)
        nmac += sum(bool(r["nmac"]) for r in t)
        shutil.rmtree(out)
        print(f"set {k + 1}/{sets}: generated {gen_s:.0f} s, run {run_s:.0f} s so far", flush=True)
    total = gen_s + run_s
    print(f"\n{runs:,} model encounters (importance-sampled pairing, 180 s at 10 Hz, open air), "
          f"{sets} sets of {per_set:,}; {failed} failed, {nmac:,} NMACs\n")
    print("| step | wall s | encounters per hour |")
    print("|---|--:|--:|")
    print(f"| `gen-encounters --model --pairing` (one thread) | {gen_s:.0f} | {runs / gen_s * 3600:,.0f} |")
    print(f"| `savsim batch --jobs 2` | {run_s:.0f} | {runs / run_s * 3600:,.0f} |")
    print(f"| both | {total:.0f} | {runs / total * 3600:,.0f} |")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--n", type=int, default=20000, help="encounters for the well-clear cost")
    p.add_argument("--sets", type=int, default=1, help="model-encounter sets")
    p.add_argument("--set-n", type=int, default=10000, help="encounters per model set")
    a = p.parse_args()
    work = tempfile.mkdtemp(prefix="savsim-daa-bench-")
    try:
        if a.n > 0:
            well_clear_cost(work, a.n)
        if a.sets > 0:
            model_sets(work, a.sets, a.set_n)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
