"""Send a fleet's telemetry to a savsim udpin port on 127.0.0.1, as many vehicles on one link
would: N vehicles (MAVLink system ids 1..250, then component ids 1, 2, ... for more than 250),
each flying a circle over the bundled city at its own place (or, with --spacing-m, in a
block around the origin), each sending GLOBAL_POSITION_INT
and ATTITUDE at --hz (one datagram per vehicle and sample) and HEARTBEAT at 1 Hz. Every frame
is encoded before the first is sent; the send loop only keeps the schedule (each vehicle at its
own phase in the period), so the sender's cost does not limit the rate.

    savsim live --connect udpin:127.0.0.1:14550 --scene scenes/city.toml --duration-s 70 \\
        --summary-json live.json &
    python3 scripts/fleet.py 14550 --vehicles 1000 --hz 10 --seconds 60
    # a drone-show block: 25 m apart at 360 m, small circles
    python3 scripts/fleet.py 14550 --vehicles 1000 --spacing-m 25 --altitude-m 360 --radius-m 5

It prints the frames and datagrams it sent and how late its sends ran; savsim's summary says
what it took in (`ingest`), and its link report the receive -> processed latency.
With --tlog PATH the datagrams are written to a tlog instead, for `savsim replay` at full speed
(the session's throughput without the network). docs/performance.md has the figures. Needs
pymavlink.
"""

import argparse
import math
import os
import socket
import struct
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

# The bundled city's origin (scenes/city.toml) and its extent, metres east/north of it.
ORIGIN_LAT, ORIGIN_LON, ORIGIN_ALT_M = -35.363261, 149.16523, 584.0
EXTENT_M = 1900.0
M_PER_DEG_LAT = 111_132.0


class Encoder:
    """A pymavlink encoder for one sender identity that keeps the frames it packs."""

    def __init__(self, system_id, component_id):
        self.link = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)

    def pack(self, message):
        """The frame, with this sender's next sequence number (pymavlink's send() counts it;
        pack() alone does not)."""
        frame = message.pack(self.link)
        self.link.seq = (self.link.seq + 1) % 256
        return frame


def vehicle_id(n):
    return n % 250 + 1, n // 250 + 1


def place(n, count, spacing_m=None, altitude_m=None):
    """Vehicle n's circle centre (east, north, up) on a square grid: spread over the whole city
    (60-100 m up), or `spacing_m` apart around the origin (a drone-show block), `altitude_m`
    up when given."""
    side = max(1, math.ceil(math.sqrt(count)))
    col, row = n % side, n // side
    if spacing_m is None:
        step = 2 * EXTENT_M / side
        east = -EXTENT_M + step * (col + 0.5)
        north = -EXTENT_M + step * (row + 0.5)
    else:
        east = (col - (side - 1) / 2) * spacing_m
        north = (row - (side - 1) / 2) * spacing_m
    up = altitude_m if altitude_m is not None else 60.0 + 40.0 * ((n * 7919) % 5) / 4.0
    return east, north, up


def frames_of(n, count, args):
    """Vehicle n's datagrams: (t_s, bytes, frames) in time order."""
    hz, seconds, radius_m, speed_mps = args.hz, args.seconds, args.radius_m, args.speed_mps
    system_id, component_id = vehicle_id(n)
    enc = Encoder(system_id, component_id)
    east0, north0, up = place(n, count, args.spacing_m, args.altitude_m)
    phase_s = (n / count) / hz
    omega = speed_mps / radius_m
    lat0 = ORIGIN_LAT + north0 / M_PER_DEG_LAT
    m_per_deg_lon = M_PER_DEG_LAT * math.cos(math.radians(ORIGIN_LAT))
    out = []
    for k in range(int(seconds * hz)):
        t = phase_s + k / hz
        a = omega * t + n
        east = east0 + radius_m * math.cos(a)
        north = north0 + radius_m * math.sin(a)
        v_east, v_north = -speed_mps * math.sin(a), speed_mps * math.cos(a)
        yaw = math.atan2(v_east, v_north)
        ms = int(t * 1000) + 1000
        gpi = mavlink.MAVLink_global_position_int_message(
            ms,
            int((lat0 + (north - north0) / M_PER_DEG_LAT) * 1e7),
            int((ORIGIN_LON + east / m_per_deg_lon) * 1e7),
            int((ORIGIN_ALT_M + up) * 1000),
            int(up * 1000),
            int(v_north * 100),
            int(v_east * 100),
            0,
            int((math.degrees(yaw) % 360) * 100),
        )
        att = mavlink.MAVLink_attitude_message(ms, 0.0, 0.0, yaw, 0.0, 0.0, omega)
        datagram = enc.pack(gpi) + enc.pack(att)
        frames = 2
        if k % max(1, int(hz)) == 0:
            frames += 1
            hb = mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4, 3
            )
            datagram += enc.pack(hb)
        out.append((t, datagram, frames))
    return out


def write_tlog(path, schedule):
    """Each frame of each datagram after its stamp: microseconds since the Unix epoch,
    big-endian, as MAVProxy writes a tlog."""
    epoch_us = 1_767_225_600_000_000  # 2026-01-01T00:00:00Z
    with open(path, "wb") as out:
        for t, datagram, _ in schedule:
            stamp = struct.pack(">Q", epoch_us + int(round(t * 1e6)))
            for frame in split_frames(datagram):
                out.write(stamp + frame)


def split_frames(datagram):
    """The MAVLink 2 frames packed one after another in `datagram` (unsigned: 12 bytes of
    header and checksum around the payload)."""
    i = 0
    while i < len(datagram):
        length = datagram[i + 1]
        end = i + 12 + length
        yield datagram[i:end]
        i = end


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("port", type=int)
    p.add_argument("--vehicles", type=int, default=1000)
    p.add_argument("--hz", type=float, default=10.0)
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--radius-m", type=float, default=40.0)
    p.add_argument("--speed-mps", type=float, default=8.0)
    p.add_argument(
        "--spacing-m",
        type=float,
        default=None,
        help="circle centres this far apart on a square grid around the origin (a drone-show "
        "block); default: spread over the whole city",
    )
    p.add_argument(
        "--tlog",
        default=None,
        help="write the fleet's datagrams to this tlog (each frame after its 8-byte microsecond "
        "stamp, the schedule's time from 2026-01-01) instead of sending them, for "
        "`savsim replay` at full speed",
    )
    p.add_argument(
        "--altitude-m",
        type=float,
        default=None,
        help="every vehicle this high (default 60-100 m, by vehicle)",
    )
    args = p.parse_args()
    if not 1 <= args.vehicles <= 250 * 255:
        p.error("--vehicles must be in 1..63750")
    if not (0 < args.hz <= 100 and 0 < args.seconds <= 3600):
        p.error("--hz must be in (0, 100] and --seconds in (0, 3600]")
    if args.spacing_m is not None and not 0 < args.spacing_m <= 10_000:
        p.error("--spacing-m must be in (0, 10000]")
    if args.altitude_m is not None and not 0 <= args.altitude_m <= 10_000:
        p.error("--altitude-m must be in [0, 10000]")
    if not 0 < args.radius_m <= 10_000:
        p.error("--radius-m must be in (0, 10000]")
    built = time.perf_counter()
    schedule = []
    for n in range(args.vehicles):
        schedule.extend(frames_of(n, args.vehicles, args))
    schedule.sort(key=lambda x: x[0])
    frames = sum(f for _, _, f in schedule)
    print(f"encoded {len(schedule)} datagrams in {time.perf_counter() - built:.1f} s")
    if args.tlog is not None:
        try:
            write_tlog(args.tlog, schedule)
        except OSError as e:
            p.error(f"--tlog {args.tlog}: {e.strerror}")
        print(f"wrote {len(schedule)} datagrams ({frames} frames) to {args.tlog}")
        return
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)
    to = ("127.0.0.1", args.port)
    start = time.perf_counter()
    late_max = 0.0
    for t, datagram, _ in schedule:
        wait = start + t - time.perf_counter()
        if wait > 0.0005:
            time.sleep(wait)
        else:
            late_max = max(late_max, -wait)
        sock.sendto(datagram, to)
    elapsed = time.perf_counter() - start
    print(
        f"sent {len(schedule)} datagrams ({frames} frames) from {args.vehicles} vehicles "
        f"in {elapsed:.2f} s; latest send {late_max * 1000:.1f} ms behind schedule"
    )


if __name__ == "__main__":
    main()
