#!/usr/bin/env python3
"""Check a closed-loop feed, as the autopilots read it, with pymavlink (independent of savsim).

Reads a tlog of what a vehicle received (or what `savsim replay --feed-out` wrote) and checks
every frame of savsim's feed component against the rules of docs/closed-loop.md:

- DISTANCE_SENSOR: readings grouped by time_boot_ms into frames; each frame has every expected
  orientation exactly once; min/max as configured, in cm; a reading in [min, max] or max + 1
  (nothing seen); frames' stamps strictly increase.
- OBSTACLE_DISTANCE: 72 bins, increment 5 deg, MAV_FRAME_BODY_FRD (12), angle_offset -20 (bin 0
  centred 20 degrees left of the nose: each 45-degree sector nine consecutive bins),
  readings in [min, max + 1] (never 0, never UINT16_MAX), time_usec increasing.
- ADSB_VEHICLE: 24-bit ICAO address, flags 0x1FF, tslc <= 1, heading < 36000.
- HEARTBEAT from the feed component: MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID.
- The frame rate on the stamps' clock.

Prints a JSON summary (counts, rate, the last reading per orientation, the last bins, the
ADS-B addresses seen); exits 1 with the first broken rule.

usage: check_feed.py FEED.tlog --orientations 0,1,...,24 --min-cm 20 --max-cm 4000
"""
import argparse
import json
import sys

from pymavlink import mavutil

FEED = (245, 196)


def fail(message):
    print(f"feed rule broken: {message}", file=sys.stderr)
    sys.exit(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("tlog")
    ap.add_argument("--orientations", default="0,1,2,3,4,5,6,7,24")
    ap.add_argument("--rangefinder", action="store_true", help="orientation 25 in every frame")
    ap.add_argument("--min-cm", type=int, default=20)
    ap.add_argument("--max-cm", type=int, default=4000)
    args = ap.parse_args()
    want = {int(o) for o in args.orientations.split(",") if o != ""}
    if args.rangefinder:
        want.add(25)

    log = mavutil.mavlink_connection(args.tlog, dialect="ardupilotmega")
    frames = []  # (stamp, {orientation: cm})
    last_usec = None
    bins_frames = 0
    last_bins = None
    adsb = {}
    heartbeats = 0
    others = 0
    while True:
        m = log.recv_match()
        if m is None:
            break
        if m.get_type() == "BAD_DATA":
            fail(f"a frame pymavlink cannot read: {m}")
        if (m.get_srcSystem(), m.get_srcComponent()) != FEED:
            others += 1
            continue
        t = m.get_type()
        if t == "DISTANCE_SENSOR":
            if m.min_distance != args.min_cm or m.max_distance != args.max_cm:
                fail(f"min/max {m.min_distance}/{m.max_distance} cm, want {args.min_cm}/{args.max_cm}")
            if not (args.min_cm <= m.current_distance <= args.max_cm + 1):
                fail(f"reading {m.current_distance} cm outside [min, max + 1]")
            if not frames or frames[-1][0] != m.time_boot_ms:
                if frames and m.time_boot_ms <= frames[-1][0]:
                    fail(f"stamp {m.time_boot_ms} after {frames[-1][0]}: not advancing")
                frames.append((m.time_boot_ms, {}))
            readings = frames[-1][1]
            if m.orientation in readings:
                fail(f"orientation {m.orientation} twice in the frame at {m.time_boot_ms}")
            readings[m.orientation] = m.current_distance
        elif t == "OBSTACLE_DISTANCE":
            if len(m.distances) != 72:
                fail(f"{len(m.distances)} bins")
            if m.increment != 5 or abs(m.increment_f - 5.0) > 1e-6:
                fail(f"increment {m.increment} / {m.increment_f}")
            if m.frame != 12 or m.angle_offset != -20:
                fail(f"frame {m.frame}, angle_offset {m.angle_offset}: want 12 (BODY_FRD), -20")
            if m.min_distance != args.min_cm or m.max_distance != args.max_cm:
                fail(f"min/max {m.min_distance}/{m.max_distance}")
            for d in m.distances:
                if not (args.min_cm <= d <= args.max_cm + 1):
                    fail(f"bin reading {d} cm outside [min, max + 1]")
            if last_usec is not None and m.time_usec <= last_usec:
                fail(f"time_usec {m.time_usec} after {last_usec}")
            last_usec = m.time_usec
            bins_frames += 1
            last_bins = list(m.distances)
        elif t == "ADSB_VEHICLE":
            if m.ICAO_address > 0xFFFFFF:
                fail(f"ICAO {m.ICAO_address:#x} is not 24-bit")
            if m.flags != 0x1FF or m.tslc > 1 or m.heading >= 36000:
                fail(f"ADSB_VEHICLE flags {m.flags:#x}, tslc {m.tslc}, heading {m.heading}")
            adsb[m.ICAO_address] = {
                "lat": m.lat, "lon": m.lon, "altitude_mm": m.altitude,
                "heading_cdeg": m.heading, "hor_velocity_cms": m.hor_velocity,
                "emitter_type": m.emitter_type, "callsign": m.callsign,
            }
        elif t == "HEARTBEAT":
            if m.type != 18 or m.autopilot != 8:
                fail(f"feed heartbeat type {m.type}, autopilot {m.autopilot}")
            heartbeats += 1
    for stamp, readings in frames:
        if set(readings) != want:
            fail(f"frame at {stamp} has orientations {sorted(readings)}, want {sorted(want)}")
    rate = None
    if len(frames) > 1 and frames[-1][0] > frames[0][0]:
        rate = (len(frames) - 1) * 1000.0 / (frames[-1][0] - frames[0][0])
    print(json.dumps({
        "frames": len(frames),
        "rate_hz": rate,
        "last": {str(k): v for k, v in frames[-1][1].items()} if frames else {},
        "obstacle_distance_frames": bins_frames,
        "last_bins": last_bins,
        "adsb": {str(k): v for k, v in adsb.items()},
        "heartbeats": heartbeats,
        "other_messages": others,
    }))


if __name__ == "__main__":
    main()
