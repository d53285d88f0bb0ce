#!/usr/bin/env python3
"""Export a lab's openseespy model to Matrix Market files for `rths import opensees`.

    python3 export_model.py MODEL.py --out-dir DIR [--units si|mm-kn] [--direction 1]

MODEL.py builds the model with `openseespy.opensees` calls (nodes, fixities, elements, masses,
`rayleigh`); it runs with `__name__ == "rths_export"`, so analyses a script keeps under
`if __name__ == "__main__":` do not run. Its directory is on `sys.path` (it may import its own
modules). The model is exported in the state the script leaves it in: a nonlinear model gives
its initial (tangent) matrices.

Writes to DIR:
- `mass.mtx`, `damping.mtx`, `stiffness.mtx`: the assembled M, C (the Rayleigh damping the script
  defines; all zero without one) and K over the model's free equations (OpenSees's `GimmeMCK`
  integrator and `printA` on a `FullGeneral` system, RCM numbering, Transformation constraints),
  Matrix Market coordinate format, every stored entry (no symmetry assumed), 17 significant digits.
- `manifest.json`: the units, each equation's (node, dof), the ground motion's influence vector in
  direction `--direction` (1 on that DOF of every node, 0 elsewhere), the matrix files.

Exit codes: 0 done, 2 bad arguments or a model script that fails, 3 openseespy cannot be imported.
"""

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from transient import assemble, build_model, failer  # noqa: E402 (after the path)

UNITS = ("si", "mm-kn")


fail = failer("export_model.py")


def write_mtx(path, a, n):
    """Write the n x n list-of-floats `a` (row-major) as a general coordinate Matrix Market file."""
    entries = []
    for i in range(n):
        row = a[i * n:(i + 1) * n]
        for j, v in enumerate(row):
            if v != 0.0:
                entries.append(f"{i + 1} {j + 1} {v:.17g}")
    with open(path, "w", encoding="ascii") as f:
        f.write("%%MatrixMarket matrix coordinate real general\n")
        f.write(f"{n} {n} {len(entries)}\n")
        for e in entries:
            f.write(e + "\n")
    return len(entries)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--units", choices=UNITS)
    p.add_argument("--direction", type=int, default=1)
    args = p.parse_args()

    try:
        import openseespy.opensees as ops
    except Exception as e:  # ImportError, or the shared library not found
        fail(3, f"cannot import openseespy ({e})")

    model = os.path.abspath(args.model)
    scope = build_model(model, fail)

    units = args.units or scope.get("RTHS_UNITS")
    if units not in UNITS:
        fail(2, f"{args.model}: give the model's units (--units si|mm-kn, or RTHS_UNITS = "
                "\"si\" | \"mm-kn\" in the script); found {units!r}")

    n = assemble(ops, lambda code, message: fail(code, f"{args.model}: {message}"))

    equations = [None] * n
    influence = [0.0] * n
    for node in sorted(ops.getNodeTags()):
        for dof, eq in enumerate(ops.nodeDOFs(node), start=1):
            if eq >= 0:
                equations[eq] = [node, dof]
                if dof == args.direction:
                    influence[eq] = 1.0
    if any(e is None for e in equations):
        fail(2, f"{args.model}: an equation belongs to no node's DOF (constraints OpenSees "
                "could not map back)")

    os.makedirs(args.out_dir, exist_ok=True)
    counts = {}
    for name, mck in (("mass", (1.0, 0.0, 0.0)), ("damping", (0.0, 1.0, 0.0)),
                      ("stiffness", (0.0, 0.0, 1.0))):
        ops.integrator("GimmeMCK", *mck)
        a = ops.printA("-ret")
        if len(a) != n * n:
            fail(2, f"{args.model}: printA gave {len(a)} entries for {n} equations")
        counts[name] = write_mtx(os.path.join(args.out_dir, f"{name}.mtx"), a, n)

    manifest = {
        "format": "rths-opensees-export",
        "version": 1,
        "model": os.path.basename(model),
        "units": units,
        "direction": args.direction,
        "equations": equations,
        "influence": influence,
        "matrices": {k: f"{k}.mtx" for k in ("mass", "damping", "stiffness")},
        "entries": counts,
    }
    with open(os.path.join(args.out_dir, "manifest.json"), "w", encoding="ascii") as f:
        json.dump(manifest, f)
        f.write("\n")


if __name__ == "__main__":
    main()
