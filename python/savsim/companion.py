"""The planner's side of savsim's companion protocol (docs/companion.md).

savsim starts your planner with ``SAVSIM_COMPANION=host:port`` set; the planner connects, and
at each of its instants is handed a :class:`Frame` (the vehicle's state, its images and point
clouds as numpy arrays, the traffic it was told) and answers with commands::

    from savsim.companion import Companion, velocity

    def plan(frame):
        depth = frame.images()["depth-160x120"]["depth_m"]   # (120, 160) float32, metres
        ...
        return [velocity([1.0, 0.0, 0.0], yaw_deg=90.0)]

    Companion().run(plan)

Every message is a 4-byte little-endian length, a JSON header of that length, and the binary
payload its ``payload_bytes`` counts. A frame's payload is read from the socket once, into one
buffer; its arrays are numpy views of that buffer (no copy).
"""

import json
import os
import socket
import struct

import numpy as np

__all__ = ["Companion", "Frame", "velocity", "mode", "mavlink"]


def velocity(enu_mps, yaw_deg=None):
    """Fly this velocity (east, north, up; m/s), facing ``yaw_deg`` (clockwise from north)."""
    command = {"velocity_enu_mps": [float(v) for v in enu_mps]}
    if yaw_deg is not None:
        command["yaw_deg"] = float(yaw_deg)
    return command


def mode(name):
    """Change to the autopilot's flight mode ``name`` (``GUIDED``, ``LAND``, ``OFFBOARD``...)."""
    return {"mode": str(name)}


def mavlink(frame_bytes):
    """Send these bytes as they are: one or more whole MAVLink frames (pymavlink's
    ``msg.pack(mav)``, for instance)."""
    return {"mavlink": bytes(frame_bytes)}


class Frame:
    """What the planner is handed at one instant.

    ``seq``, ``t_s`` (the vehicle's clock), ``truth`` (position, velocity, attitude: the truth,
    for scoring, not what a real planner would know), ``estimate`` (the autopilot's own
    position estimate and its age, or None), ``intent_enu_mps`` (what the row's plan asks now,
    or None), ``traffic`` (ADS-B reports sent since the last frame) and ``captures`` (each
    device's newest reading: a dict with ``device``, ``kind`` (``depth`` or ``points``),
    ``instant_s``, ``origin_enu_m``, ``enu_from_device_xyzw``, ``fov_deg`` for images, and
    ``arrays``: name -> numpy array).
    """

    def __init__(self, header, payload):
        self.header = header
        self.seq = header["seq"]
        self.t_s = header["t_s"]
        self.truth = header["truth"]
        self.estimate = header.get("estimate")
        self.intent_enu_mps = header.get("intent_enu_mps")
        self.traffic = header.get("traffic", [])
        self.captures = []
        for c in header.get("captures", []):
            arrays = {}
            for a in c["arrays"]:
                view = np.frombuffer(payload, dtype=np.dtype(a["dtype"]), count=_count(a), offset=a["offset"])
                arrays[a["name"]] = view.reshape(a["shape"])
            capture = {k: v for k, v in c.items() if k not in ("arrays", "extra")}
            capture.update(c.get("extra", {}))
            capture["arrays"] = arrays
            self.captures.append(capture)

    def images(self):
        """Each depth camera's arrays by device: ``depth_m`` (float32, NaN no reading, inf
        nothing in range), ``segment_id`` (uint32), ``class`` (uint8), rows from the top."""
        return {c["device"]: c["arrays"] for c in self.captures if c["kind"] == "depth"}

    def clouds(self):
        """Each lidar's arrays by device: ``points_m`` (n x 3 float32, the device's frame: x
        forward, y right, z down), ``segment_id``, ``class``."""
        return {c["device"]: c["arrays"] for c in self.captures if c["kind"] == "points"}


def _count(a):
    n = 1
    for s in a["shape"]:
        n *= s
    return n


class Companion:
    """A planner's link to savsim: ``address`` is ``host:port`` (default: the
    ``SAVSIM_COMPANION`` savsim set)."""

    def __init__(self, address=None):
        address = address or os.environ.get("SAVSIM_COMPANION")
        if not address:
            raise RuntimeError("SAVSIM_COMPANION is not set: savsim starts the planner with it")
        host, port = address.rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.hello, _ = self._receive()
        if self.hello.get("type") != "hello":
            raise RuntimeError("savsim did not greet: %r" % (self.hello,))

    def _exactly(self, n):
        buffer = bytearray(n)
        view = memoryview(buffer)
        got = 0
        while got < n:
            k = self.sock.recv_into(view[got:], n - got)
            if k == 0:
                raise EOFError("savsim closed the link")
            got += k
        return buffer

    def _receive(self):
        (length,) = struct.unpack("<I", self._exactly(4))
        header = json.loads(bytes(self._exactly(length)))
        payload = self._exactly(header.get("payload_bytes", 0))
        return header, payload

    def frames(self):
        """Each frame, until savsim ends the row."""
        while True:
            try:
                header, payload = self._receive()
            except (EOFError, ConnectionError):
                return
            if header.get("type") == "frame":
                yield Frame(header, payload)

    def reply(self, frame, commands=()):
        """Answer ``frame`` with ``commands`` (from :func:`velocity`, :func:`mode`,
        :func:`mavlink`)."""
        payload = bytearray()
        out = []
        for c in commands:
            if "mavlink" in c:
                raw = c["mavlink"]
                out.append({"mavlink": {"offset": len(payload), "bytes": len(raw)}})
                payload += raw
            else:
                out.append(c)
        header = json.dumps({"type": "commands", "seq": frame.seq, "commands": out,
                             "payload_bytes": len(payload)}).encode()
        self.sock.sendall(struct.pack("<I", len(header)) + header + bytes(payload))

    def run(self, plan):
        """Answer every frame with ``plan(frame)``'s commands until savsim ends the row."""
        for frame in self.frames():
            self.reply(frame, plan(frame) or ())
