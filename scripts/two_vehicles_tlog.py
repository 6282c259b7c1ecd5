"""Write a tlog of two copters crossing over the bundled city (scenes/city.toml) at 40 m, so
that they meet at the scene's origin 15 s in: a vehicle-vehicle collision to look at in rerun
(docs/rerun.md). Written with pymavlink, as a ground station would record it.

usage: python3 scripts/two_vehicles_tlog.py OUT.tlog
"""
import math
import struct
import sys

from pymavlink.dialects.v20 import ardupilotmega as mav2

ORIGIN_LAT, ORIGIN_LON, ORIGIN_ALT_M = -35.363261, 149.16523, 584.0  # scenes/city.toml
EARTH_R_M = 6378137.0
RATE_HZ = 10
SPEED_M_S = 8.0
ALTITUDE_M = 40.0
DURATION_S = 30.0


def lat_lon(east_m, north_m):
    """Small offsets from the scene's origin (good to centimetres over a few hundred metres)."""
    lat = ORIGIN_LAT + math.degrees(north_m / EARTH_R_M)
    lon = ORIGIN_LON + math.degrees(east_m / (EARTH_R_M * math.cos(math.radians(ORIGIN_LAT))))
    return int(lat * 1e7), int(lon * 1e7)


# (system id, start east/north, unit direction east/north)
vehicles = [
    (1, (-120.0, 0.0), (1.0, 0.0)),   # eastbound
    (2, (0.0, -120.0), (0.0, 1.0)),   # northbound
]
encoders = {sysid: mav2.MAVLink(None, srcSystem=sysid, srcComponent=1) for sysid, _, _ in vehicles}
t0_us = 1_700_000_000_000_000
records = []
for step in range(int(DURATION_S * RATE_HZ)):
    t_s = step / RATE_HZ
    boot_ms = 60_000 + int(t_s * 1000)
    for sysid, (e0, n0), (de, dn) in vehicles:
        m = encoders[sysid]
        e, n = e0 + de * SPEED_M_S * t_s, n0 + dn * SPEED_M_S * t_s
        lat, lon = lat_lon(e, n)
        yaw = math.atan2(de, dn)  # NED yaw: 0 north, pi/2 east
        t_us = t0_us + int(t_s * 1e6) + sysid * 1000
        frames = [
            m.global_position_int_encode(
                boot_ms, lat, lon, int((ORIGIN_ALT_M + ALTITUDE_M) * 1000), int(ALTITUDE_M * 1000),
                int(dn * SPEED_M_S * 100), int(de * SPEED_M_S * 100), 0,
                int(math.degrees(yaw) % 360 * 100)),
            m.attitude_encode(boot_ms, 0.0, 0.0, yaw, 0.0, 0.0, 0.0),
        ]
        if step % RATE_HZ == 0:
            frames.append(m.heartbeat_encode(2, 3, 0, 0, 4))  # quadrotor, ArduPilot
        for frame in frames:
            records.append(struct.pack(">Q", t_us) + bytes(frame.pack(m)))

with open(sys.argv[1], "wb") as f:
    f.write(b"".join(records))
