"""The companion study's chart (docs/companion.md): each variant's collision rate with its 95%
bootstrap interval, from `savsim study summarize --json`, and the collision rate against the
approach speed (the rows' plans) for each variant.

    savsim study summarize --json results/ > summary.json
    python3 scripts/companion_chart.py summary.json results/ docs/images/companion-study.png
"""

import glob
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402

ORDER = ["nominal", "ac-avoid", "companion"]
COLOURS = {"nominal": "#999999", "ac-avoid": "#44aa66", "companion": "#4477cc"}


def speed_of(plan):
    """The horizontal speed of a plan's velocity leg, m/s."""
    for leg in plan.split(";"):
        words = leg.split()
        if words and words[0] == "velocity":
            return math.hypot(float(words[1]), float(words[2]))
    return float("nan")


def main(summary_path, results_dir, out):
    summary = json.load(open(summary_path))
    rates = {v["variant"]: v["collision_rate"] for v in summary["variants"]}
    rows = []
    for path in glob.glob(results_dir + "/*.parquet"):
        rows += pq.read_table(path, columns=["variant", "plan", "outcome"]).to_pylist()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    names = [v for v in ORDER if v in rates]
    values = [rates[v]["value"] for v in names]
    low = [rates[v]["value"] - rates[v]["low"] for v in names]
    high = [rates[v]["high"] - rates[v]["value"] for v in names]
    left.bar(names, values, yerr=[low, high], capsize=6, color=[COLOURS[v] for v in names])
    left.set_ylabel("collision rate (95% bootstrap over pairs)")
    left.set_title("%d approaches, lockstep, ArduCopter 4.5.6" % summary["variants"][0]["encounters"])
    left.set_ylim(0, 1.05)
    edges = [2, 3, 4, 5, 6, 7, 8]
    for v in names:
        xs, ys = [], []
        for a, b in zip(edges, edges[1:]):
            sel = [r for r in rows if r["variant"] == v and a <= speed_of(r["plan"]) < b
                   and r["outcome"] != "error"]
            if sel:
                xs.append((a + b) / 2)
                ys.append(sum(r["outcome"] == "collision" for r in sel) / len(sel))
        right.plot(xs, ys, marker="o", label=v, color=COLOURS[v])
    right.set_xlabel("approach speed, m/s")
    right.set_ylabel("collision rate")
    right.set_ylim(-0.02, 1.05)
    right.legend()
    right.set_title("by speed (the camera reads to 10 m)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(*sys.argv[1:4])
