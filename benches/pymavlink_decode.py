"""Decode a tlog with pymavlink as fast as it goes; print messages, bytes and seconds as JSON.

usage: python3 pymavlink_decode.py FILE.tlog [REPEATS]
"""
import json
import os
import sys
import time

from pymavlink import mavutil

path = sys.argv[1]
repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 1
messages = 0
start = time.perf_counter()
for _ in range(repeats):
    m = mavutil.mavlink_connection(path, dialect="ardupilotmega")
    while True:
        msg = m.recv_msg()
        if msg is None:
            break
        if msg.get_type() != "BAD_DATA":
            messages += 1
seconds = time.perf_counter() - start
print(json.dumps({"messages": messages, "bytes": os.path.getsize(path) * repeats, "seconds": seconds}))
