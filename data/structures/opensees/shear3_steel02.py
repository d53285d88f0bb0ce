"""A 3-story shear frame whose stories yield by Steel02 (Menegotto-Pinto), built with openseespy:
the elastic structure is `data/structures/opensees-shear3-steel02.json` (the same masses, story
stiffnesses, specimen and 2 % Rayleigh damping), the yielding is a law rths's story springs
(bilinear, Bouc-Wen) were not written for. docs/opensees-nonlinear.md, "Shipped OpenSees models".

Units: kN, mm, s (`RTHS_UNITS = "mm-kn"`). Node tags are the floors (1 to 3; the ground is node
100), so `out_<FLOOR>_1_mm` names a floor as rths's story structures do. Story k is a
`zeroLength` of Steel02 between floors k-1 and k (initial stiffness the story's, minus the
specimen's in story 1; yield forces those of `shear3-yielding`, 1 % hardening, R0 18); the
specimen is an elastic `zeroLength` (`SPECIMEN_ELEMENT`) from floor 1 to a fixed node, the numerical
stand-in of a 100 kN/mm brace. Rayleigh damping of 2 % in the first and the last mode, on the
initial stiffness (`-betaKinit`), as rths builds a story structure's damping: the story elements
take it by `-doRayleigh 1` (a `zeroLength` has no Rayleigh damping by default, which left the
frame with the mass-proportional part alone, 2.5 % off the elastic structure file on an elastic
run), and so does the specimen's stand-in: the structure file's damping is the whole frame's,
specimen included, and all of it belongs to the numerical part (its specimen has no damping of
its own). The stand-in's recorded force is its material's, without the damping.
"""

import math

import openseespy.opensees as ops

RTHS_UNITS = "mm-kn"
FLOOR_MASS = [0.6, 0.6, 0.5]
STORY_STIFFNESS = [300.0, 250.0, 200.0]
SPECIMEN_K_KN_PER_MM = 100.0
YIELD_FORCE_KN = [3703.4, 4347.65, 2461.65]
HARDENING = 0.01
DAMPING_RATIO = 0.02
GROUND, ANCHOR = 100, 101
SPECIMEN_NODE, SPECIMEN_ELEMENT = 1, 1000


def build():
    """Build the frame in the current OpenSees domain; returns the specimen's node tag."""
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(GROUND, 0.0)
    ops.fix(GROUND, 1)
    ops.node(ANCHOR, 0.0)
    ops.fix(ANCHOR, 1)
    for f, m in enumerate(FLOOR_MASS, start=1):
        ops.node(f, 0.0, "-mass", m)
    for k, (kk, fy) in enumerate(zip(STORY_STIFFNESS, YIELD_FORCE_KN), start=1):
        k0 = kk - (SPECIMEN_K_KN_PER_MM if k == 1 else 0.0)
        ops.uniaxialMaterial("Steel02", k, fy, k0, HARDENING, 18.0, 0.925, 0.15)
        below = GROUND if k == 1 else k - 1
        ops.element("zeroLength", k, below, k, "-mat", k, "-dir", 1, "-doRayleigh", 1)
    ops.uniaxialMaterial("Elastic", 99, SPECIMEN_K_KN_PER_MM)
    ops.element(
        "zeroLength", SPECIMEN_ELEMENT, ANCHOR, SPECIMEN_NODE, "-mat", 99, "-dir", 1, "-doRayleigh", 1
    )
    w = [math.sqrt(v) for v in ops.eigen("-fullGenLapack", len(FLOOR_MASS))]
    w1, wn = w[0], w[-1]
    alpha_m = DAMPING_RATIO * 2.0 * w1 * wn / (w1 + wn)
    beta_k = DAMPING_RATIO * 2.0 / (w1 + wn)
    ops.rayleigh(alpha_m, 0.0, beta_k, 0.0)
    return SPECIMEN_NODE


build()
