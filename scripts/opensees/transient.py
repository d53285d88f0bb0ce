#!/usr/bin/env python3
"""OpenSees's own transient analysis of a model under a ground motion, for comparison with rths.

    python3 transient.py MODEL.py --record AG.txt --dt DT --dofs NODE:DOF[,NODE:DOF...] --out OUT.csv
                         [--direction 1]

MODEL.py is built as `export_model.py` builds it (run as `rths_export`, its directory on
`sys.path`). AG.txt holds the ground acceleration, one value per line in the model's units,
sample k at time k*DT. The analysis is Newmark's average acceleration (gamma 1/2, beta 1/4) at
DT with a linear algorithm factorizing once (`Linear -factorOnce`, a `BandSPD` system, RCM
numbering), the model's own damping; the model starts at rest.

The ground motion enters as the effective earthquake loads `-M*iota*ag(t)` on the nodes (a `Plain`
pattern on a `Path` series), `M` being the mass matrix OpenSees assembles for the model (the one
its inertia forces use) and `iota` 1 on DOF `--direction` of every node. `--excitation uniform`
uses OpenSees's `UniformExcitation` instead: openseespy 3.7.1.2 applies the ground force of an
`elasticBeamColumn`'s `-mass` twice there (measured: twice the response of the same mass given
with `ops.mass`), so its response to distributed mass is not the model's (docs/opensees.md). OUT.csv gets `time_s` and one column `NODE_DOF` of displacements per DOF, a row per sample
(row 0: rest). stdout gets one JSON line: steps, seconds in `analyze`, seconds per step.
"""

import argparse
import json
import math
import os
import runpy
import sys
import time

# Tags for the record's series and pattern, away from a lab's own.
SERIES_TAG = 987001
PATTERN_TAG = 987001


def build_model(path, fail):
    """Run the model script at `path` as every script here does: as `rths_export` (its
    `if __name__ == "__main__":` part does not run), its directory first on `sys.path` so it
    imports its own modules, whatever their names. Returns its globals; a missing or failing
    script is `fail(2, message)`."""
    model = os.path.abspath(path)
    if not os.path.isfile(model):
        fail(2, f"{path}: no such model script")
    # As `python MODEL.py` would: its folder first on the path, and no module of ours cached under
    # a name the script may use for one of its own (this one is imported as `transient`).
    folder = os.path.dirname(model)
    if folder in sys.path:
        sys.path.remove(folder)
    sys.path.insert(0, folder)
    sys.modules.pop("transient", None)
    try:
        return runpy.run_path(model, run_name="rths_export")
    except SystemExit as e:
        fail(2, f"{path}: the model script exited ({e.code})")
    except Exception as e:  # the script's own error, or OpenSees's
        fail(2, f"{path}: the model script failed: {type(e).__name__}: {e}")


def parse_dof(text, fail):
    """(node, dof) of `NODE:DOF`; anything else is `fail(2, message)`."""
    try:
        node, dof = text.split(":")
        return int(node), int(dof)
    except ValueError:
        fail(2, f"`{text}` is not NODE:DOF")


def _at2_number(token):
    """The finite float an AT2 token holds (Fortran's 1.0D-02 too), or None."""
    try:
        value = float(token.replace("D", "E"))
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _at2_header_value(upper, key):
    """The token after `key` on an upper-cased header line, past one `=` or `:`, up to the next
    blank or comma; None if the key is absent or nothing follows it."""
    at = upper.find(key)
    if at < 0:
        return None
    rest = upper[at + len(key):].lstrip()
    if rest[:1] in ("=", ":"):
        rest = rest[1:].lstrip()
    token = rest.replace(",", " ").split()
    return token[0] if token else None


def _at2_header_fields(upper):
    """The NPTS and DT tokens of an upper-cased line 4: `NPTS= 4000, DT= .01 SEC` (`=` or `:`,
    comma optional) or the older PEER layout `4000 .0100 NPTS, DT`; None where one is missing."""
    lead = upper.replace(",", " ").split()
    if (len(lead) >= 3 and _at2_number(lead[0]) is not None and _at2_number(lead[1]) is not None
            and lead[2].startswith("NPTS") and "DT" in upper):
        return lead[0], lead[1]
    npts = _at2_header_value(upper, "NPTS")
    # DT after NPTS first, so that a record name holding "DT" is not taken for it.
    after = upper.find("NPTS")
    dt = _at2_header_value(upper[after + 4:], "DT") if after >= 0 else None
    return npts, dt if dt is not None else _at2_header_value(upper, "DT")


def read_at2(path, fail):
    """(dt, accelerations in g) of a PEER AT2 file, in the layouts rths's own reader takes: lines
    1-3 free text, line 4 `NPTS` and `DT` (`NPTS= 4000, DT= .01 SEC`, `=` or `:`, or the older
    `4000 .0100 NPTS, DT`), then exactly NPTS finite values separated by blanks or commas. A file
    that is not one is `fail(2, message)` naming the file and, where there is one, the line."""
    # Any stray byte becomes U+FFFD, then fails as a value naming its line (no UnicodeDecodeError).
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError as e:
        fail(2, f"{path}: cannot be read ({e.strerror})")
    if len(lines) < 4:
        fail(2, f"{path}: not an AT2 file (fewer than 4 lines)")
    npts_text, dt_text = _at2_header_fields(lines[3].upper())
    if npts_text is None or dt_text is None:
        fail(2, f"{path}: line 4: no NPTS= and DT= in the AT2 header")
    if not npts_text.isdigit() or int(npts_text) < 1:
        fail(2, f"{path}: line 4: NPTS `{npts_text}` is not a whole number of points")
    npts = int(npts_text)
    dt = _at2_number(dt_text)
    if dt is None or dt <= 0.0:
        fail(2, f"{path}: line 4: DT `{dt_text}` is not a finite positive step")
    values = []
    for number, line in enumerate(lines[4:], start=5):
        for token in line.replace(",", " ").split():
            value = _at2_number(token)
            if value is None:
                fail(2, f"{path}: line {number}: `{token}` is not a finite number")
            values.append(value)
    # A cut file, or one with values past its NPTS, is refused as rths's own reader refuses it:
    # never run as another record than its header says.
    if len(values) != npts:
        fail(2, f"{path}: NPTS {npts} in the header, {len(values)} acceleration values after it")
    return dt, values


def failer(script):
    """The `fail(code, message)` of a script: `script: message` on stderr, then exit `code`."""
    def fail(code, message):
        print(f"{script}: {message}", file=sys.stderr)
        sys.exit(code)
    return fail


fail_exit = failer("transient.py")


def assemble(ops, fail):
    """Number the model's equations and size its system (one step of zero length, so no time
    passes); the system's size, with a `GimmeMCK` analysis left in place to read its matrices. A
    model OpenSees cannot assemble, or one without free DOFs, is `fail(2, message)`."""
    ops.wipeAnalysis()
    ops.system("FullGeneral")
    ops.numberer("RCM")
    ops.constraints("Transformation")
    ops.algorithm("Linear")
    ops.integrator("GimmeMCK", 0.0, 0.0, 1.0)
    ops.analysis("Transient")
    if ops.analyze(1, 0.0) != 0:
        fail(2, "OpenSees could not assemble the model (a mechanism? see its messages above)")
    n = ops.systemSize()
    if n == 0:
        fail(2, "the model has no free DOFs")
    return n


def ground_loads(ops, direction, fail):
    """(node, nodal load per unit ground acceleration) for every node with mass: -M*iota."""
    n = assemble(ops, fail)
    eqs = {node: ops.nodeDOFs(node) for node in sorted(ops.getNodeTags())}
    iota = [0.0] * n
    for node, dofs in eqs.items():
        if len(dofs) >= direction and dofs[direction - 1] >= 0:
            iota[dofs[direction - 1]] = 1.0
    ops.integrator("GimmeMCK", 1.0, 0.0, 0.0)
    m = ops.printA("-ret")
    m_iota = [sum(m[i * n + j] * iota[j] for j in range(n) if iota[j] != 0.0) for i in range(n)]
    loads = []
    for node, dofs in eqs.items():
        values = [-m_iota[e] if e >= 0 else 0.0 for e in dofs]
        if any(v != 0.0 for v in values):
            loads.append((node, values))
    ops.wipeAnalysis()
    return loads


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--record", required=True)
    p.add_argument("--dt", type=float, required=True)
    p.add_argument("--dofs", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--direction", type=int, default=1)
    p.add_argument("--excitation", choices=("nodal", "uniform"), default="nodal")
    args = p.parse_args()

    import openseespy.opensees as ops

    build_model(args.model, fail_exit)

    with open(args.record, encoding="ascii") as f:
        ag = [float(line) for line in f if line.strip()]
    dofs = [parse_dof(item, fail_exit) for item in args.dofs.split(",")]

    ops.timeSeries("Path", SERIES_TAG, "-dt", args.dt, "-values", *ag)
    if args.excitation == "uniform":
        ops.pattern("UniformExcitation", PATTERN_TAG, args.direction, "-accel", SERIES_TAG)
    else:
        loads = ground_loads(ops, args.direction, fail_exit)
        ops.pattern("Plain", PATTERN_TAG, SERIES_TAG)
        for node, values in loads:
            ops.load(node, *values)
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
