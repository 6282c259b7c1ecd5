"""Run a savsim manifest as Ray tasks on a local Ray cluster, then merge the shards with DuckDB
into the summary a study reports.

    python3 examples/ray_batch.py MANIFEST OUT_DIR [--shards 8] [--workers 2]

Each Ray task runs one contiguous shard of the manifest with ``savsim.run_manifest`` (one
thread per task: Ray spreads the tasks over the workers) and writes it as
``OUT_DIR/part-K-of-N.parquet``, the same rows and file names as ``savsim batch --shard K/N``.
A shard whose file exists is skipped, so a failed run is re-run as it is. On a real cluster,
replace ``ray.init(num_cpus=...)`` with ``ray.init(address="auto")``; OUT_DIR must then be on
storage every node sees.
"""

import argparse
import json
import os
import sys
import time

import duckdb
import pyarrow.parquet as pq
import ray

import savsim

SUMMARY = """
SELECT count(*)                                          AS runs,
       count(*) FILTER (WHERE error IS NOT NULL)         AS failed,
       count(*) FILTER (WHERE collisions > 0)            AS with_collision,
       count(*) FILTER (WHERE nmac)                      AS nmac,
       avg(CASE WHEN nmac THEN 1.0 ELSE 0.0 END)
           FILTER (WHERE error IS NULL)                  AS nmac_rate,
       min(cpa_m)                                        AS closest_cpa_m,
       sum(ticks)                                        AS ticks
FROM read_parquet('{pattern}')
"""


@ray.remote(num_cpus=1)
def run_shard(rows, first_index, path):
    """One shard: its rows through savsim, written atomically (a temporary file renamed)."""
    table = savsim.run_manifest(rows, jobs=1, first_index=first_index)
    tmp = path + ".tmp"
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    except BaseException:
        # Nothing half-written stays beside the results.
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return table.num_rows


def shard_bounds(n_rows, count):
    """Contiguous shards, as ``savsim batch --shard K/N`` cuts them."""
    return [(k * n_rows // count, (k + 1) * n_rows // count) for k in range(count)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("manifest")
    parser.add_argument("out_dir")
    parser.add_argument("--shards", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2, help="CPUs of the local Ray cluster")
    args = parser.parse_args(argv)

    rows = savsim.load_manifest(args.manifest)
    os.makedirs(args.out_dir, exist_ok=True)
    ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False)
    started = time.monotonic()
    pending = []
    for k, (lo, hi) in enumerate(shard_bounds(len(rows), args.shards)):
        path = os.path.join(args.out_dir, f"part-{k:05}-of-{args.shards:05}.parquet")
        if os.path.exists(path):
            print(f"shard {k}/{args.shards} is done: skipped", file=sys.stderr)
            continue
        pending.append(run_shard.remote(rows[lo:hi], lo, path))
    ray.get(pending)
    wall_s = time.monotonic() - started
    ray.shutdown()

    pattern = os.path.join(args.out_dir, "*.parquet")
    con = duckdb.connect()
    cursor = con.execute(SUMMARY.format(pattern=pattern.replace("'", "''")))
    names = [d[0] for d in cursor.description]
    summary = dict(zip(names, cursor.fetchone()))
    summary["wall_s"] = wall_s
    print(json.dumps(summary, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
