"""What site_paper_frame.py and site_3story.py share: a frame of stories each the paper's
(docs/design.md section 2), written in the braces' coordinate, the braces of its lower stories
genericClients of `rths site` (or all elastic), integrated explicitly so that each step sends one
trial displacement to the site. The scripts' docstrings describe their models; `run` builds one.
"""
import argparse
import json
import math
import time

import openseespy.opensees as ops

from transient import failer, read_at2

M = 1.75  # kN s^2/mm
K_FRAME = 176.75  # kN/mm
COS2 = 0.50857
C_FRAME = 1.496  # kN s/mm
G_MM_S2 = 9806.65
DT_TICK = 1.0 / 2048.0
# kN/mm: the prototype brace (the rig's nominal specimen times the force scale), the elastic
# brace of a story above the genericClients when --elastic does not give one.
K_BRACE = 1224.1


def parser(elastic_help):
    """The options both scripts take; only --elastic's help says which braces it replaces."""
    p = argparse.ArgumentParser()
    p.add_argument("--record", required=True)
    p.add_argument("--port", type=int, default=8090)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--udp", action="store_true")
    p.add_argument("--elastic", type=float, default=None, help=elastic_help)
    p.add_argument("--ticks-per-step", type=int, default=4)
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--out", default=None)
    return p


def build(a, stories, clients):
    """Nodes 1 (ground, fixed) to stories + 1; story s is element s (frame stiffness and damping)
    and brace 10 + s between floors s and s + 1. The braces of stories 1..clients are
    genericClients on ports PORT + s - 1 unless --elastic; every other brace is elastic."""
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    for i in range(1, stories + 2):
        ops.node(i, 0.0)
    ops.fix(1, 1)
    ops.uniaxialMaterial("Elastic", 1, K_FRAME / COS2)
    ops.uniaxialMaterial("Viscous", 2, C_FRAME / COS2, 1.0)
    for s in range(1, stories + 1):
        ops.mass(s + 1, M / COS2)
        ops.element("zeroLength", s, s, s + 1, "-mat", 1, 2, "-dir", 1, 1)
    ops.uniaxialMaterial("Elastic", 3, a.elastic if a.elastic is not None else K_BRACE)
    for s in range(1, stories + 1):
        if a.elastic is None and s <= clients:
            # A lone story's client holds its free floor only: its one basic DOF is the
            # actuator's displacement. In a taller frame every client spans its two floors (two
            # basic DOFs, the site imposes their difference), the first one as the others.
            nodes = [s + 1] if stories == 1 else [s, s + 1]
            args = ["genericClient", 10 + s, "-node", *nodes, *["-dof", 1] * len(nodes),
                    "-server", a.port + s - 1, a.host]
            if a.udp:
                args.append("-udp")
            ops.element(*args)
        else:
            ops.element("zeroLength", 10 + s, s, s + 1, "-mat", 3, "-dir", 1)


def run(stories, clients, elastic_help):
    """Parse the options, build the frame, integrate the record and write the floors'
    displacements: JSON `disp_mm` one number a step for one story, a list per floor otherwise."""
    p = parser(elastic_help)
    a = p.parse_args()
    fail = failer(p.prog)

    cos = math.sqrt(COS2)
    build(a, stories, clients)

    dt_rec, acc = read_at2(a.record, fail)
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
    floors = range(2, stories + 2)
    disp = []
    t0 = time.perf_counter()
    for _ in range(steps):
        if ops.analyze(1, dt) != 0:
            raise SystemExit("analysis failed")
        if stories == 1:
            disp.append(ops.nodeDisp(2, 1))
        else:
            disp.append([ops.nodeDisp(n, 1) for n in floors])
    wall = time.perf_counter() - t0
    ops.wipe()  # the genericClient sends DIE
    out = {"steps": steps, "dt_s": dt, "wall_s": wall, "disp_mm": disp}
    if a.out:
        with open(a.out, "w") as f:
            json.dump(out, f)
    if stories == 1:
        peak = f"peak {max(abs(x) for x in disp):.3f} mm"
    else:
        peak = f"peak roof {max(abs(x[-1]) for x in disp):.3f} mm"
    print(f"{steps} steps of {dt * 1e3:.4f} ms, {wall / steps * 1e3:.4f} ms per step, {peak}")
