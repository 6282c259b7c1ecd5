"""A depth-image avoidance for savsim's companion interface: a vector field histogram (Borenstein
and Koren, 1991) over the columns of a forward depth camera (the ``depth-160x120`` preset).

At each frame: the plan's velocity (``intent_enu_mps``) is where the vehicle wants to go. Each
image column is an azimuth; a column is blocked when anything in it (within +-20 degrees of the
camera's horizon) is nearer than the stopping distance at the wanted speed plus a margin, and
blocked columns are widened by the vehicle's radius at their range. The vehicle flies the free
azimuth nearest the wanted direction, facing it (the camera looks where it goes), at the wanted
speed, slower when the way is narrow; with no free column within the image, it stops and turns
towards the wanted direction; when the wanted direction is outside the image, it turns to see
it before going.

On ArduCopter it flies in GUIDED, where the row's pilot put it for the takeoff. On PX4 (the
``hello`` names the autopilot) it asks for OFFBOARD with its first setpoints and again once a
second while it flies (PX4 takes OFFBOARD only while setpoints come).

Run by savsim (a study row's ``companion`` column)::

    companion = python3 examples/companion_vfh.py

The camera's pose is taken from the capture (savsim's truth of where the camera looked); a real
companion would take it from the autopilot's attitude. Needs numpy and the savsim package's
client (``pip install ./python``); from a checkout it falls back to python/savsim/companion.py.
"""

import math
import os
import sys
import time

import numpy as np

try:
    from savsim.companion import Companion, mode, velocity
except ImportError:  # a checkout without the package installed
    import importlib.util

    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location(
        "companion", os.path.join(here, "..", "python", "savsim", "companion.py"))
    _m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(_m)
    Companion, mode, velocity = _m.Companion, _m.mode, _m.velocity

CAMERA = os.environ.get("VFH_CAMERA", "depth-160x120")
RADIUS_M = 0.6          # the vehicle's radius and a little more
DECEL_MPS2 = 2.0        # what it can brake at
MARGIN_M = 2.0          # kept beyond the stopping distance
BAND_DEG = 20.0         # rows within this of the camera's horizon are looked at
TURN_ONLY_DEG = 35.0    # a wanted direction further off the camera's axis: turn first
# Wall time to spend on each frame (a slower planner; in a lockstep row it changes nothing).
SLEEP_S = float(os.environ.get("VFH_SLEEP_S", "0"))


def heading_deg(v):
    """Clockwise from north, of an ENU vector."""
    return math.degrees(math.atan2(v[0], v[1])) % 360.0


def wrap(a):
    return (a + 180.0) % 360.0 - 180.0


def camera_heading_deg(capture):
    """Where the camera's axis points, clockwise from north (its x axis in ENU)."""
    x, y, z, w = capture["enu_from_device_xyzw"]
    # The rotated x axis: first column of the rotation matrix.
    fx = 1 - 2 * (y * y + z * z)
    fy = 2 * (x * y + w * z)
    return heading_deg((fx, fy))


class Vfh:
    def __init__(self):
        self.azimuth = None

    def columns(self, depth, fov_deg):
        """Each column's azimuth (deg, right of the axis) and its nearest range in the band."""
        h, w = depth.shape
        fx = w / 2 / math.tan(math.radians(fov_deg[0]) / 2)
        fy = h / 2 / math.tan(math.radians(fov_deg[1]) / 2)
        if self.azimuth is None:
            u = np.arange(w) + 0.5 - w / 2
            v = np.arange(h) + 0.5 - h / 2
            self.azimuth = np.degrees(np.arctan(u / fx))
            elevation = np.degrees(np.arctan(v / fy))
            self.rows = np.abs(elevation) <= BAND_DEG
            # Range along a pixel's ray from its depth: depth * |(1, u/fx, v/fy)|.
            self.stretch = np.sqrt(1 + (u[None, :] / fx) ** 2 + (v[:, None] / fy) ** 2)
        band = depth[self.rows]
        ranges = np.where(np.isfinite(band), band, np.inf) * self.stretch[self.rows]
        return self.azimuth, ranges.min(axis=0)

    def plan(self, frame):
        if SLEEP_S > 0:
            time.sleep(SLEEP_S)
        want = frame.intent_enu_mps
        image = next((c for c in frame.captures if c["device"] == CAMERA), None)
        if want is None or image is None:
            return []
        speed = math.hypot(want[0], want[1])
        if speed < 0.1:
            return [velocity([0.0, 0.0, want[2]])]
        wanted = heading_deg(want)
        facing = camera_heading_deg(image)
        off = wrap(wanted - facing)
        if abs(off) > TURN_ONLY_DEG:
            return [velocity([0.0, 0.0, 0.0], yaw_deg=wanted)]
        azimuth, nearest = self.columns(image["arrays"]["depth_m"], image["fov_deg"])
        reach = speed * speed / (2 * DECEL_MPS2) + MARGIN_M
        blocked = nearest < reach
        # Widen each blocked column by the vehicle's radius at its range.
        for i in np.flatnonzero(blocked):
            half = math.degrees(math.atan2(RADIUS_M, max(nearest[i], 0.1)))
            blocked |= np.abs(azimuth - azimuth[i]) <= half
        free = np.flatnonzero(~blocked)
        if free.size == 0:
            return [velocity([0.0, 0.0, 0.0], yaw_deg=wanted)]
        best = free[np.argmin(np.abs(azimuth[free] - off))]
        go = (facing + azimuth[best]) % 360.0
        # Slower when the chosen way is far from the wanted one or near an obstacle.
        turn = abs(wrap(go - wanted))
        scale = max(0.3, math.cos(math.radians(min(turn, 80.0))))
        if np.isfinite(nearest[best]):
            scale = min(scale, max(0.3, nearest[best] / (reach + 4.0)))
        v = speed * scale
        east, north = v * math.sin(math.radians(go)), v * math.cos(math.radians(go))
        return [velocity([east, north, want[2]], yaw_deg=go)]


def main():
    vfh = Vfh()
    link = Companion()
    if link.hello.get("autopilot") != "px4":
        link.run(vfh.plan)
        return
    every = max(1, round(link.hello.get("hz", 10.0)))
    flying = 0

    def plan_offboard(frame):
        nonlocal flying
        commands = vfh.plan(frame)
        if not commands:
            flying = 0
            return commands
        flying += 1
        if flying % every == 1 or every == 1:
            commands.append(mode("OFFBOARD"))
        return commands

    link.run(plan_offboard)


if __name__ == "__main__":
    sys.exit(main())
