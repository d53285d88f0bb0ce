#!/usr/bin/env python3
"""The interface's yield displacement of an openseespy model, from a pushover: the yield that turns a
run's peak interface displacement into its ductility (docs/opensees-nonlinear.md, "Held out in the goal's
range").

    python3 pushover.py MODEL.py --control NODE:DOF --to-mm MAX [--target-ductility 4]
        [--step-mm 0.5] [--pattern triangular|uniform] [--output NODE:DOF ...] [--out CURVE.csv]
        [--units si|mm-kn] [--direction 1]

MODEL.py is built as `export_model.py` builds it (run as `rths_export`, its directory on
`sys.path`), at rest, with its specimen stand-in in place (the pushover is of the structure the
training runs integrate). Lateral loads in direction `--direction` go on every node with mass:
`M*iota` (the ground loads of `transient.py`) times the node's height (its last coordinate) for
`triangular`, as they are for `uniform`. The analysis is static, displacement control of
`--control` in steps of `--step-mm` up to `--to-mm` (Newton on `NormDispIncr` 1e-8, Krylov-Newton
and quarter steps where a step does not converge), so the curve passes the peak lateral force.

The curve (control displacement, total lateral force) is idealized as ASCE 41-17 section 7.4.3.2.5
does: a first line from the origin through the curve at 0.6 of the yield force, a second to the
target point (or to the peak force, where the curve falls before the target), the areas under
both equal; the yield displacement is where the lines meet. The
target is `--target-ductility` times that yield (iterated; default 4, the top of the ductility
range a run is judged in), within the curve.

stdout gets one JSON line: initial stiffness (kN/mm, of the first step), effective stiffness, yield
force and displacement, target displacement, peak force. `--out` writes the curve as CSV
(`control_mm,lateral_force_kn,out_<NODE>_<DOF>_mm...`). Exit codes: 0 done, 2 bad arguments or a
model/analysis that fails, 3 openseespy missing.
"""

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from transient import build_model, failer, ground_loads, parse_dof  # noqa: E402 (after the path)

# Tags of the load series and pattern, away from a lab's own.
SERIES_TAG = 987021
PATTERN_TAG = 987021
# Iterations of the idealization (each a fixed-point step on the yield force; it settles in a few).
IDEALIZE_ITERATIONS = 100


fail = failer("pushover.py")


def interp(x, xs, ys):
    """Linear interpolation of y at x on the rising table (xs, ys)."""
    for i in range(1, len(xs)):
        if xs[i] >= x:
            a = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
            return ys[i - 1] + a * (ys[i] - ys[i - 1])
    return ys[-1]


def area(xs, ys, upto):
    """Area under the curve from its first point to `upto` (trapezoids)."""
    total = 0.0
    for px, py, x, y in zip(xs, ys, xs[1:], ys[1:]):
        if x > upto:
            return total + 0.5 * (py + interp(upto, [px, x], [py, y])) * (upto - px)
        total += 0.5 * (py + y) * (x - px)
    return total


def idealize(xs, vs, target_mm):
    """ASCE 41-17's bilinear idealization of the curve up to `target_mm` (or up to the peak force,
    where the curve falls before the target): (k_e, V_y, d_y)."""
    # The tables start at the origin, so a first step already past 0.6 V_y is read on the
    # elastic line through it rather than extrapolated.
    xs, vs = [0.0] + xs, [0.0] + vs
    peak = max(range(len(vs)), key=lambda i: vs[i])
    d = min(target_mm, xs[peak])
    vt = interp(d, xs, vs)
    a = area(xs, vs, d)
    rise_x, rise_v = xs[: peak + 1], vs[: peak + 1]
    vy = interp(0.25 * d, xs, vs)
    for _ in range(IDEALIZE_ITERATIONS):
        x06 = interp(0.6 * vy, rise_v, rise_x)
        if not x06 > 0.0:
            fail(2, "the curve has no rising branch to idealize")
        ke = 0.6 * vy / x06
        den = 0.5 * (d - vt / ke)
        if den <= 1e-12 * d:
            if d < target_mm:
                # Elastic up to its peak, then falling: it yields at the peak.
                return ke, vt, vt / ke
            fail(2, f"the curve to {d:g} mm does not yield: extend --to-mm")
        nxt = (a - 0.5 * vt * d) / den
        if abs(nxt - vy) <= 1e-12 * abs(vy):
            vy = nxt
            break
        vy = nxt
    else:
        fail(2, "the bilinear idealization did not settle")
    if not (ke > 0.0 and 0.0 < vy <= vs[peak] * (1.0 + 1e-9)):
        fail(2, f"no bilinear fits the curve (k_e {ke:g}, V_y {vy:g} for a peak of {vs[peak]:g})")
    return ke, vy, vy / ke


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--control", required=True)
    p.add_argument("--to-mm", type=float, required=True)
    p.add_argument("--target-ductility", type=float, default=4.0)
    p.add_argument("--step-mm", type=float, default=0.5)
    p.add_argument("--pattern", choices=("triangular", "uniform"), default="triangular")
    p.add_argument("--output", action="append", default=[])
    p.add_argument("--out")
    p.add_argument("--units", choices=("si", "mm-kn"))
    p.add_argument("--direction", type=int, default=1)
    args = p.parse_args()
    if not args.to_mm > 0.0 or not args.step_mm > 0.0 or args.step_mm >= args.to_mm:
        fail(2, "--to-mm and --step-mm must be positive, the step below the range")
    if not args.target_ductility > 1.0:
        fail(2, "--target-ductility must be above 1")
    if args.direction < 1:
        fail(2, "--direction counts from 1")
    try:
        import openseespy.opensees as ops
    except ImportError as e:
        fail(3, f"openseespy cannot be imported ({e})")
    scope = build_model(args.model, fail)
    units = args.units or scope.get("RTHS_UNITS")
    if units not in ("si", "mm-kn"):
        fail(2, f"{args.model}: give the model's units (--units si|mm-kn or RTHS_UNITS)")
    length_to_mm, force_to_kn = (1000.0, 1e-3) if units == "si" else (1.0, 1.0)
    cn, cd = parse_dof(args.control, fail)
    outs = [parse_dof(o, fail) for o in args.output]
    for flag, (n, d) in [("--control", (cn, cd))] + [("--output", o) for o in outs]:
        try:
            ops.nodeDisp(n, d)
        except Exception:  # openseespy raises its own error type for a missing node
            fail(2, f"{flag} {n}:{d}: no such node and DOF in the model")
    loads = []
    for node, values in ground_loads(ops, args.direction, fail):
        if len(values) < args.direction:
            fail(2, f"--direction {args.direction}: node {node} has {len(values)} DOF(s)")
        height = ops.nodeCoord(node)[-1] if args.pattern == "triangular" else 1.0
        loads.append((node, [-v * height for v in values]))
    total = sum(v[args.direction - 1] for _, v in loads)
    if total <= 0.0:
        fail(2, "no lateral load: no node with mass in that direction stands above height 0 "
                "(a model without heights takes --pattern uniform)")
    ops.timeSeries("Linear", SERIES_TAG)
    ops.pattern("Plain", PATTERN_TAG, SERIES_TAG)
    for node, values in loads:
        ops.load(node, *[v / total for v in values])
    step = args.step_mm / length_to_mm
    ops.wipeAnalysis()
    ops.system("BandGeneral")
    ops.numberer("RCM")
    ops.constraints("Transformation")
    ops.test("NormDispIncr", 1e-8, 50)
    ops.algorithm("Newton")
    ops.integrator("DisplacementControl", cn, cd, step)
    ops.analysis("Static")
    xs, vs, rows = [], [], []
    for k in range(int(round(args.to_mm / args.step_mm))):
        ok = ops.analyze(1)
        if ok != 0:
            ops.algorithm("KrylovNewton")
            ops.integrator("DisplacementControl", cn, cd, step / 4.0)
            ok = ops.analyze(4)
            ops.integrator("DisplacementControl", cn, cd, step)
            ops.algorithm("Newton")
        if ok != 0:
            fail(2, f"the pushover did not converge at step {k + 1}")
        # The pattern's loads sum to 1, so the load factor is the total lateral force.
        x = ops.nodeDisp(cn, cd) * length_to_mm
        v = ops.getLoadFactor(PATTERN_TAG) * force_to_kn
        xs.append(x)
        vs.append(v)
        rows.append([x, v] + [ops.nodeDisp(n, d) * length_to_mm for n, d in outs])
    if args.out:
        with open(args.out, "w", encoding="ascii") as f:
            f.write(",".join(["control_mm", "lateral_force_kn"] +
                             [f"out_{n}_{d}_mm" for n, d in outs]) + "\n")
            for r in rows:
                f.write(",".join(f"{v:.17g}" for v in r) + "\n")
    # The target is μ times the yield it gives: a fixed point, reached in a few passes.
    target = 0.5 * xs[-1]
    for _ in range(IDEALIZE_ITERATIONS):
        ke, vy, dy = idealize(xs, vs, target)
        nxt = args.target_ductility * dy
        if nxt > xs[-1]:
            fail(2, f"the target ({args.target_ductility:g} x {dy:.1f} mm) is past the curve: "
                    "extend --to-mm")
        if abs(nxt - target) < 1e-9 * xs[-1]:
            target = nxt
            break
        target = nxt
    else:
        fail(2, "the target did not settle at the ductility's multiple of the yield")
    print(json.dumps({"initial_stiffness_kn_per_mm": vs[0] / xs[0],
                      "effective_stiffness_kn_per_mm": ke, "yield_force_kn": vy,
                      "yield_mm": dy, "target_mm": target,
                      "target_ductility": args.target_ductility, "peak_force_kn": max(vs)}))


if __name__ == "__main__":
    main()
