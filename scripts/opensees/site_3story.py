"""A 3-story braced frame in OpenSees, each story the paper's (docs/design.md section 2: mass, frame
stiffness and damping, brace), the braces of stories 1 and 2 the two experimental elements of
`rths site --elements 2` (genericClients on ports PORT and PORT + 1, two actuators), the third an
elastic brace; or all three elastic for comparison.

As site_paper_frame.py, in the braces' coordinate (floor displacements times cos(theta)): a story's
brace deformation is the difference of its two floors' DOFs, the genericClient of a story spans
both (two basic DOFs; the site imposes their difference). Explicit integration (NewmarkExplicit, algorithm Linear):
each step sends one trial displacement to the site.

  python site_3story.py --record IELC180.AT2 [--port 8090] [--udp] [--elastic K]
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
                   help="every brace an elastic element of this stiffness (kN/mm); also the third story's")
    p.add_argument("--ticks-per-step", type=int, default=4)
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--out", default=None)
    a = p.parse_args()

    cos = math.sqrt(COS2)
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    for i in range(1, 5):
        ops.node(i, 0.0)
    ops.fix(1, 1)
    ops.uniaxialMaterial("Elastic", 1, K_FRAME / COS2)
    ops.uniaxialMaterial("Viscous", 2, C_FRAME / COS2, 1.0)
    for s in range(1, 4):
        ops.mass(s + 1, M / COS2)
        ops.element("zeroLength", s, s, s + 1, "-mat", 1, 2, "-dir", 1, 1)
    ops.uniaxialMaterial("Elastic", 3, a.elastic if a.elastic is not None else 1224.1)
    for s in range(1, 4):
        if a.elastic is None and s <= 2:
            args = ["genericClient", 10 + s, "-node", s, s + 1, "-dof", 1, "-dof", 1,
                    "-server", a.port + s - 1, a.host]
            if a.udp:
                args.append("-udp")
            ops.element(*args)
        else:
            ops.element("zeroLength", 10 + s, s, s + 1, "-mat", 3, "-dir", 1)

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
        disp.append([ops.nodeDisp(n, 1) for n in (2, 3, 4)])
    wall = time.perf_counter() - t0
    ops.wipe()  # the genericClient sends DIE
    out = {"steps": steps, "dt_s": dt, "wall_s": wall, "disp_mm": disp}
    if a.out:
        with open(a.out, "w") as f:
            json.dump(out, f)
    print(f"{steps} steps of {dt * 1e3:.4f} ms, {wall / steps * 1e3:.4f} ms per step, "
          f"peak roof {max(abs(x[2]) for x in disp):.3f} mm")


if __name__ == "__main__":
    main()
