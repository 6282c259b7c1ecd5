"""The savsim Python package against the savsim CLI (run by tests/integration/batch.rs).

    python3 tests/python/check_package.py SAVSIM_BIN WORK_DIR [--ray]

Checks that generated manifests are the same from Python and the CLI, that Python's results
are the CLI's row for row (pyarrow reads both), that the truth of generated encounters is
found, that the GIL is released while runs run, that errors are Python exceptions with
savsim's message, and with --ray that examples/ray_batch.py on 2 local workers gives the
same rows and a DuckDB summary that agrees with them. Prints what it checked.
"""

import json
import os
import subprocess
import sys
import threading
import time

import pyarrow.compute as pc
import pyarrow.parquet as pq

import savsim

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CITY = os.path.join(ROOT, "scenes", "city.toml")
DEMO = os.path.join(ROOT, "scenes", "flights", "copter_square_10ms.tlog")
MEASURED = {"tick_cost_us_median", "tick_cost_us_p99", "wall_s"}


def outcome(table):
    """The table without its measured columns, as rows."""
    keep = [c for c in table.column_names if c not in MEASURED]
    return table.select(keep).sort_by("index").to_pylist()


def main():
    binary, work = sys.argv[1], sys.argv[2]
    with_ray = "--ray" in sys.argv[3:]
    os.makedirs(work, exist_ok=True)

    # The same manifest from Python and from the CLI.
    manifest = os.path.join(work, "encounters.csv")
    subprocess.run([binary, "batch", "gen-encounters", "--n", "24", "--seed", "5", "--scene",
                    CITY, "--duration-s", "60", "--out", manifest], check=True)
    generated = savsim.gen_encounters(24, seed=5, scene=CITY, duration_s=60.0)
    assert savsim.load_manifest(manifest) == generated, "gen-encounters differs from Python's"
    # A tlog row and a failing row join the encounters.
    with open(manifest) as f:
        columns = f.readline().count(",") + 1
    pad = lambda row: row + "," * (columns - row.count(",") - 1) + "\n"
    with open(manifest, "a") as f:
        f.write(pad(f"demo,{DEMO},{CITY},exact"))
        f.write(pad(f"missing,{work}/missing.tlog,,exact"))
    print("checked: gen-encounters from Python equals the CLI's")

    subprocess.run([binary, "batch", manifest, "--out", os.path.join(work, "cli"), "--jobs",
                    "2", "--no-progress"], check=True, stdout=subprocess.DEVNULL)
    cli = pq.read_table(os.path.join(work, "cli", "part-00000-of-00001.parquet"))
    for jobs in (1, 2):
        table = savsim.run_manifest(manifest, jobs=jobs)
        assert table.schema == cli.schema, f"schema differs:\n{table.schema}\n{cli.schema}"
        assert outcome(table) == outcome(cli), f"jobs={jobs}: rows differ from the CLI's"
    print(f"checked: Python's {cli.num_rows} rows equal the CLI's (jobs 1 and 2)")

    rows = outcome(cli)
    encounters = [r for r in rows if r["kind"] == "encounter"]
    assert all(r["error"] is None for r in encounters)
    # The intruder's approach (over the city, its own airliner is another track).
    intruder = [next(a for a in r["approaches"] if a["track"] == "intruder") for r in encounters]
    worst = max(abs(a["distance_m"] - r["expect_cpa_m"]) for a, r in zip(intruder, encounters))
    assert worst < 1e-6, f"closest approach off by {worst} m"
    assert all(a["nmac"] == r["expect_nmac"] for a, r in zip(intruder, encounters))
    demo = next(r for r in rows if r["run_id"] == "demo")
    assert demo["first_collision_obstacle"] == "b2150" and demo["messages"] == 21976, demo
    missing = next(r for r in rows if r["run_id"] == "missing")
    assert "missing.tlog" in missing["error"], missing
    print(f"checked: closest approaches within {worst:.1e} m of their construction, NMAC flags "
          "equal, the demo's collision, the missing tlog's error")

    # The GIL is released: another Python thread runs while savsim does.
    spins = 0
    done = threading.Event()

    def spin():
        nonlocal spins
        while not done.is_set():
            spins += 1

    spinner = threading.Thread(target=spin)
    many = savsim.gen_encounters(40, seed=9, scene=CITY, duration_s=60.0)
    spinner.start()
    started = time.monotonic()
    savsim.run_manifest(many, jobs=1)
    took = time.monotonic() - started
    done.set()
    spinner.join()
    assert spins > 10000, f"only {spins} spins in {took:.2f} s: the GIL was held"
    print(f"checked: {spins} spins of another thread during a {took:.2f} s run (GIL released)")

    for call, expect in [
        (lambda: savsim.replay(os.path.join(work, "missing.tlog")), "missing.tlog"),
        (lambda: savsim.run_manifest([{"tlog": DEMO, "bogus": 1}]), "bogus"),
        (lambda: savsim.run_manifest(os.path.join(work, "nope.csv")), "nope.csv"),
        (lambda: savsim.gen_encounters(1, duration_s=-1.0), "duration_s"),
    ]:
        try:
            call()
        except savsim.SavsimError as e:
            assert expect in str(e), f"{e!r} does not name {expect}"
        else:
            raise AssertionError(f"no SavsimError naming {expect}")
    row = savsim.replay(DEMO, scene=CITY)
    assert row["collisions"] == 1 and row["first_collision_obstacle"] == "b2150", row
    print("checked: errors are SavsimError with savsim's message; replay() returns the row")
    # An autopilot's own log: ArduCopter SITL's DataFlash of an ADS-B encounter (its POS, ATT
    # and the ADSB traffic its receiver logged), replayed in open air.
    row = savsim.replay(os.path.join(ROOT, "tests", "fixtures", "arducopter_adsb.bin"))
    assert row["ticks"] == 1387 and row["nmac"] and row["cpa_track"] == "icao:F00000", row
    assert abs(row["cpa_horizontal_m"] - 112.5) < 0.5, row
    print("checked: replay() reads a DataFlash log and its ADS-B traffic")

    if with_ray:
        out = os.path.join(work, "ray")
        result = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "ray_batch.py"),
                                 manifest, out, "--shards", "4", "--workers", "2"],
                                check=True, capture_output=True, text=True)
        summary = json.loads(result.stdout.strip().splitlines()[-1])
        merged = pq.read_table(out)
        assert outcome(merged) == outcome(cli), "Ray's rows differ from the CLI's"
        assert summary["runs"] == cli.num_rows
        assert summary["failed"] == 1
        assert summary["nmac"] == pc.sum(cli["nmac"]).as_py()
        assert summary["with_collision"] == sum(r["collisions"] > 0 for r in rows)
        print(f"checked: Ray on 2 workers gives the CLI's rows; DuckDB's summary {summary}")


if __name__ == "__main__":
    main()
