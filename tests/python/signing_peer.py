#!/usr/bin/env python3
"""A vehicle played by pymavlink's MAVLink 2 signing (independent of savsim), for signing tests.

Sends to savsim (--to HOST:PORT), as system 1 component 1 (an ArduCopter heartbeat), in turn:
  signed      heartbeats and GLOBAL_POSITION_INT signed with the key (the passphrase's SHA-256,
              as MAVProxy's `signing setup` makes it);
  unsigned    GLOBAL_POSITION_INT without a signature;
  wrong_key   GLOBAL_POSITION_INT signed with another key;
  replayed    earlier signed frames sent again, byte for byte;
  stale       GLOBAL_POSITION_INT from a new stream (component 2) whose timestamp is two minutes
              behind;
then signed frames again. Meanwhile it reads what savsim sends back and checks each frame's
signature with pymavlink (unsigned frames rejected).

Prints one JSON object: {"sent": {category: n}, "signed_positions": n, "from_savsim":
{"good": n, "bad": n, "unsigned": n, "types": {...}}}.

usage: signing_peer.py --to 127.0.0.1:PORT --passphrase P [--per-kind 20]
"""
import argparse
import hashlib
import json
import os
import time
from collections import defaultdict

os.environ["MAVLINK20"] = "1"  # before pymavlink loads: MAVLink 2 (signing needs it)
from pymavlink import mavutil  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--to", required=True)
    ap.add_argument("--passphrase", required=True)
    ap.add_argument("--per-kind", type=int, default=20)
    ap.add_argument("--listen-s", type=float, default=2.5)
    args = ap.parse_args()

    key = hashlib.sha256(args.passphrase.encode("utf-8")).digest()
    other = hashlib.sha256(b"not the key").digest()
    conn = mavutil.mavlink_connection(f"udpout:{args.to}", source_system=1, source_component=1,
                                      dialect="ardupilotmega")
    conn.setup_signing(key, sign_outgoing=True, allow_unsigned_callback=lambda mav, msg_id: False)
    mav = conn.mav
    sent = defaultdict(int)
    signed_positions = 0
    replay = []
    boot_ms = [1000]

    def position():
        boot_ms[0] += 50
        return mav.global_position_int_encode(boot_ms[0], -353632610, 1491652300, 600000, 16000, 0, 0, 0, 0)

    def heartbeat():
        return mav.heartbeat_encode(mavutil.mavlink.MAV_TYPE_QUADROTOR,
                                    mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0,
                                    mavutil.mavlink.MAV_STATE_ACTIVE)

    def signed_burst():
        nonlocal signed_positions
        for i in range(args.per_kind):
            m = heartbeat() if i % 5 == 0 else position()
            mav.send(m)
            if m.get_type() == "GLOBAL_POSITION_INT":
                signed_positions += 1
            replay.append(bytes(m.get_msgbuf()))
            sent["signed"] += 1
            time.sleep(0.005)

    signed_burst()
    mav.signing.sign_outgoing = False
    for _ in range(args.per_kind):
        mav.send(position())
        sent["unsigned"] += 1
    mav.signing.sign_outgoing = True
    mav.signing.secret_key = other
    for _ in range(args.per_kind):
        mav.send(position())
        sent["wrong_key"] += 1
    mav.signing.secret_key = key
    for buf in replay[: args.per_kind]:
        conn.write(buf)
        sent["replayed"] += 1
    # A new stream (component 2) two minutes behind the newest timestamp.
    now_ts = mav.signing.timestamp
    mav.srcComponent = 2
    mav.signing.timestamp = now_ts - 120 * 100 * 1000
    for _ in range(args.per_kind):
        mav.send(position())
        sent["stale"] += 1
    mav.srcComponent = 1
    mav.signing.timestamp = max(mav.signing.timestamp, now_ts) + 1
    signed_burst()

    # What savsim sends back, judged by pymavlink's signing.
    types = defaultdict(int)
    good = bad = unsigned = 0
    end = time.time() + args.listen_s
    next_hb = 0.0
    while time.time() < end:
        if time.time() >= next_hb:
            next_hb = time.time() + 0.5
            mav.send(heartbeat())
            sent["signed"] += 1
        before = (mav.signing.goodsig_count, mav.signing.badsig_count, mav.signing.reject_count)
        m = conn.recv_match(blocking=True, timeout=0.05)
        after = (mav.signing.goodsig_count, mav.signing.badsig_count, mav.signing.reject_count)
        good += after[0] - before[0]
        bad += after[1] - before[1]
        unsigned += max(0, (after[2] - before[2]) - (after[1] - before[1]))
        if m is not None and m.get_type() != "BAD_DATA":
            types[f"{m.get_srcSystem()}/{m.get_srcComponent()} {m.get_type()}"] += 1
    print(json.dumps({
        "sent": dict(sent),
        "signed_positions": signed_positions,
        "from_savsim": {"good": good, "bad": bad, "unsigned": unsigned, "types": dict(types)},
    }), flush=True)


if __name__ == "__main__":
    main()
