"""What the rerun logger costs: `savsim demo` with and without `--rerun save=...`, run in
interleaved pairs (so that a noisy machine's load falls on both alike), medians and the spread
of the per-pair ratio (docs/performance.md).

usage: python3 scripts/logger_overhead.py [PAIRS]   (from the repository, after cargo build --release)
"""
import subprocess, time, statistics, sys
cmds = [["./target/release/savsim","demo"], ["./target/release/savsim","demo","--rerun","save=/tmp/savsim_logger_overhead.rrd"]]
n = int(sys.argv[1]) if len(sys.argv) > 1 else 30
t = [[], []]
for i in range(n + 3):
    for k in (0, 1) if i % 2 == 0 else (1, 0):
        s = time.perf_counter()
        subprocess.run(cmds[k], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        if i >= 3:
            t[k].append(time.perf_counter() - s)
m = [statistics.median(x) * 1000 for x in t]
r = sorted(b / a for a, b in zip(t[0], t[1]))
mn = [min(x) * 1000 for x in t]
print(f"pairs {n}: median without {m[0]:.1f} ms, with {m[1]:.1f} ms, ratio of medians {m[1]/m[0]:.2f}; per-pair ratio median {statistics.median(r):.2f}, quartiles {r[len(r)//4]:.2f}-{r[3*len(r)//4]:.2f}; fastest {mn[0]:.1f} vs {mn[1]:.1f} ms ({mn[1]/mn[0]:.2f})")
