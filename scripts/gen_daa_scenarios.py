#!/usr/bin/env python3
"""Write savsim's own DAIDALUS state files (tests/fixtures/daa/*.daa, and with the state
uncertainty columns of sensor uncertainty mitigation, tests/fixtures/daa/sum/*.daa): encounters
for running savsim daa and DAIDALUS's DaidalusAlerting side by side (docs/daa.md).
Deterministic.

    python3 scripts/gen_daa_scenarios.py tests/fixtures/daa
"""
import math
import sys
from pathlib import Path

R = 1852.0 * 60.0 * 180.0 / math.pi  # DAIDALUS's sphere: 1 nmi per minute of arc
LAT0, LON0 = 47.3977, 8.5456  # near Zurich: small UAS at low altitude


def geodetic(e_m, n_m):
    """A point e_m east and n_m north of (LAT0, LON0) on the sphere (small offsets)."""
    lat = LAT0 + math.degrees(n_m / R)
    lon = LON0 + math.degrees(e_m / (R * math.cos(math.radians(LAT0))))
    return lat, lon


def straight(p0, v):
    return lambda t: ([p0[i] + v[i] * t for i in range(3)], v)


def turning(p0, speed, heading0_deg, rate_deg_s, climb):
    """Constant turn rate and climb: the state at t (exact arc)."""

    def at(t):
        h0, w = math.radians(heading0_deg), math.radians(rate_deg_s)
        if w == 0:
            e, n = speed * t * math.sin(h0), speed * t * math.cos(h0)
        else:
            e = speed / w * (math.cos(h0) - math.cos(h0 + w * t))
            n = speed / w * (math.sin(h0 + w * t) - math.sin(h0))
        h = h0 + w * t
        return ([p0[0] + e, p0[1] + n, p0[2] + climb * t],
                [speed * math.sin(h), speed * math.cos(h), climb])

    return at


def write_geodetic(path, aircraft, duration_s):
    with open(path, "w") as f:
        f.write("NAME, lat, lon, alt, vx, vy, vz, time\n")
        f.write("unitless, [deg], [deg], [m], [m/s], [m/s], [m/s], [s]\n")
        for t in range(duration_s + 1):
            for name, track in aircraft:
                (e, n, u), v = track(t)
                lat, lon = geodetic(e, n)
                f.write(f"{name}, {lat:.10f}, {lon:.10f}, {u:.4f}, "
                        f"{v[0]:.6f}, {v[1]:.6f}, {v[2]:.6f}, {t:.1f}\n")


def write_euclidean(path, aircraft, duration_s):
    # DAIDALUS's default units: sx, sy in nmi, sz in ft, vx, vy in knots, vz in fpm.
    with open(path, "w") as f:
        f.write("NAME sx sy sz vx vy vz time\n")
        for t in range(duration_s + 1):
            for name, track in aircraft:
                (e, n, u), v = track(t)
                f.write(f"{name} {e / 1852:.9f} {n / 1852:.9f} {u / 0.3048:.6f} "
                        f"{v[0] * 3600 / 1852:.6f} {v[1] * 3600 / 1852:.6f} "
                        f"{v[2] * 60 / 0.3048:.6f} {t}\n")


def write_polar(path, aircraft, duration_s):
    with open(path, "w") as f:
        f.write("NAME, sx, sy, sz, trk, gs, vs, time\n")
        f.write("unitless, [m], [m], [m], [deg], [m/s], [m/s], [s]\n")
        for t in range(duration_s + 1):
            for name, track in aircraft:
                (e, n, u), v = track(t)
                trk = math.degrees(math.atan2(v[0], v[1])) % 360.0
                f.write(f"{name}, {e:.4f}, {n:.4f}, {u:.4f}, {trk:.6f}, "
                        f"{math.hypot(v[0], v[1]):.6f}, {v[2]:.6f}, {t:.1f}\n")


# 1-sigma state errors (s_EW, s_NS, s_EN, sz in m; v_EW, v_NS, v_EN, vz in m/s): NACp 8 and
# NACv 2 (DO-365 Appendix Q's ownship), an intruder seen by ADS-B at NACp 7 with a correlated
# east-north error, and one with none.
SIGMA = {
    "own": (37.8, 37.8, 0.0, 4.5, 1.22, 1.22, 0.0, 0.3),
    "adsb": (75.6, 60.0, -30.0, 7.6, 1.5, 1.0, 0.5, 0.87),
    "exact": (0.0,) * 8,
}


def write_sum(path, aircraft, sigmas, duration_s):
    """A Euclidean file with the uncertainty columns, in metres and m/s (the ownship first)."""
    with open(path, "w") as f:
        f.write("NAME, sx, sy, sz, vx, vy, vz, time, s_EW_std, s_NS_std, s_EN_std, sz_std, "
                "v_EW_std, v_NS_std, v_EN_std, vz_std\n")
        f.write("unitless, [m], [m], [m], [m/s], [m/s], [m/s], [s], [m], [m], [m], [m], "
                "[m/s], [m/s], [m/s], [m/s]\n")
        for t in range(duration_s + 1):
            for (name, track), sigma in zip(aircraft, sigmas):
                (e, n, u), v = track(t)
                stds = ", ".join(f"{x:.4f}" for x in SIGMA[sigma])
                f.write(f"{name}, {e:.4f}, {n:.4f}, {u:.4f}, {v[0]:.6f}, {v[1]:.6f}, "
                        f"{v[2]:.6f}, {t:.1f}, {stds}\n")


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    # Two small UAS at 120 m, head on at 20 m/s each, 60 m abeam, 10 m apart vertically.
    write_geodetic(out / "sua_head_on.daa", [
        ("Own", straight([0, -2400, 120], [0, 20, 0])),
        ("Intruder", straight([60, 2400, 130], [0, -20, 0])),
    ], 150)
    # A 90-degree crossing at 400 ft: ownship 30 m/s north, intruder 25 m/s west.
    write_euclidean(out / "crossing.daa", [
        ("Own", straight([0, -3000, 122], [0, 30, 0])),
        ("Intruder", straight([2600, 40, 135], [-25, 0, 0])),
    ], 160)
    # Overtaking: the intruder 15 m/s faster from behind, 30 m to the side, 15 m below.
    write_euclidean(out / "overtaking.daa", [
        ("Own", straight([0, 0, 150], [0, 20, 0])),
        ("Intruder", straight([30, -2200, 135], [0, 35, 0])),
    ], 200)
    # A climbing, turning ownship (3 deg/s, 2 m/s up) and a straight intruder, in trk/gs/vs.
    write_polar(out / "climbing_turn.daa", [
        ("Own", turning([0, 0, 100], 25.0, 0.0, 3.0, 2.0)),
        ("Intruder", straight([1500, 1800, 180], [-12, -10, -1])),
    ], 150)
    # Three aircraft: ownship and two intruders from either side.
    write_geodetic(out / "three_aircraft.daa", [
        ("Own", straight([0, 0, 100], [0, 25, 0])),
        ("Left", straight([-3000, 2000, 110], [25, 5, 0])),
        ("Right", straight([2800, 3200, 90], [-20, 0, 0.5])),
    ], 180)
    # The same kinds of encounter with state errors (DAIDALUS's SUM alerters).
    (out / "sum").mkdir(exist_ok=True)
    write_sum(out / "sum" / "sum_head_on.daa", [
        ("Own", straight([0, -4000, 120], [0, 30, 0])),
        ("Intruder", straight([150, 4000, 160], [0, -30, 0])),
    ], ["own", "adsb"], 170)
    write_sum(out / "sum" / "sum_crossing.daa", [
        ("Own", straight([0, -3000, 122], [0, 30, 0])),
        ("Intruder", straight([2600, 40, 135], [-25, 0, -0.5])),
    ], ["own", "adsb"], 160)
    write_sum(out / "sum" / "sum_near_miss_exact_intruder.daa", [
        ("Own", straight([0, 0, 150], [0, 20, 0.5])),
        ("Intruder", straight([400, 2600, 140], [-4, -20, 0])),
    ], ["own", "exact"], 170)
    write_sum(out / "sum" / "sum_three_aircraft.daa", [
        ("Own", straight([0, 0, 100], [0, 25, 0])),
        ("Left", straight([-3000, 2000, 110], [25, 5, 0])),
        ("Right", straight([2800, 3200, 90], [-20, 0, 0.5])),
    ], ["own", "adsb", "exact"], 180)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/fixtures/daa")
