"""Send a burst of MAVLink to a savsim udpin port on 127.0.0.1: the bundled demo flight's
frames, 10 to a datagram, 10 datagrams a millisecond (100,000 frames/s), for --seconds.

    savsim live --connect udpin:127.0.0.1:14550 --scene scenes/city.toml --duration-s 14 \
        --summary-json live.json &
    python3 scripts/blast.py 14550 --seconds 10

docs/reliability.md and docs/performance.md report what savsim's summary said (dropped
chunks, decoded messages, the receive -> processed latency under the burst). Needs pymavlink.
"""

import argparse
import socket
import time
from pathlib import Path

from pymavlink import mavutil

ROOT = Path(__file__).resolve().parent.parent


def frames(tlog):
    log = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    out = []
    while True:
        m = log.recv_msg()
        if m is None:
            return out
        if m.get_type() != "BAD_DATA":
            out.append(m.get_msgbuf())


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("port", type=int)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--tlog", default=ROOT / "scenes/flights/copter_square_10ms.tlog")
    args = p.parse_args()
    all_frames = frames(args.tlog)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    to = ("127.0.0.1", args.port)
    sent, k = 0, 0
    start = time.perf_counter()
    for ms in range(int(args.seconds * 1000)):
        wait = start + ms / 1000.0 - time.perf_counter()
        if wait > 0:
            time.sleep(wait)
        for _ in range(10):
            datagram = b"".join(all_frames[(k + i) % len(all_frames)] for i in range(10))
            k += 10
            sock.sendto(datagram, to)
            sent += 10
    elapsed = time.perf_counter() - start
    print(f"{sent} frames in {elapsed:.2f} s ({sent / elapsed:.0f}/s)")


if __name__ == "__main__":
    main()
