"""Autopilot-log reading speed, savsim against the readers people trust, on the same files
(docs/performance.md): `savsim replay FILE --mode none` (the whole process: start, read the
log into positions and attitudes, write nothing) against pyulog's `ULog(FILE)` for .ulg files
and pymavlink's `DFReader_binary` reading every message for .bin files, timed inside Python
(the interpreter's start and imports left out, in savsim's disfavour). Runs alternate; medians
of N runs each.

usage: python3 scripts/log_decode_bench.py [--runs N] FILE...   (after cargo build --release)
"""
import argparse
import statistics
import subprocess
import time


def peer_seconds(path):
    start = time.perf_counter()
    if path.lower().endswith(".ulg"):
        from pyulog import ULog
        ULog(path)
    else:
        from pymavlink import DFReader
        r = DFReader.DFReader_binary(path, zero_time_base=False)
        while r.recv_msg() is not None:
            pass
    return time.perf_counter() - start


def savsim_seconds(savsim, path):
    start = time.perf_counter()
    subprocess.run([savsim, "replay", path, "--mode", "none"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--savsim", default="./target/release/savsim")
    ap.add_argument("files", nargs="+")
    args = ap.parse_args()
    print("| file | MiB | peer | peer median | savsim median | peer / savsim |")
    print("|---|---|---|---|---|---|")
    for path in args.files:
        peer_seconds(path)  # imports and the page cache, once
        savsim_seconds(args.savsim, path)
        peer, ours = [], []
        for i in range(args.runs):
            pair = (lambda: peer.append(peer_seconds(path)),
                    lambda: ours.append(savsim_seconds(args.savsim, path)))
            for run in pair if i % 2 == 0 else pair[::-1]:
                run()
        p, s = statistics.median(peer), statistics.median(ours)
        name = "pyulog" if path.lower().endswith(".ulg") else "DFReader"
        size = __import__("os").path.getsize(path) / 2**20
        print(f"| {path.split('/')[-1]} | {size:.2f} | {name} | {p * 1000:.0f} ms | "
              f"{s * 1000:.1f} ms | {p / s:.1f}x |")


if __name__ == "__main__":
    main()
