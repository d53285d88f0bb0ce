#!/usr/bin/env python3
"""Training time histories of a (nonlinear) openseespy model for `rths train nonlinear --histories`.

    python3 write_histories.py MODEL.py --specimen NODE:DOF --specimen-element TAG
        --output NODE:DOF [--output ...] --record AT2 [--record ...] --scale S [--scale ...]
        --dt DT --out-dir DIR [--duration-s T] [--free-s F] [--units si|mm-kn] [--direction 1]
        [--recorders]

MODEL.py is built as `export_model.py` builds it (run as `rths_export`, its directory on
`sys.path`), with the specimen modelled by a numerical stand-in element `--specimen-element` (a
`zeroLength` or truss at `--specimen`). For every record (a PEER AT2 file, in g) and every scale
the model is rebuilt at rest and integrated by Newmark's average acceleration at DT (`--dt`, the
controller's step: 1/2048 s) with Newton iterations (`NormDispIncr` 1e-8, up to 50 iterations,
then Krylov-Newton and smaller steps if a step does not converge), over the first `--duration-s`
of the record (default: all of it) and `--free-s` of free vibration (default 5 s). The ground
motion enters as the nodal loads `-M*iota*ag(t)` (transient.py's `ground_loads`).

Writes DIR/RECORD-xSCALE.csv per run in rths's history layout (units mm, kN, mm/s^2):
`time_s,ground_accel_mm_s2,specimen_force_kn,interface_mm,out_<NODE>_<DOF>_mm...`; the specimen
force is the stand-in element's resisting force at the specimen node in the specimen's direction.
With `--recorders`, each run is written instead as a directory DIR/RECORD-xSCALE/ of OpenSees's
own recorder files at their default precision (6 significant digits), the layout `--histories`
also reads: `recorder Node ... disp` for the interface and each output, `recorder Element ...
basicForce` for the specimen's stand-in (its force in tension, which is the force at the specimen
node when that node is the element's second end; the script refuses the other order), and
`ground_accel.out` written by the script at the recorders' times (OpenSees records no ground
acceleration). The recorders write a row at time 0 and one per committed step, as the CSV has;
a step that needed sub-steps would write its sub-steps too: the reader then refuses the run naming
the line.
stdout gets one JSON line per run (file, steps, seconds, seconds per step, peak interface mm).
Exit codes: 0 done, 2 bad arguments or a model/analysis that fails, 3 openseespy missing.
"""

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from transient import (build_model, failer, ground_loads, parse_dof,  # noqa: E402 (after the path)
                       read_at2)

G_MM_S2 = 9806.65
SERIES_TAG = 987011
PATTERN_TAG = 987011


fail = failer("write_histories.py")


def resample(dt_in, values, dt_out, duration_s):
    """Linear interpolation of `values` (step dt_in) at step dt_out over duration_s."""
    n = int(round(duration_s / dt_out)) + 1
    out = []
    for k in range(n):
        x = k * dt_out / dt_in
        i = int(x)
        if i + 1 >= len(values):
            out.append(values[-1] if i < len(values) else 0.0)
        else:
            a = x - i
            out.append((1.0 - a) * values[i] + a * values[i + 1])
    return out


def attach_recorders(args, ops, folder, sn, sd, outs):
    """OpenSees's own recorders of one run into `folder` (the layout of `--histories`)."""
    os.makedirs(folder, exist_ok=True)
    ops.recorder("Node", "-file", os.path.join(folder, "interface_disp.out"), "-time",
                 "-node", sn, "-dof", sd, "disp")
    for n, d in outs:
        ops.recorder("Node", "-file", os.path.join(folder, f"out_{n}_{d}.out"), "-time",
                     "-node", n, "-dof", d, "disp")
    ops.recorder("Element", "-file", os.path.join(folder, "specimen_force.out"), "-time",
                 "-ele", args.specimen_element, "basicForce")


def run(args, ops, model, record, scale, outs, folder=None):
    build_model(model, fail)

    length_to_mm, force_to_kn = (1000.0, 1e-3) if args.units == "si" else (1.0, 1.0)
    dt_rec, ag_g = read_at2(record, fail)
    duration = args.duration_s if args.duration_s else (len(ag_g) - 1) * dt_rec
    duration = min(duration, (len(ag_g) - 1) * dt_rec)
    ag = resample(dt_rec, [scale * a * G_MM_S2 / length_to_mm for a in ag_g], args.dt, duration)
    ag += [0.0] * int(round(args.free_s / args.dt))
    sn, sd = parse_dof(args.specimen, fail)
    ends = ops.eleNodes(args.specimen_element)
    if sn not in ends:
        fail(2, f"element {args.specimen_element} does not end at node {sn}")
    ndf = len(ops.nodeDOFs(sn))
    slot = ends.index(sn) * ndf + sd - 1
    if folder is not None:
        if ends.index(sn) != 1:
            fail(2, f"--recorders: node {sn} must be element {args.specimen_element}'s second end "
                    "(basicForce is the force at that end)")
        attach_recorders(args, ops, folder, sn, sd, outs)

    ops.timeSeries("Path", SERIES_TAG, "-dt", args.dt, "-values", *ag)
    loads = ground_loads(ops, args.direction, fail)
    ops.pattern("Plain", PATTERN_TAG, SERIES_TAG)
    for node, values in loads:
        ops.load(node, *values)
    ops.wipeAnalysis()
    ops.system("BandGeneral")
    ops.numberer("RCM")
    ops.constraints("Transformation")
    ops.test("NormDispIncr", 1e-8, 50)
    ops.algorithm("Newton")
    ops.integrator("Newmark", 0.5, 0.25)
    ops.analysis("Transient")

    def row(t):
        return [t, ag[min(int(round(t / args.dt)), len(ag) - 1)] * length_to_mm,
                ops.eleResponse(args.specimen_element, "force")[slot] * force_to_kn,
                ops.nodeDisp(sn, sd) * length_to_mm] + \
               [ops.nodeDisp(n, d) * length_to_mm for n, d in outs]

    rows = [row(0.0)]
    spent = 0.0
    for k in range(1, len(ag)):
        t0 = time.perf_counter()
        ok = ops.analyze(1, args.dt)
        if ok != 0:
            ops.algorithm("KrylovNewton")
            ok = ops.analyze(4, args.dt / 4.0)
            ops.algorithm("Newton")
        spent += time.perf_counter() - t0
        if ok != 0:
            fail(2, f"{record} x{scale}: the analysis did not converge at step {k}")
        rows.append(row(k * args.dt))
    if folder is not None:
        # Removing the recorders closes their files; the ground acceleration at their times.
        ops.remove("recorders")
        with open(os.path.join(folder, "ground_accel.out"), "w", encoding="ascii") as f:
            for r in rows:
                f.write(f"{r[0]:.17g} {r[1] / length_to_mm:.17g}\n")
    return rows, spent


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--specimen", required=True)
    p.add_argument("--specimen-element", type=int, required=True)
    p.add_argument("--output", action="append", default=[])
    p.add_argument("--record", action="append", required=True)
    p.add_argument("--scale", action="append", type=float, required=True)
    p.add_argument("--dt", type=float, required=True)
    p.add_argument("--out-dir", required=True)
    p.add_argument("--duration-s", type=float)
    p.add_argument("--free-s", type=float, default=5.0)
    p.add_argument("--units", choices=("si", "mm-kn"))
    p.add_argument("--direction", type=int, default=1)
    p.add_argument("--recorders", action="store_true")
    args = p.parse_args()
    try:
        import openseespy.opensees as ops
    except ImportError as e:
        fail(3, f"openseespy cannot be imported ({e})")
    model = os.path.abspath(args.model)
    if args.units is None:
        # Built here only to read its units: each run builds it again, at rest.
        args.units = build_model(model, fail).get("RTHS_UNITS")
        if args.units not in ("si", "mm-kn"):
            fail(2, f"{args.model}: give the model's units (--units si|mm-kn or RTHS_UNITS)")
    outs = [parse_dof(o, fail) for o in args.output]
    os.makedirs(args.out_dir, exist_ok=True)
    header = ["time_s", "ground_accel_mm_s2", "specimen_force_kn", "interface_mm"] + \
        [f"out_{n}_{d}_mm" for n, d in outs]
    for record in args.record:
        stem = os.path.splitext(os.path.basename(record))[0]
        for scale in args.scale:
            if args.recorders:
                path = os.path.join(args.out_dir, f"{stem}-x{scale:g}")
                rows, spent = run(args, ops, model, record, scale, outs, folder=path)
            else:
                rows, spent = run(args, ops, model, record, scale, outs)
                path = os.path.join(args.out_dir, f"{stem}-x{scale:g}.csv")
                with open(path, "w", encoding="ascii") as f:
                    f.write(",".join(header) + "\n")
                    for r in rows:
                        f.write(",".join(f"{v:.17g}" for v in r) + "\n")
            steps = len(rows) - 1
            print(json.dumps({"file": path, "steps": steps, "analyze_s": spent,
                              "per_step_s": spent / max(steps, 1),
                              "peak_interface_mm": max(abs(r[3]) for r in rows)}))
            sys.stdout.flush()


if __name__ == "__main__":
    main()
