"""Turn `savsim study gen --kind approaches` into the companion study of docs/companion.md:
each approach flown in lockstep (physics = savsim) three ways, all with the same camera
(`depth-160x120`) where one is carried:

- nominal: no avoidance (AVOID_ENABLE=0), no camera;
- ac-avoid: ArduCopter's own avoidance (AC_Avoid, the study's mitigated parameters) fed by the
  camera through savsim's proximity feed;
- companion: the planner of examples/companion_vfh.py flying in GUIDED from the camera, the
  autopilot's avoidance off.

    python3 scripts/companion_study.py gen/study.csv > companion.csv
    savsim study companion.csv --out results --jobs 2
"""

import csv
import sys

CAMERA = "depth-160x120"
PLANNER = "python3 examples/companion_vfh.py"


def main(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    extra = ["companion", "companion_hz", "companion_latency_s"]
    fields = list(rows[0].keys()) + [c for c in extra if c not in rows[0]]
    out = csv.DictWriter(sys.stdout, fieldnames=fields, lineterminator="\n")
    out.writeheader()
    by_pair = {}
    for r in rows:
        by_pair.setdefault(r["pair"], {})[r["variant"]] = r
    for pair, variants in by_pair.items():
        nominal, mitigated = variants["nominal"], variants["mitigated"]
        for name, params, sensors, companion in [
            ("nominal", "AVOID_ENABLE=0", "", ""),
            ("ac-avoid", mitigated["params"], CAMERA, ""),
            ("companion", "AVOID_ENABLE=0", CAMERA, PLANNER),
        ]:
            row = dict(nominal)
            row.update({
                "id": "%s-%s" % (pair, name),
                "variant": name,
                "params": params,
                "feed": "proximity" if sensors else "",
                "sensors": sensors,
                "physics": "savsim",
                "companion": companion,
                "companion_hz": "10" if companion else "",
                "companion_latency_s": "0.05" if companion else "",
            })
            out.writerow(row)


if __name__ == "__main__":
    main(sys.argv[1])
