#!/usr/bin/env python3
"""Closed-loop sensor studies with ArduCopter SITL: does the autopilot's own avoidance still
work when its sensors are modelled (docs/sensors.md) rather than ideal?

Study A (`adsb`): ArduCopter's ADS-B avoidance (AVD_*) against surveillance quality.
  `savsim study gen --kind encounters --n N --seed 11` with nine sensor sets: `ideal`,
  ADS-B with NACp 10, 8, 7, 6 (scenes/sensors/adsb-nacp*.toml: every report received, no
  latency jitter, the other Appendix Q errors kept), exact ADS-B with Appendix Q reception
  alone (scenes/sensors/adsb-appq-reception.toml) and exact ADS-B 0.5, 1 and 2 s late
  (`ideal-adsb:latency_s=...`). The generated mitigated rows use ArduCopter's default AVD
  distances (fail at 100 m horizontally), inside the NMAC cylinder (500 ft = 152 m); the
  script writes `study_avd300.csv`, the manifest with `AVD_F_ACTION=3` replaced by
  `AVD_F_ACTION=3;AVD_F_DIST_XY=300;AVD_W_DIST_XY=600;AVD_F_DIST_Z=60;AVD_W_DIST_Z=120` in
  the mitigated rows, and flies that.
Study B (`prox`): proximity avoidance (AC_Avoid) with `ideal` (the exact 72-ray ring), a
  forward depth camera (`realsense-d435`) and a 2D lidar (`rplidar-a2`):
  `savsim study gen --kind approaches --n N --seed 12`.

For each: gen, (edit), fly (`savsim study MANIFEST --out DIR/out --speedup S --jobs J`),
`savsim study summarize DIR/out --json > DIR/summary.json` and the text summary
(`DIR/summary.txt`), and the chart (scripts/sensor_study_chart.py).

    SAVSIM_ARDUCOPTER=.../arducopter SAVSIM_ARDUCOPTER_DEFAULTS=.../copter.parm \
    python3 scripts/sensor_study.py --savsim target/release/savsim --out /tmp/studies \
        --n 200 --jobs 2 --speedup 20

`--n 3` is a smoke test. `--study adsb` or `--study prox` runs one. A study whose results
already exist is not flown again (savsim skips shards whose file exists) unless `--force`.
Each step's command and wall time are printed and written to DIR/commands.txt. `--keep-work`
keeps each row's folder (its `feed.tlog`: scripts/adsb_first_errors.py reads it).

A row's sensor errors are drawn with a seed made from its `seed` column and its pair
(docs/sensors.md, "What a seed means"). `--adsb-base-seeds 1,2,3,4` flies the ADS-B study's
NACp 6 rows again under each of those base seeds (its `seed` column rewritten, the variant
named `... seed S`), into DIR/adsb/seed-S/, and summarizes them with the study's own rows
(DIR/adsb/summary_seeds.*): how much the error draw alone moves the NACp 6 ratio.
"""

import argparse
import csv
import os
import shlex
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
SENSORS_DIR = os.path.join(REPO, "scenes", "sensors")
CHART = os.path.join(HERE, "sensor_study_chart.py")

AVD_DEFAULT = "AVD_F_ACTION=3"
AVD_300 = "AVD_F_ACTION=3;AVD_F_DIST_XY=300;AVD_W_DIST_XY=600;AVD_F_DIST_Z=60;AVD_W_DIST_Z=120"


def adsb_sets(sensors_dir):
    files = ["adsb-nacp10", "adsb-nacp8", "adsb-nacp7", "adsb-nacp6", "adsb-appq-reception"]
    return (["ideal"]
            + [os.path.join(sensors_dir, f + ".toml") for f in files]
            + [f"ideal-adsb:latency_s={s}" for s in ("0.5", "1.0", "2.0")])


PROX_SETS = ["ideal", "realsense-d435", "rplidar-a2"]


def run(cmd, log, stdout=None):
    line = " ".join(shlex.quote(c) for c in cmd) + (f" > {stdout}" if stdout else "")
    print(f"$ {line}", flush=True)
    t0 = time.monotonic()
    if stdout:
        with open(stdout, "w") as f:
            subprocess.run(cmd, check=True, stdout=f)
    else:
        subprocess.run(cmd, check=True)
    dt = time.monotonic() - t0
    print(f"  ({dt:.1f} s)", flush=True)
    with open(log, "a") as f:
        f.write(f"{line}\n# wall {dt:.1f} s\n")
    return dt


def widen_avd(src, dst):
    """Write `dst`: `src` with AVD_F_ACTION=3 replaced by the 300 m distances in the
    mitigated rows' params. Returns how many rows were changed."""
    with open(src, newline="") as f:
        reader = csv.DictReader(f)
        fields = reader.fieldnames
        rows = list(reader)
    changed = 0
    for r in rows:
        if (r.get("variant") or "").startswith("mitigated") and AVD_DEFAULT in (r.get("params") or ""):
            parts = [AVD_300 if p.strip() == AVD_DEFAULT else p for p in r["params"].split(";")]
            r["params"] = ";".join(parts)
            changed += 1
    with open(dst, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return changed


def study(name, a, env):
    d = os.path.join(a.out, name)
    os.makedirs(d, exist_ok=True)
    log = os.path.join(d, "commands.txt")
    if name == "adsb":
        gen = [a.savsim, "study", "gen", "--kind", "encounters", "--n", str(a.n), "--seed",
               str(a.seed_adsb)]
        sets = adsb_sets(a.sensors_dir)
    else:
        gen = [a.savsim, "study", "gen", "--kind", "approaches", "--n", str(a.n), "--seed",
               str(a.seed_prox)]
        sets = PROX_SETS
    for s in sets:
        gen += ["--sensors", s]
    gen += ["--out", d]
    run(gen, log)
    manifest = os.path.join(d, "study.csv")
    if name == "adsb":
        edited = os.path.join(d, "study_avd300.csv")
        n = widen_avd(manifest, edited)
        print(f"  study_avd300.csv: {n} mitigated rows with {AVD_300}", flush=True)
        with open(log, "a") as f:
            f.write(f"# {edited}: {n} mitigated rows' {AVD_DEFAULT} -> {AVD_300}\n")
        manifest = edited
    out = os.path.join(d, "out")
    wall = fly(a, env, manifest, out, log)
    summarize(a, out, d, "summary", log)
    png = os.path.join(a.charts, "sensors_adsb.png" if name == "adsb" else "sensors_proximity.png")
    kind = "adsb" if name == "adsb" else "proximity"
    run([sys.executable, CHART, "--kind", kind, os.path.join(d, "summary.json"), out, png], log)
    if name == "adsb" and a.adsb_base_seeds:
        wall += base_seeds(a, env, d, manifest, log)
    return wall


def fly(a, env, manifest, out, log):
    """`savsim study MANIFEST --out OUT`; its wall time."""
    fly = [a.savsim, "study", manifest, "--out", out, "--speedup", str(a.speedup), "--jobs",
           str(a.jobs)]
    if a.force:
        fly.append("--force")
    if a.keep_work:
        fly.append("--keep-work")
    subprocess_env = dict(os.environ, **env)
    print(f"$ SAVSIM_ARDUCOPTER={env['SAVSIM_ARDUCOPTER']} "
          f"SAVSIM_ARDUCOPTER_DEFAULTS={env['SAVSIM_ARDUCOPTER_DEFAULTS']} \\", flush=True)
    t0 = time.monotonic()
    line = " ".join(shlex.quote(c) for c in fly)
    print(f"$ {line}", flush=True)
    subprocess.run(fly, check=True, env=subprocess_env)
    wall = time.monotonic() - t0
    print(f"  ({wall:.1f} s)", flush=True)
    with open(log, "a") as f:
        f.write(f"SAVSIM_ARDUCOPTER={env['SAVSIM_ARDUCOPTER']} "
                f"SAVSIM_ARDUCOPTER_DEFAULTS={env['SAVSIM_ARDUCOPTER_DEFAULTS']} {line}\n"
                f"# wall {wall:.1f} s\n")
    return wall


def summarize(a, out, d, name, log):
    """`savsim study summarize OUT` as JSON and text, into D/NAME.json and D/NAME.txt."""
    run([a.savsim, "study", "summarize", out, "--json"], log,
        stdout=os.path.join(d, name + ".json"))
    run([a.savsim, "study", "summarize", out], log, stdout=os.path.join(d, name + ".txt"))
    with open(os.path.join(d, name + ".txt")) as f:
        print(f.read(), flush=True)


def base_seeds(a, env, d, manifest, log):
    """The NACp 6 rows of `manifest` flown under each of `--adsb-base-seeds`, then summarized
    with the study's own rows (their shards linked into D/all-seeds/)."""
    with open(manifest, newline="") as f:
        reader = csv.DictReader(f)
        fields = reader.fieldnames
        rows = [r for r in reader if "adsb-nacp6" in (r.get("variant") or "")]
    combined = os.path.join(d, "all-seeds")
    os.makedirs(combined, exist_ok=True)
    link(os.path.join(d, "out"), combined, "study")
    wall = 0.0
    for seed in a.adsb_base_seeds.split(","):
        seed = seed.strip()
        sd = os.path.join(d, f"seed-{seed}")
        os.makedirs(sd, exist_ok=True)
        edited = os.path.join(sd, "study.csv")
        with open(edited, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
            w.writeheader()
            for r in rows:
                w.writerow(dict(r, seed=seed, id=f"{r['id']}-seed{seed}",
                                variant=f"{r['variant']} seed {seed}"))
        with open(log, "a") as f:
            f.write(f"# {edited}: the NACp 6 rows with seed {seed}\n")
        out = os.path.join(sd, "out")
        wall += fly(a, env, edited, out, log)
        link(out, combined, f"seed{seed}")
    summarize(a, combined, d, "summary_seeds", log)
    return wall


def link(results, combined, prefix):
    """Each Parquet shard of `results` linked into `combined` as PREFIX-<name>."""
    for name in sorted(os.listdir(results)):
        if name.endswith(".parquet"):
            target = os.path.join(combined, f"{prefix}-{name}")
            if not os.path.lexists(target):
                os.symlink(os.path.abspath(os.path.join(results, name)), target)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--savsim", required=True, help="the savsim binary")
    ap.add_argument("--out", required=True, help="work directory (adsb/ and prox/ in it)")
    ap.add_argument("--n", type=int, default=200, help="encounter pairs / approach pairs")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--speedup", type=float, default=20)
    ap.add_argument("--study", choices=["adsb", "prox", "both"], default="both")
    ap.add_argument("--seed-adsb", type=int, default=11)
    ap.add_argument("--seed-prox", type=int, default=12)
    ap.add_argument("--sensors-dir", default=SENSORS_DIR,
                    help="where adsb-nacp*.toml and adsb-appq-reception.toml are")
    ap.add_argument("--charts", default=os.path.join(REPO, "docs", "images"),
                    help="where sensors_adsb.png and sensors_proximity.png go")
    ap.add_argument("--arducopter", default=os.environ.get("SAVSIM_ARDUCOPTER"))
    ap.add_argument("--defaults", default=os.environ.get("SAVSIM_ARDUCOPTER_DEFAULTS"))
    ap.add_argument("--force", action="store_true", help="fly shards whose results exist")
    ap.add_argument("--keep-work", action="store_true",
                    help="keep each row's folder (its feed.tlog)")
    ap.add_argument("--adsb-base-seeds", default="",
                    help="fly the NACp 6 rows again under these base seeds (comma-separated)")
    a = ap.parse_args()
    if not a.arducopter or not a.defaults:
        sys.exit("give --arducopter and --defaults (or SAVSIM_ARDUCOPTER, "
                 "SAVSIM_ARDUCOPTER_DEFAULTS)")
    a.savsim = os.path.abspath(a.savsim)
    a.sensors_dir = os.path.abspath(a.sensors_dir)
    a.out = os.path.abspath(a.out)
    a.charts = os.path.abspath(a.charts)
    env = {"SAVSIM_ARDUCOPTER": os.path.abspath(a.arducopter),
           "SAVSIM_ARDUCOPTER_DEFAULTS": os.path.abspath(a.defaults)}
    print(subprocess.run([a.savsim, "--version"], capture_output=True, text=True).stdout.strip())
    walls = {}
    for name in (["adsb", "prox"] if a.study == "both" else [a.study]):
        walls[name] = study(name, a, env)
    for name, w in walls.items():
        print(f"{name}: flown in {w:.1f} s of wall time")


if __name__ == "__main__":
    main()
