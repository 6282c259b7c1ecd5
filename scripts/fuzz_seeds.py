#!/usr/bin/env python3
"""Write the fuzz targets' seed corpora (fuzz/corpus/<target>/) from the bundled demo flight
(and, for osm_reader and flight_logs, from ../shared/fixtures/realdata when it is there).

Run from the repository root: python3 scripts/fuzz_seeds.py
"""
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FUZZ = ROOT / "fuzz"
TLOG = (ROOT / "scenes/flights/copter_square_10ms.tlog").read_bytes()


def frames(tlog: bytes, most: int) -> list[bytes]:
    """The MAVLink frames of a tlog (each record: 8-byte timestamp, then one frame)."""
    out, p = [], 0
    while p + 8 < len(tlog) and len(out) < most:
        q = p + 8
        if tlog[q] == 0xFD:  # v2: 10-byte header, payload, 2-byte CRC, 13-byte signature if signed
            n = tlog[q + 1] + 12 + (13 if tlog[q + 2] & 1 else 0)
        elif tlog[q] == 0xFE:  # v1: 6-byte header, payload, 2-byte CRC
            n = tlog[q + 1] + 8
        else:
            break
        out.append(tlog[q:q + n])
        p = q + n
    return out


def write(target: str, name: str, data: bytes) -> None:
    directory = FUZZ / "corpus" / target
    directory.mkdir(parents=True, exist_ok=True)
    (directory / name).write_bytes(data)


for i in range(0, min(len(TLOG), 4096 * 40), 4096):
    write("tlog_reader", f"seed{i // 4096:03d}", TLOG[i:i + 4096])
blob = b"".join(frames(TLOG, 400))
# datagram_decode: the first byte sets the datagram (and TCP read) size.
write("datagram_decode", "seed0", bytes([40]) + blob[:2048])
write("datagram_decode", "seed1", bytes([255]) + blob[2048:4096])
# live_links: per chunk (who, time step, length, bytes); alternate links and UDP senders.
chunks = bytearray()
for i, f in enumerate(frames(TLOG, 120)):
    chunks += bytes([(i % 2) << 7 | (i % 4), 5, len(f)]) + f
write("live_links", "seed0", bytes(chunks))
# feed: a byte choosing the kinds and rate, then 4 KiB of the tlog (the flight, not its start).
for k, i in enumerate(range(4096 * 40, min(len(TLOG), 4096 * 56), 4096)):
    write("feed", f"seed{k:03d}", bytes([k % 16]) + TLOG[i:i + 4096])
write("scene_parser", "seed0", (FUZZ / "scene.toml").read_bytes().split(b"[[terrain]]")[0])
# daa_files: a small configuration, a NUL, the first 60 lines of each of savsim's scenarios.
CONF = (b"lookahead_time = 180 [s]\nalerting_m = 2\nalerting_n = 4\nhysteresis_time = 5 [s]\n"
        b"persistence_time = 4 [s]\nalerters = A\nA_alert_1_detector = d\n"
        b"A_alert_1_alerting_time = 55 [s]\nA_alert_1_early_alerting_time = 75 [s]\n"
        b"A_d_WCV_DTHR = 0.66 [nmi]\nA_d_WCV_ZTHR = 450 [ft]\nA_d_WCV_TTHR = 35 [s]\n"
        b"A_d_WCV_TCOA = 0 [s]\nA_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD\n")
for k, daa in enumerate(sorted((ROOT / "tests" / "fixtures" / "daa").glob("*.daa"))):
    head = b"\n".join(daa.read_bytes().split(b"\n")[:60])
    write("daa_files", f"seed{k:03d}", CONF + b"\0" + head)
# osm_reader and flight_logs: the heads of ../shared/fixtures/realdata's files, where present.
REALDATA = ROOT.parent / "shared" / "fixtures" / "realdata"
for path in sorted((REALDATA / "osm").glob("*.osm*")) if REALDATA.is_dir() else []:
    if not path.name.endswith(".ref.json"):
        write("osm_reader", path.name, path.read_bytes()[:8000])
for kind, pattern in [("ulog", "*.ulg"), ("dataflash", "*.bin")]:
    for path in sorted((REALDATA / kind).glob(pattern)) if REALDATA.is_dir() else []:
        write("flight_logs", path.name, path.read_bytes()[:16384])
print("seeds written under", FUZZ / "corpus")
