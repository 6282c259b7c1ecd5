"""A planner for savsim's companion tests, behaving as its first argument says:

- ``echo``: answers each frame with what it read (so the test checks the arrays arrived
  whole): a velocity of (the image's mean depth, depth at row 7 column 9, class at row 3
  column 4), facing the frame's number, and a mode change to GUIDED;
- ``crash``: says something and exits with status 3 at the first frame;
- ``hang``: never answers;
- ``garbage``: answers with bytes that are not the protocol;
- ``flood``: announces a header of 100 MB;
- ``many``: answers with 1000 commands;
- ``nan``: answers with a velocity of NaN;
- ``noop``: answers each frame with one velocity at once, touching its image (the round-trip
  bench);
- ``where``: answers each frame with a velocity of the vehicle's position as told (east,
  north, up, metres as m/s) and, with the first frame, a change to GUIDED when its hello
  named the ``wall`` clock;
- ``slow-where``: ``where``, after 300 ms of wall time on each frame.

The client is loaded from the source tree (python/savsim/companion.py), not an installed
package.
"""

import importlib.util
import math
import os
import struct
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location(
    "companion", os.path.join(here, "..", "..", "python", "savsim", "companion.py"))
companion = importlib.util.module_from_spec(spec)
spec.loader.exec_module(companion)

behaviour = sys.argv[1]
link = companion.Companion()
for frame in link.frames():
    if behaviour == "echo":
        image = frame.images()["cam"]
        depth, classes = image["depth_m"], image["class"]
        assert depth.shape == (120, 160) and depth.dtype.name == "float32", depth.shape
        assert not depth.flags.owndata, "a view of the payload, not a copy"
        v = [float(depth.mean()), float(depth[7, 9]), float(classes[3, 4])]
        link.reply(frame, [companion.velocity(v, yaw_deg=frame.seq), companion.mode("GUIDED")])
    elif behaviour == "crash":
        print("planner: giving up on frame", frame.seq, flush=True)
        sys.exit(3)
    elif behaviour == "hang":
        time.sleep(3600)
    elif behaviour == "garbage":
        link.sock.sendall(struct.pack("<I", 12) + b"not json at all")
    elif behaviour == "flood":
        link.sock.sendall(struct.pack("<I", 100_000_000) + b"x" * 65536)
    elif behaviour == "many":
        link.reply(frame, [companion.velocity([0, 0, 0])] * 1000)
    elif behaviour == "noop":
        depth = frame.images()["cam"]["depth_m"]
        link.reply(frame, [companion.velocity([float(depth[0, 0]), 0, 0])])
    elif behaviour in ("where", "slow-where"):
        if behaviour == "slow-where":
            time.sleep(0.3)
        commands = [companion.velocity(frame.truth["position_enu_m"])]
        if frame.seq == 0 and link.hello.get("clock") == "wall":
            commands.append(companion.mode("GUIDED"))
        link.reply(frame, commands)
    elif behaviour == "nan":
        link.reply(frame, [{"velocity_enu_mps": [math.nan, 0, 0]}])
