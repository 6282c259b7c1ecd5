"""Write ULog files under 1 KiB built to explode a reader that trusts their formats: an array of
10^8 bytes, a count of 2^64 - 1, and nested arrays of 255 x 255 x 255 uint64 (133 MB a
sample if flattened), each the format of a topic savsim reads (vehicle_global_position,
vehicle_attitude), with one subscription and one data message.

    python3 scripts/crafted_ulog.py OUT_DIR
    /usr/bin/time -v savsim replay OUT_DIR/nested.ulg     # a clear error (exit 2), at once
"""
import os
import struct
import sys

MAGIC = b"ULog\x01\x12\x35"


def ulog(formats, topic):
    out = MAGIC + b"\x01" + struct.pack("<Q", 0)
    msgs = [(b"F", f.encode()) for f in formats]
    msgs.append((b"A", b"\x00\x00\x00" + topic.encode()))
    msgs.append((b"D", b"\x00\x00" + b"\x00" * 16))
    for kind, payload in msgs:
        out += struct.pack("<H", len(payload)) + kind + payload
    return out


def main(out):
    os.makedirs(out, exist_ok=True)
    files = {
        "huge_array.ulg": ulog(["vehicle_global_position:uint64_t timestamp;uint8_t[100000000] x;"], "vehicle_global_position"),
        "endless_count.ulg": ulog(["vehicle_global_position:uint64_t timestamp;uint8_t[18446744073709551615] x;"], "vehicle_global_position"),
        "nested.ulg": ulog(["vehicle_attitude:uint64_t timestamp;b[255] x;", "b:c[255] y;", "c:uint64_t[255] z;"], "vehicle_attitude"),
    }
    for name, data in files.items():
        assert len(data) < 1024
        with open(os.path.join(out, name), "wb") as f:
            f.write(data)
        print(name, len(data), "bytes")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
