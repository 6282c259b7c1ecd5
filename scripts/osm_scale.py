"""OpenStreetMap scenes at scale: a generated extract of N buildings on a grid, every K-th
with a `building:part` over its north-east quarter, read by `savsim scene info` (timed), which
must report the parts' outlines kept where the parts leave them.

    cargo build --release && python3 scripts/osm_scale.py [--buildings 100000] [--every 10]

Prints the buildings, the outlines kept in part, and the wall time of `scene info`.
"""

import argparse
import os
import re
import subprocess
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("SAVSIM_BIN") or os.path.join(ROOT, "target", "release", "savsim")
M_PER_DEG = 111_320.0


def extract(path, n, every):
    """n 20 m square buildings 40 m apart around (0, 0); every `every`-th has a part over its
    north-east quarter."""
    side = int(n ** 0.5) + 1
    d = 10.0 / M_PER_DEG
    node = 0
    with open(path, "w") as f:
        f.write('<osm version="0.6">\n')
        ways = []
        for k in range(n):
            cx = (k % side) * 40.0 / M_PER_DEG
            cy = (k // side) * 40.0 / M_PER_DEG
            corners = [(cx - d, cy - d), (cx + d, cy - d), (cx + d, cy + d), (cx - d, cy + d)]
            ids = []
            for lon, lat in corners:
                node += 1
                f.write(f'<node id="{node}" lat="{lat:.9f}" lon="{lon:.9f}"/>\n')
                ids.append(node)
            ways.append((ids, 'k="building" v="yes"/><tag k="height" v="20"'))
            if k % every == 0:
                quarter = [(cx, cy), (cx + d, cy), (cx + d, cy + d), (cx, cy + d)]
                qids = []
                for lon, lat in quarter:
                    node += 1
                    f.write(f'<node id="{node}" lat="{lat:.9f}" lon="{lon:.9f}"/>\n')
                    qids.append(node)
                ways.append((qids, 'k="building:part" v="yes"/><tag k="height" v="8"'))
        for w, (ids, tags) in enumerate(ways, start=1):
            nds = "".join(f'<nd ref="{i}"/>' for i in ids + ids[:1])
            f.write(f'<way id="{w}">{nds}<tag {tags}/></way>\n')
        f.write("</osm>\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--buildings", type=int, default=100_000)
    ap.add_argument("--every", type=int, default=10)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as dir:
        osm = os.path.join(dir, "extract.osm")
        extract(osm, args.buildings, args.every)
        scene = os.path.join(dir, "scene.toml")
        with open(scene, "w") as f:
            f.write('[origin]\nlat_deg = 0\nlon_deg = 0\nalt_m = 0\n\n'
                    '[[osm]]\nid = "osm"\nfile = "extract.osm"\n')
        started = time.monotonic()
        out = subprocess.run([BIN, "scene", "info", scene], check=True,
                             capture_output=True, text=True).stdout
        wall = time.monotonic() - started
        line = next(l for l in out.splitlines() if l.strip().startswith("osm "))
        kept = int(re.search(r"(\d+) kept where their parts leave them", line).group(1))
        parts = (args.buildings + args.every - 1) // args.every
        print(f"{args.buildings} buildings, {parts} parts, {os.path.getsize(osm) / 1e6:.0f} MB of XML")
        print(line.strip())
        print(f"scene info: {wall:.2f} s")
        assert kept == parts, f"{kept} outlines kept in part, expected {parts}"


if __name__ == "__main__":
    main()
