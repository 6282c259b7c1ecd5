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

With --show the fleet flies a drone show's pattern instead: a grid --spacing-m apart (3 m by
default) on the ground around the origin, every vehicle taking off together to --altitude-m
(30 m), the block spreading to twice its spacing with a wave running through it, holding, then
drawing together and landing in its slots; vehicles 1 and 2 (neighbours in the grid) are made
to touch in the middle of the hold (vehicle 2 drifts onto vehicle 1 and back), as a show's
fault would. No other pair ever comes nearer than the grid's spacing.

    python3 scripts/fleet.py 0 --show --vehicles 100 --seconds 60 --tlog show.tlog \\
        --slots-out slots.csv
    savsim replay show.tlog --scene empty.toml --separation-m 2 --slots slots.csv

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


def circling(n, count, args):
    """Vehicle n's circle: where it is at t (east, north, up, metres) and its yaw rate."""
    east0, north0, up = place(n, count, args.spacing_m, args.altitude_m)
    omega = args.speed_mps / args.radius_m

    speed = args.speed_mps

    def at(t):
        a = omega * t + n
        where = east0 + args.radius_m * math.cos(a), north0 + args.radius_m * math.sin(a), up
        return where, (-speed * math.sin(a), speed * math.cos(a), 0.0)

    return at, omega


# A show's phases, seconds: on the ground, climbing, spreading, holding (the rest), drawing
# together, descending, and on the ground again at the end.
SHOW_GROUND_S, SHOW_CLIMB_MPS, SHOW_SPREAD_S = 2.0, 2.0, 8.0
SHOW_WAVE_M, SHOW_WAVE_S = 2.0, 6.0


def smooth(u):
    """0 to 1 with zero slope at both ends (a vehicle's move starting and stopping)."""
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


def show(n, count, args, faulty=True):
    """Vehicle n's flight in the show (see the module's doc): where it is at t (its slot's
    place, with `faulty` false)."""
    spacing = args.spacing_m
    east0, north0, _ = place(n, count, spacing, 0.0)
    altitude = args.altitude_m
    climb_s = altitude / SHOW_CLIMB_MPS
    up_at = SHOW_GROUND_S + climb_s
    spread_at = up_at
    spread_end = spread_at + SHOW_SPREAD_S
    down_at = args.seconds - SHOW_GROUND_S - climb_s
    gather_at = down_at - SHOW_SPREAD_S
    hold_mid = 0.5 * (spread_end + gather_at)
    # The wave: each vehicle's height offset by its column's phase, grown in and out with the
    # spread (neighbours' heights differ, which only adds to their distance).
    side = max(1, math.ceil(math.sqrt(count)))
    column = n % side

    def where(t):
        climbing = smooth((t - SHOW_GROUND_S) / climb_s) - smooth((t - down_at) / climb_s)
        spread = 1.0 + smooth((t - spread_at) / SHOW_SPREAD_S) - smooth((t - gather_at) / SHOW_SPREAD_S)
        east, north = east0 * spread, north0 * spread
        wave = (spread - 1.0) * SHOW_WAVE_M * math.sin(2 * math.pi * (t / SHOW_WAVE_S + column / side))
        up = altitude * climbing + wave
        if n == 1 and faulty:
            # Vehicle 2 drifts onto vehicle 1 (its western neighbour) and back in the hold,
            # touching it at its middle (within 0.1 m), keeping its height.
            e1, n1, _ = place(0, count, spacing, 0.0)
            touch = smooth(1.0 - abs(t - hold_mid) / 4.0)
            other_up = altitude * climbing + (spread - 1.0) * SHOW_WAVE_M * math.sin(
                2 * math.pi * (t / SHOW_WAVE_S))
            east += touch * (e1 * spread + 0.1 - east)
            north += touch * (n1 * spread - north)
            up += touch * (other_up - up)
        return east, north, up

    def at(t):
        ahead, behind = where(t + 0.01), where(t - 0.01)
        return where(t), tuple((a - b) / 0.02 for a, b in zip(ahead, behind))

    return at, 0.0


def write_slots(path, count, args):
    """Every vehicle's slot over the show, as savsim's --slots reads them: a keyframe every
    0.1 s, seconds after the first vehicle's first position (the show's time)."""
    with open(path, "w") as out:
        out.write("vehicle,t_s,east_m,north_m,up_m,component\n")
        for n in range(count):
            system_id, component_id = vehicle_id(n)
            position, _ = show(n, count, args, faulty=False)
            for k in range(int(args.seconds * 10) + 1):
                t = k / 10
                (east, north, up), _ = position(t)
                out.write(f"{system_id},{t:.1f},{east:.3f},{north:.3f},{up:.3f},{component_id}\n")


def frames_of(n, count, args):
    """Vehicle n's datagrams: (t_s, bytes, frames) in time order."""
    hz, seconds = args.hz, args.seconds
    system_id, component_id = vehicle_id(n)
    enc = Encoder(system_id, component_id)
    position, omega = (show if args.show else circling)(n, count, args)
    phase_s = (n / count) / hz
    m_per_deg_lon = M_PER_DEG_LAT * math.cos(math.radians(ORIGIN_LAT))
    out = []
    for k in range(int(seconds * hz)):
        t = phase_s + k / hz
        (east, north, up), (v_east, v_north, v_up) = position(t)
        yaw = 0.0 if args.show else math.atan2(v_east, v_north)
        ms = int(t * 1000) + 1000
        gpi = mavlink.MAVLink_global_position_int_message(
            ms,
            int((ORIGIN_LAT + north / M_PER_DEG_LAT) * 1e7),
            int((ORIGIN_LON + east / m_per_deg_lon) * 1e7),
            int((ORIGIN_ALT_M + up) * 1000),
            int(up * 1000),
            int(v_north * 100),
            int(v_east * 100),
            int(-v_up * 100),
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
        help="every vehicle this high (default 60-100 m, by vehicle; a show's 30 m)",
    )
    p.add_argument(
        "--show",
        action="store_true",
        help="fly a drone show's pattern from a grid on the ground (see the module's doc)",
    )
    p.add_argument(
        "--slots-out",
        default=None,
        help="with --show: write every vehicle's slot (the show as planned, no vehicle "
        "touching) to this CSV, for savsim's --slots",
    )
    args = p.parse_args()
    if args.show:
        args.spacing_m = 3.0 if args.spacing_m is None else args.spacing_m
        args.altitude_m = 30.0 if args.altitude_m is None else args.altitude_m
        least_s = 2 * (SHOW_GROUND_S + args.altitude_m / SHOW_CLIMB_MPS + SHOW_SPREAD_S) + 8.0
        if args.seconds < least_s:
            p.error(f"--show at {args.altitude_m} m needs --seconds of at least {least_s:.0f}")
        if args.vehicles < 2:
            p.error("--show needs at least 2 vehicles")
    elif args.slots_out is not None:
        p.error("--slots-out needs --show")
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
    if args.slots_out is not None:
        try:
            write_slots(args.slots_out, args.vehicles, args)
        except OSError as e:
            p.error(f"--slots-out {args.slots_out}: {e.strerror}")
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
