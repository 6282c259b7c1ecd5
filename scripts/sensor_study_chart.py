#!/usr/bin/env python3
"""Chart a closed-loop sensor study (scripts/sensor_study.py): the risk ratios of each
mitigated variant against the nominal one with their 95% intervals, read from
`savsim study summarize DIR --json`, beside the distribution of the closest approach per
variant, read from the study's Parquet results.

    python3 scripts/sensor_study_chart.py --kind adsb summary.json RESULTS_DIR \
        docs/images/sensors_adsb.png
    python3 scripts/sensor_study_chart.py --kind proximity summary.json RESULTS_DIR \
        docs/images/sensors_proximity.png

`--kind adsb`: NMAC, LoWC and collision ratios; closest approach to the intruder (`cpa_m`).
`--kind proximity`: collision ratio; closest approach to an obstacle (`closest_obstacle_m`,
which savsim records within its 10 m near-miss band only: rows never that close are counted
and drawn at the band's edge, as "> 10 m").

An interval whose upper bound is null (unbounded: more than 2.5% of the bootstrap resamples
had no nominal event) is drawn to the top of the axis with an arrow; a ratio without a value
(no nominal event at all) is written as "undefined". Rows whose outcome is `error` are left
out, as `summarize` leaves them out.

Needs matplotlib and pyarrow (pip install matplotlib pyarrow).
"""

import argparse
import glob
import json
import math
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402

NEAR_MISS_BAND_M = 10.0


def short(variant):
    """`mitigated//abs/path/adsb-nacp8.toml` -> `adsb-nacp8`; `mitigated/ideal-adsb:latency_s=1.0`
    -> `ideal-adsb:latency_s=1.0`; `nominal` stays."""
    if not variant.startswith("mitigated/"):
        return variant
    rest = variant[len("mitigated/"):]
    if rest.lower().endswith(".toml"):
        rest = os.path.basename(rest)[: -len(".toml")]
    return rest


def read_rows(results_dir, column):
    files = sorted(glob.glob(os.path.join(results_dir, "*.parquet")))
    if not files:
        sys.exit(f"no *.parquet in {results_dir}")
    by_variant = {}
    for f in files:
        t = pq.read_table(f, columns=["variant", "outcome", column]).to_pydict()
        for v, o, x in zip(t["variant"], t["outcome"], t[column]):
            if o == "error":
                continue
            by_variant.setdefault(v or "nominal", []).append(x)
    return by_variant


def sort_key(variant):
    """ideal first; then NACp files, best first; other files; presets with settings by their
    numbers (latency ascending); the rest by name."""
    name = short(variant)
    nums = re.findall(r"[0-9]+(?:\.[0-9]+)?", name)
    num = float(nums[-1]) if nums else 0.0
    if name == "ideal":
        return (0, 0.0, name)
    if "nacp" in name:
        return (1, -num, name)
    if variant.lower().endswith(".toml"):
        return (2, 0.0, name)
    if ":" in name:
        return (3, num, name)
    return (4, 0.0, name)


def order(variants, nominal):
    """Nominal first, then the mitigated variants (sort_key)."""
    return [nominal] + sorted((v for v in variants if v != nominal), key=sort_key)


def draw_ratios(ax, ratios, key, title):
    names = [short(r["variant"]) for r in ratios]
    xs = list(range(len(ratios)))
    finite = [1.0]
    for r in ratios:
        e = r[key]
        finite += [x for x in (e["value"], e["low"], e["high"]) if x is not None]
    top = max(finite) * 1.25
    ax.set_ylim(0.0, top)
    for x, r in zip(xs, ratios):
        e = r[key]
        v, lo, hi = e["value"], e["low"], e["high"]
        if v is None:
            ax.text(x, top * 0.5, "undefined\n(no nominal\nevent)", ha="center", va="center",
                    fontsize=7, rotation=90, color="0.4")
            continue
        lo_y = lo if lo is not None else 0.0
        if hi is None:
            ax.annotate("", xy=(x, top), xytext=(x, lo_y),
                        arrowprops=dict(arrowstyle="->", color="C3", lw=1.5))
            ax.text(x + 0.12, top * 0.97, "unbounded", fontsize=6, color="C3", rotation=90,
                    va="top")
        else:
            ax.plot([x, x], [lo_y, hi], color="C0", lw=1.5)
            ax.plot([x - 0.15, x + 0.15], [hi, hi], color="C0", lw=1.5)
        if lo is not None:
            ax.plot([x - 0.15, x + 0.15], [lo, lo], color="C0", lw=1.5)
        ax.plot([x], [v], "o", color="C0", ms=5)
        ax.text(x + 0.18, v, f"{v:.2f}", fontsize=7, va="center")
    ax.axhline(1.0, color="0.6", lw=0.8, ls="--")
    ax.set_xticks(xs)
    ax.set_xticklabels(names, rotation=40, ha="right", fontsize=7)
    ax.set_xlim(-0.6, len(xs) - 0.4)
    ax.set_title(title, fontsize=9)
    ax.set_ylabel("risk ratio (mitigated / nominal)", fontsize=8)


def draw_closest(ax, by_variant, variants, column, kind):
    data, labels = [], []
    for v in variants:
        xs = by_variant.get(v, [])
        if kind == "proximity":
            far = sum(1 for x in xs if x is None)
            vals = [NEAR_MISS_BAND_M if x is None else x for x in xs]
            label = f"{short(v)}\n(n={len(xs)}" + (f", {far} >10 m)" if far else ")")
        else:
            vals = [x for x in xs if x is not None]
            label = f"{short(v)}\n(n={len(vals)})"
        data.append(vals)
        labels.append(label)
    ax.boxplot(data, whis=(10, 90), showfliers=True, flierprops=dict(ms=2, alpha=0.5))
    ax.set_xticks(range(1, len(labels) + 1))
    ax.set_xticklabels(labels, rotation=40, ha="right", fontsize=7)
    if kind == "adsb":
        ax.axhline(152.4, color="C3", lw=0.8, ls="--")
        ax.text(0.55, 152.4, " NMAC 500 ft", color="C3", fontsize=7, va="bottom")
        ax.set_ylabel("closest approach to the intruder, cpa_m (m)", fontsize=8)
    else:
        ax.axhline(1.5, color="C3", lw=0.8, ls="--")
        ax.text(0.55, 1.5, " soft fail 1.5 m", color="C3", fontsize=7, va="bottom")
        ax.axhline(NEAR_MISS_BAND_M, color="0.6", lw=0.8, ls=":")
        ax.set_ylabel("closest approach to an obstacle, closest_obstacle_m (m)", fontsize=8)
    ax.set_title("closest approach per variant (box: quartiles, whiskers: 10th-90th pct)",
                 fontsize=9)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kind", choices=["adsb", "proximity"], required=True)
    ap.add_argument("--title", default=None)
    ap.add_argument("summary", help="savsim study summarize DIR --json, saved")
    ap.add_argument("results", help="the study's results directory (*.parquet)")
    ap.add_argument("png")
    a = ap.parse_args()

    with open(a.summary) as f:
        s = json.load(f)
    nominal = s.get("nominal", "nominal")
    ratios = sorted(s["ratios"], key=lambda r: sort_key(r["variant"]))
    if a.kind == "adsb":
        panels = [("nmac_ratio", "NMAC ratio"), ("lowc_ratio", "LoWC ratio"),
                  ("collision_ratio", "collision ratio")]
        column = "cpa_m"
    else:
        panels = [("collision_ratio", "collision ratio")]
        column = "closest_obstacle_m"
    by_variant = read_rows(a.results, column)
    variants = order([r["variant"] for r in ratios], nominal)

    n = len(panels)
    pairs = ratios[0]["pairs"] if ratios else 0
    if n == 1:
        # one ratio: the ratio and the closest approaches side by side
        fig = plt.figure(figsize=(12.0, 6.0))
        grid = fig.add_gridspec(1, 2, width_ratios=[1.0, 1.4])
        ratio_axes = [fig.add_subplot(grid[0, 0])]
        closest = fig.add_subplot(grid[0, 1])
    else:
        fig = plt.figure(figsize=(max(7.0, 4.6 * n), 10.0))
        grid = fig.add_gridspec(2, n, height_ratios=[1.0, 1.1])
        ratio_axes = [fig.add_subplot(grid[0, i]) for i in range(n)]
        closest = fig.add_subplot(grid[1, :])
    for ax, (key, title) in zip(ratio_axes, panels):
        draw_ratios(ax, ratios, key, f"{title} (95% bootstrap, {pairs} pairs)")
    draw_closest(closest, by_variant, variants, column, a.kind)
    fails = s.get("failed", 0)
    fig.suptitle((a.title or f"savsim sensor study ({a.kind})")
                 + f": {s.get('rows', '?')} rows, {fails} error rows left out", fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(a.png)), exist_ok=True)
    fig.savefig(a.png, dpi=130)
    print(f"wrote {a.png}")


if __name__ == "__main__":
    main()
