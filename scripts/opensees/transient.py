#!/usr/bin/env python3
"""OpenSees's own transient analysis of a model under a ground motion, for comparison with rths.

    python3 transient.py MODEL.py --record AG.txt --dt DT --dofs NODE:DOF[,NODE:DOF...] --out OUT.csv
                         [--direction 1]

MODEL.py is built as `export_model.py` builds it (run as `rths_export`, its directory on
`sys.path`). AG.txt holds the ground acceleration, one value per line in the model's units,
sample k at time k*DT. The analysis is Newmark's average acceleration (gamma 1/2, beta 1/4) at
DT with a linear algorithm factorizing once (`Linear -factorOnce`, a `BandSPD` system, RCM
numbering), a `UniformExcitation` in `--direction`, the model's own damping; the model starts at
rest. OUT.csv gets `time_s` and one column `NODE_DOF` of displacements per DOF, a row per sample
(row 0: rest). stdout gets one JSON line: steps, seconds in `analyze`, seconds per step.
"""

import argparse
import json
import os
import runpy
import sys
import time

# Tags for the record's series and pattern, away from a lab's own.
SERIES_TAG = 987001
PATTERN_TAG = 987001


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--record", required=True)
    p.add_argument("--dt", type=float, required=True)
    p.add_argument("--dofs", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--direction", type=int, default=1)
    args = p.parse_args()

    import openseespy.opensees as ops

    model = os.path.abspath(args.model)
    sys.path.insert(0, os.path.dirname(model))
    runpy.run_path(model, run_name="rths_export")

    with open(args.record, encoding="ascii") as f:
        ag = [float(line) for line in f if line.strip()]
    dofs = []
    for item in args.dofs.split(","):
        node, dof = item.split(":")
        dofs.append((int(node), int(dof)))

    ops.timeSeries("Path", SERIES_TAG, "-dt", args.dt, "-values", *ag)
    ops.pattern("UniformExcitation", PATTERN_TAG, args.direction, "-accel", SERIES_TAG)
    ops.wipeAnalysis()
    ops.system("BandSPD")
    ops.numberer("RCM")
    ops.constraints("Transformation")
    ops.algorithm("Linear", "-factorOnce")
    ops.integrator("Newmark", 0.5, 0.25)
    ops.analysis("Transient")

    rows = [[0.0] + [0.0] * len(dofs)]
    spent = 0.0
    for k in range(1, len(ag)):
        t0 = time.perf_counter()
        ok = ops.analyze(1, args.dt)
        spent += time.perf_counter() - t0
        if ok != 0:
            print(f"transient.py: analysis failed at step {k}", file=sys.stderr)
            sys.exit(2)
        rows.append([k * args.dt] + [ops.nodeDisp(n, d) for n, d in dofs])

    with open(args.out, "w", encoding="ascii") as f:
        f.write(",".join(["time_s"] + [f"{n}_{d}" for n, d in dofs]) + "\n")
        for r in rows:
            f.write(",".join(f"{v:.17g}" for v in r) + "\n")
    steps = len(ag) - 1
    print(json.dumps({"steps": steps, "analyze_s": spent,
                      "per_step_s": spent / steps if steps else 0.0}))


if __name__ == "__main__":
    main()
