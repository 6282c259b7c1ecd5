#!/usr/bin/env python3
"""The errors of the first ADS-B report each row of a study told its vehicle, read from the
feed the rows sent, with tools that share nothing with savsim: pymavlink reads each row's
`feed.tlog` (`savsim study ... --keep-work`), pyproj places the report in the scene's frame,
scipy tests the errors against the model's normal distribution.

    python3 scripts/adsb_first_errors.py RESULTS_DIR --variant nacp6 --sigma-m 227

RESULTS_DIR holds the study's Parquet shards and its `work/` folder. The rows whose variant
contains `--variant` are read (one per pair, the intruder's first fresh report, `tslc` 0). The
truth is the intruder's first waypoint: `study gen --kind encounters` holds the intruder there
until its second waypoint, and a row whose first report reached the vehicle (`first_detection_s`,
the vehicle's clock) after that is left out and counted. Open air: the scene's origin is SITL's
home (CMAC), as `study gen --kind encounters` writes its rows; `--origin LAT,LON,ALT` for
another.

Prints, per axis (east, north): n, mean, standard deviation, the Kolmogorov-Smirnov statistic
against N(0, sigma) and its p-value; `--json` as JSON.
"""

import argparse
import glob
import json
import os
import sys

import pyarrow.parquet as pq
from pymavlink import mavutil
from pyproj import Transformer
from scipy import stats

CMAC = (-35.363261, 149.165230, 584.0)


def enu_from(origin):
    """A function (lat, lon, h) -> (e, n) in the tangent plane at `origin`, by pyproj's
    topocentric conversion (WGS84)."""
    lat0, lon0, h0 = origin
    t = Transformer.from_pipeline(
        "+proj=pipeline +step +proj=cart +ellps=WGS84 "
        f"+step +proj=topocentric +ellps=WGS84 +lat_0={lat0} +lon_0={lon0} +h_0={h0}"
    )

    def enu(lat, lon, h):
        e, n, _ = t.transform(lon, lat, h)
        return e, n

    return enu


def first_fresh_report(tlog):
    m = mavutil.mavlink_connection(tlog)
    while True:
        msg = m.recv_match(type="ADSB_VEHICLE")
        if msg is None:
            return None
        if msg.tslc == 0:
            return msg


def rows(results_dir, variant):
    files = sorted(glob.glob(os.path.join(results_dir, "*.parquet")))
    if not files:
        sys.exit(f"no *.parquet in {results_dir}")
    cols = ["index", "row_id", "variant", "pair", "intruder", "first_detection_s", "outcome"]
    for f in files:
        t = pq.read_table(f, columns=cols).to_pylist()
        for r in t:
            if variant in (r["variant"] or "") and r["outcome"] != "error":
                yield r


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", help="the study's --out directory (with work/)")
    ap.add_argument("--variant", required=True, help="rows whose variant contains this")
    ap.add_argument("--sigma-m", type=float, required=True, help="the model's sigma an axis")
    ap.add_argument("--origin", default=",".join(map(str, CMAC)),
                    help="the scene's origin, LAT,LON,ALT (default: CMAC)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    enu = enu_from(tuple(float(x) for x in a.origin.split(",")))
    work = os.path.join(a.results, "work")
    errors, late, missing = [], 0, 0
    for r in rows(a.results, a.variant):
        folder = glob.glob(os.path.join(work, f"{r['index']:06d}-*"))
        tlog = folder and os.path.join(folder[0], "feed.tlog")
        if not tlog or not os.path.exists(tlog):
            missing += 1
            continue
        waypoints = [[float(x) for x in w.split()] for w in r["intruder"].split(";")]
        held_until_s = waypoints[1][0] if waypoints[1][1:] == waypoints[0][1:] else 0.0
        if r["first_detection_s"] is None or r["first_detection_s"] > held_until_s:
            late += 1
            continue
        report = first_fresh_report(tlog)
        if report is None:
            missing += 1
            continue
        e, n = enu(report.lat * 1e-7, report.lon * 1e-7, report.altitude * 1e-3)
        errors.append((r["pair"], e - waypoints[0][1], n - waypoints[0][2]))
    out = {"rows": len(errors), "left_out_late": late, "left_out_no_feed": missing,
           "pairs": len({p for p, _, _ in errors})}
    for axis, name in ((1, "east"), (2, "north")):
        x = [err[axis] for err in errors]
        if len(x) < 2:
            sys.exit(f"{len(x)} rows with a first report: nothing to test")
        ks = stats.kstest(x, "norm", args=(0.0, a.sigma_m))
        mean = sum(x) / len(x)
        sd = (sum((v - mean) ** 2 for v in x) / (len(x) - 1)) ** 0.5
        out[name] = {"mean_m": mean, "sd_m": sd, "ks_d": ks.statistic, "ks_p": ks.pvalue}
    if a.json:
        print(json.dumps(out, indent=1))
        return
    print(f"{out['rows']} rows ({out['pairs']} pairs); left out: {late} reported after the "
          f"intruder's hold, {missing} without a feed")
    for name in ("east", "north"):
        s = out[name]
        print(f"{name}: mean {s['mean_m']:+.1f} m, sd {s['sd_m']:.1f} m, "
              f"KS D {s['ks_d']:.4f} p {s['ks_p']:.3f} against N(0, {a.sigma_m} m)")


if __name__ == "__main__":
    main()
