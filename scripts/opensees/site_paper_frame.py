"""The paper's one-story braced frame (docs/design.md section 2) in OpenSees, its brace the
experimental element of `rths site` (a genericClient), or an elastic element for comparison.

The model is written in the brace's coordinate: its one DOF is the brace deformation d = x cos(theta)
(mm, the actuator's displacement at specimen scale 1), so the genericClient's basic DOF is what the
actuator imposes. Dividing the story equation by cos^2(theta):
  (m/c2) d'' + (c/c2) d' + (k_a/c2) d + N = -(m/c2) cos(theta) ug''
with N the brace force (kN, prototype). Explicit integration (NewmarkExplicit, algorithm Linear):
each step sends one trial displacement to the site.

  python site_paper_frame.py --record IELC180.AT2 [--port 8090] [--udp] [--elastic K]
      [--ticks-per-step 4] [--duration 10] [--scale 1] [--out disp.json]
"""
import argparse
import json
import math
import time

import openseespy.opensees as ops

M = 1.75  # kN s^2/mm
K_FRAME = 176.75  # kN/mm
COS2 = 0.50857
C_FRAME = 1.496  # kN s/mm
G_MM_S2 = 9806.65
DT_TICK = 1.0 / 2048.0


def read_at2(path):
    """Acceleration (g) and its step (s) of a PEER AT2 file."""
    with open(path) as f:
        lines = f.read().splitlines()
    head = lines[3].upper().replace(",", " ")
    dt = float(head.split("DT=")[1].split()[0])
    values = [float(v) for l in lines[4:] for v in l.split()]
    return values, dt


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--record", required=True)
    p.add_argument("--port", type=int, default=8090)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--udp", action="store_true")
    p.add_argument("--elastic", type=float, default=None,
                   help="the brace as an elastic element of this stiffness (kN/mm) instead")
    p.add_argument("--ticks-per-step", type=int, default=4)
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--out", default=None)
    a = p.parse_args()

    cos = math.sqrt(COS2)
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(1, 0.0)
    ops.node(2, 0.0)
    ops.fix(1, 1)
    ops.mass(2, M / COS2)
    ops.uniaxialMaterial("Elastic", 1, K_FRAME / COS2)
    ops.uniaxialMaterial("Viscous", 2, C_FRAME / COS2, 1.0)
    ops.element("zeroLength", 1, 1, 2, "-mat", 1, 2, "-dir", 1, 1)
    if a.elastic is None:
        args = ["genericClient", 3, "-node", 2, "-dof", 1, "-server", a.port, a.host]
        if a.udp:
            args.append("-udp")
        ops.element(*args)
    else:
        ops.uniaxialMaterial("Elastic", 3, a.elastic)
        ops.element("zeroLength", 3, 1, 2, "-mat", 3, "-dir", 1)

    acc, dt_rec = read_at2(a.record)
    ops.timeSeries("Path", 1, "-dt", dt_rec, "-values", *acc,
                   "-factor", a.scale * G_MM_S2 * cos)
    ops.pattern("UniformExcitation", 1, 1, "-accel", 1)
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system("FullGeneral")
    ops.test("FixedNumIter", 1)
    ops.algorithm("Linear")
    ops.integrator("NewmarkExplicit", 0.5)
    ops.analysis("Transient")

    dt = a.ticks_per_step * DT_TICK
    steps = int(round(a.duration / dt))
    disp = []
    t0 = time.perf_counter()
    for _ in range(steps):
        if ops.analyze(1, dt) != 0:
            raise SystemExit("analysis failed")
        disp.append(ops.nodeDisp(2, 1))
    wall = time.perf_counter() - t0
    ops.wipe()  # the genericClient sends DIE
    out = {"steps": steps, "dt_s": dt, "wall_s": wall, "disp_mm": disp}
    if a.out:
        with open(a.out, "w") as f:
            json.dump(out, f)
    print(f"{steps} steps of {dt * 1e3:.4f} ms, {wall / steps * 1e3:.4f} ms per step, "
          f"peak {max(abs(x) for x in disp):.3f} mm")


if __name__ == "__main__":
    main()
