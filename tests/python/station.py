#!/usr/bin/env python3
"""A ground station played by pymavlink (independent of savsim), for `--forward` tests.

Listens on UDP (prints `PORT n` first, so that savsim can be pointed at it with
`--forward udpout:127.0.0.1:n`), or connects wherever --connect says. Sends its heartbeat at
1 Hz as 255/190 (QGroundControl's identity). Once the vehicle (--target) is heard it asks, in
turn and until each is answered: a parameter (PARAM_REQUEST_READ), a mode (MAV_CMD_DO_SET_MODE,
checked in the vehicle's heartbeat), and arming (MAV_CMD_COMPONENT_ARM_DISARM, forced with
21196 when --force-arm; checked in the heartbeat's armed flag). Counts every message it
receives per sender and type; with --signing-passphrase it signs what it sends.

Prints one JSON object at the end: counts {"sysid/compid": {"TYPE": n}}, param (its value),
mode_set, armed, acks {command: result}. Until then, once a second, `POSITIONS n`: the
GLOBAL_POSITION_INT heard from the target so far, followed by `DONE` once the parameter was
read, the mode seen and the vehicle seen armed (those asked for). SIGTERM ends the run early: it reads what is
still arriving for --drain-s more, then prints its JSON and exits 0.

usage: station.py [--connect URL] --target 1 --param SYSID_THISMAV --mode 4 --run-s 6
"""
import argparse
import hashlib
import json
import os
import signal
import sys
import time
from collections import defaultdict

os.environ["MAVLINK20"] = "1"  # before pymavlink loads: MAVLink 2 (signing needs it)
from pymavlink import mavutil  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", default="udpin:127.0.0.1:0")
    ap.add_argument("--target", type=int, default=1)
    ap.add_argument("--param", default="SYSID_THISMAV")
    ap.add_argument("--mode", type=int, default=None, help="custom mode to set")
    ap.add_argument("--arm", action="store_true")
    ap.add_argument("--force-arm", action="store_true")
    ap.add_argument("--run-s", type=float, default=6.0)
    ap.add_argument("--until-done", action="store_true", help="stop once everything was answered")
    ap.add_argument("--signing-passphrase", default=None)
    ap.add_argument("--drain-s", type=float, default=1.0, help="read on this long after SIGTERM")
    args = ap.parse_args()
    stop = {"at": None}
    signal.signal(signal.SIGTERM, lambda *_: stop.__setitem__("at", stop["at"] or time.time()))

    conn = mavutil.mavlink_connection(args.connect, source_system=255, source_component=190,
                                      dialect="ardupilotmega")
    if args.connect.startswith("udpin:"):
        print(f"PORT {conn.port.getsockname()[1]}", flush=True)
    else:
        print("PORT 0", flush=True)
    if args.signing_passphrase is not None:
        key = hashlib.sha256(args.signing_passphrase.encode("utf-8")).digest()
        conn.setup_signing(key, sign_outgoing=True)
    mav = conn.mav

    counts = defaultdict(lambda: defaultdict(int))
    param_value = None
    acks = {}
    mode_seen = False
    armed_seen = False
    heard = False
    next_hb = 0.0
    next_ask = 0.0
    start = time.time()
    next_progress = 0.0
    while time.time() - start < args.run_s:
        now = time.time()
        if stop["at"] is not None and now - stop["at"] >= args.drain_s:
            break
        done = param_value is not None and (args.mode is None or mode_seen) and (not args.arm or armed_seen)
        if now >= next_progress:
            next_progress = now + 1.0
            heard_target = counts.get(f"{args.target}/1", {})
            positions = heard_target.get('GLOBAL_POSITION_INT', 0)
            print(f"POSITIONS {positions}{' DONE' if done else ''}", flush=True)
        if now >= next_hb:
            next_hb = now + 1.0
            mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        if heard and now >= next_ask:
            next_ask = now + 0.5
            if param_value is None:
                mav.param_request_read_send(args.target, 1, args.param.encode(), -1)
            elif args.mode is not None and not mode_seen:
                mav.command_long_send(args.target, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE, 0,
                                      mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                      args.mode, 0, 0, 0, 0, 0)
            elif args.arm and not armed_seen:
                mav.command_long_send(args.target, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                      1, 21196 if args.force_arm else 0, 0, 0, 0, 0, 0)
        if args.until_done and done:
            break
        m = conn.recv_match(blocking=True, timeout=0.05)
        if m is None:
            continue
        if m.get_type() == "BAD_DATA":
            counts["bad"]["BAD_DATA"] += 1
            continue
        src = (m.get_srcSystem(), m.get_srcComponent())
        counts[f"{src[0]}/{src[1]}"][m.get_type()] += 1
        if src[0] != args.target:
            continue
        heard = True
        t = m.get_type()
        if t == "PARAM_VALUE" and m.param_id == args.param:
            param_value = m.param_value
        elif t == "COMMAND_ACK":
            acks[str(m.command)] = m.result
        elif t == "HEARTBEAT" and src[1] == 1:
            if args.mode is not None and m.custom_mode == args.mode:
                mode_seen = True
            if m.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                armed_seen = True
    print(json.dumps({
        "counts": {k: dict(v) for k, v in counts.items()},
        "param": param_value,
        "mode_set": mode_seen,
        "armed": armed_seen,
        "acks": acks,
    }), flush=True)


if __name__ == "__main__":
    sys.exit(main())
