"""What the sensor models cost, measured in one run (release build):

    cargo build --release && python3 scripts/sensor_cost.py [--runs 5] [--encounters 2000] \
        [--live-rounds 3] [--only feed|batch|live]

1. The feed: `savsim demo --feed obstacle-distance` (the bundled flight over the bundled city)
   with `--sensors ideal`, with the same 72-ray ring as a modelled device without errors
   (scenes/sensors/ring72-exact.toml), and with every error a range device can have
   (ring72-noisy.toml): wall time of the whole replay, median of the runs (the feed's frames
   are cast after the collision tick, whose own cost the summary reports apart).
2. Batch: N generated encounters (180 s at 10 Hz, open air) run by `savsim batch --jobs 1`
   plain, alerting on exact states (`daa_conf`, `sensors = ideal`) and on modelled ones
   (`sensors = adsb-1090es,gps-ins`), the variants interleaved over the rounds: encounters per
   core-hour from the median wall time.
3. The closed-loop feed's latency (with `SAVSIM_ARDUCOPTER`): ArduCopter SITL (instance 9,
   its ports clear of a study's) at speedup 1 on the ground at the bundled city's origin,
   `savsim live --connect udpin:127.0.0.1:PORT --scene scenes/city.toml --feed
   proximity,rangefinder,adsb --duration-s 30` with each sensor set in turn (ideal; rplidar-a2
   with tfmini-down and adsb-1090es; the noisy ring), the rounds interleaved, the first (SITL's
   boot) discarded: `link.feed.latency` p99 from each run's summary, median over the rounds.

Prints each as a Markdown table.
"""

import argparse
import csv
import json
import os
import socket
import statistics
import subprocess
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("SAVSIM_BIN") or os.path.join(ROOT, "target", "release", "savsim")
CONF = """lookahead_time = 120 [s]
hysteresis_time = 5 [s]
persistence_time = 4 [s]
alerting_m = 2
alerting_n = 4
h_pos_z_score = 1.5
h_vel_z_score_min = 0.5
h_vel_z_score_max = 1.0
h_vel_z_distance = 5 [nmi]
v_pos_z_score = 0.75
v_vel_z_score = 1.5
alerters = S
S_alert_1_region = NEAR
S_alert_1_alerting_time = 40 [s]
S_alert_1_early_alerting_time = 60 [s]
S_alert_1_detector = d
S_d_WCV_DTHR = 2000 [ft]
S_d_WCV_ZTHR = 250 [ft]
S_d_WCV_TTHR = 0 [s]
S_d_WCV_TCOA = 0 [s]
S_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD_SUM
"""


def feed(runs, work):
    configs = [
        ("ideal", "ideal"),
        ("ring as a device, no error", os.path.join(ROOT, "scenes/sensors/ring72-exact.toml")),
        ("ring as a device, every error", os.path.join(ROOT, "scenes/sensors/ring72-noisy.toml")),
    ]
    walls = {label: [] for label, _ in configs}
    # Round-robin, the first round discarded (caches warm), so a change in the machine's load
    # falls on every configuration alike.
    for round_ in range(runs + 1):
        for label, sensors in configs:
            started = time.monotonic()
            subprocess.run([BIN, "demo", "--feed", "obstacle-distance", "--sensors", sensors],
                           check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
            if round_ > 0:
                walls[label].append(time.monotonic() - started)
    rows = [(label, statistics.median(walls[label])) for label, _ in configs]
    base = rows[0]
    print("| feed from | wall s (median) | vs ideal |")
    print("|---|---|---|")
    for label, wall in rows:
        print(f"| {label} | {wall:.2f} | {wall / base[1]:.3f} |")


def batch(n, rounds, work):
    plain = os.path.join(work, "enc.csv")
    subprocess.run([BIN, "batch", "gen-encounters", "--n", str(n), "--seed", "3", "--out", plain],
                   check=True, stdout=subprocess.DEVNULL)
    conf = os.path.join(work, "s.conf")
    with open(conf, "w") as f:
        f.write(CONF)
    with open(plain, newline="") as f:
        runs = list(csv.DictReader(f))
    variants = [("plain", None), ("alerting on exact states", "ideal"),
                ("alerting on adsb-1090es, gps-ins", "adsb-1090es,gps-ins")]
    manifests = []
    for i, (label, sensors) in enumerate(variants):
        manifest = plain
        if sensors:
            manifest = os.path.join(work, f"enc-{i}.csv")
            with open(manifest, "w", newline="") as f:
                fields = list(runs[0].keys())
                fields += [k for k in ("sensors", "daa_conf") if k not in fields]
                w = csv.DictWriter(f, fieldnames=fields)
                w.writeheader()
                for r in runs:
                    w.writerow({**r, "sensors": sensors, "daa_conf": conf})
        manifests.append(manifest)
    walls = {label: [] for label, _ in variants}
    # Round-robin, as the feed's: a change in the machine's load falls on every variant alike.
    for _ in range(rounds):
        for (label, _), manifest in zip(variants, manifests):
            out = os.path.join(work, "out")
            started = time.monotonic()
            subprocess.run([BIN, "batch", manifest, "--out", out, "--jobs", "1", "--force"],
                           check=True, stdout=subprocess.DEVNULL)
            walls[label].append(time.monotonic() - started)
    rows = [(label, statistics.median(walls[label])) for label, _ in variants]
    print()
    print(f"| {n} encounters, --jobs 1, median of {rounds} | wall s | encounters per core-hour "
          "| vs plain | vs exact states |")
    print("|---|--:|--:|--:|--:|")
    for label, wall in rows:
        print(f"| {label} | {wall:.1f} | {n / wall * 3600:,.0f} | {rows[0][1] / wall:.3f} "
              f"| {rows[1][1] / wall:.3f} |")


def free_udp_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def live(rounds, work):
    arducopter = os.environ.get("SAVSIM_ARDUCOPTER")
    if not arducopter:
        print("\nSKIP live feed latency: set SAVSIM_ARDUCOPTER (and SAVSIM_ARDUCOPTER_DEFAULTS)")
        return
    port = free_udp_port()
    command = [arducopter, "--model", "+", "--speedup", "1", "--wipe", "-I", "9",
               "--home", "-35.363261,149.16523,584,0", "--serial0", f"udpclient:127.0.0.1:{port}"]
    if os.environ.get("SAVSIM_ARDUCOPTER_DEFAULTS"):
        command += ["--defaults", os.environ["SAVSIM_ARDUCOPTER_DEFAULTS"]]
    sets = [("ideal", "ideal"),
            ("rplidar-a2, tfmini-down, adsb-1090es", "rplidar-a2,tfmini-down,adsb-1090es"),
            ("the noisy ring", os.path.join(ROOT, "scenes/sensors/ring72-noisy.toml"))]
    p99 = {label: [] for label, _ in sets}
    frames = {label: 0 for label, _ in sets}
    sitl = subprocess.Popen(command, cwd=work, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        for round_ in range(rounds + 1):  # the first round (SITL's boot) discarded
            for label, sensors in sets:
                summary = os.path.join(work, "summary.json")
                subprocess.run([BIN, "live", "--connect", f"udpin:127.0.0.1:{port}",
                                "--scene", os.path.join(ROOT, "scenes/city.toml"),
                                "--feed", "proximity,rangefinder,adsb", "--sensors", sensors,
                                "--duration-s", "30", "--summary-json", summary],
                               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                with open(summary) as f:
                    latency = json.load(f)["link"]["feed"]["latency"]
                if round_ > 0:
                    p99[label].append(latency["p99_us"])
                    frames[label] += latency["chunks"]
    finally:
        sitl.terminate()
        sitl.wait()
    base = statistics.median(p99["ideal"])
    print()
    print(f"| live feed, {rounds} rounds of 30 s | frames | p99 us (median of rounds) | vs ideal |")
    print("|---|--:|--:|--:|")
    for label, _ in sets:
        median = statistics.median(p99[label])
        print(f"| {label} | {frames[label]:,} | {median:.0f} | {median / base:.3f} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--encounters", type=int, default=2000)
    ap.add_argument("--live-rounds", type=int, default=3)
    ap.add_argument("--only", choices=["feed", "batch", "live"], default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        if args.only in (None, "feed"):
            feed(args.runs, work)
        if args.only in (None, "batch"):
            batch(args.encounters, args.runs, work)
        if args.only in (None, "live"):
            live(args.live_rounds, work)


if __name__ == "__main__":
    main()
