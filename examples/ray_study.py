"""Run a savsim study's shards as Ray tasks, then summarize them.

    python3 examples/ray_study.py MANIFEST OUT_DIR [--shards 8] [--workers 2] [--speedup 30]

Each Ray task runs ``savsim study MANIFEST --out OUT_DIR --shard K/N`` (one SITL at a time per
task: Ray spreads the tasks over the workers), which writes ``OUT_DIR/part-K-of-N.parquet``
whole or not at all and skips a shard already written, so a failed run is re-run as it is. The
SITL binary comes from ``SAVSIM_ARDUCOPTER`` (and ``SAVSIM_ARDUCOPTER_DEFAULTS``) in each
worker's environment. Tasks on one machine share its ports, so each task's study runs in a
network namespace of its own (savsim makes one where the machine allows). On a real cluster,
replace ``ray.init(num_cpus=...)`` with ``ray.init(address="auto")``; OUT_DIR must then be on
storage every node sees, and ``savsim`` on every node's PATH (or ``--savsim``).
"""

import argparse
import subprocess
import sys

import ray


@ray.remote(num_cpus=1)
def run_shard(savsim, manifest, out_dir, k, n, speedup):
    """One shard of the study: its exit status and the last lines it printed."""
    done = subprocess.run(
        [savsim, "study", manifest, "--out", out_dir, "--shard", f"{k}/{n}",
         "--speedup", str(speedup)],
        capture_output=True, text=True, check=False,
    )
    return done.returncode, (done.stdout + done.stderr).strip().splitlines()[-3:]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("manifest")
    parser.add_argument("out_dir")
    parser.add_argument("--shards", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2, help="CPUs of the local Ray cluster")
    parser.add_argument("--speedup", type=float, default=30.0)
    parser.add_argument("--savsim", default="savsim", help="the savsim executable")
    args = parser.parse_args(argv)
    ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False)
    tasks = [
        run_shard.remote(args.savsim, args.manifest, args.out_dir, k, args.shards, args.speedup)
        for k in range(args.shards)
    ]
    failed = 0
    for k, (status, tail) in enumerate(ray.get(tasks)):
        print(f"shard {k}/{args.shards}: exit {status}: {' | '.join(tail)}")
        failed += status != 0
    ray.shutdown()
    summary = subprocess.run([args.savsim, "study", "summarize", args.out_dir], check=False)
    return 1 if failed or summary.returncode else 0


if __name__ == "__main__":
    sys.exit(main())
