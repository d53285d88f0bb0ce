"""A 3-bay, 3-story planar steel moment frame with fiber sections (Steel02) in every beam and
column and a brace specimen at the first floor, built with openseespy: the shipped nonlinear
OpenSees example of rths (docs/nonlinear.md, "The shipped fiber frame").

Units: kN, mm, s (mass in kN*s^2/mm), `RTHS_UNITS = "mm-kn"`.

- Members are `forceBeamColumn` elements (one per member, 5 Lobatto points) on fiber sections of
  wide-flange shapes: flanges and web as fiber patches of Steel02 (fy 0.345 kN/mm^2, E 200
  kN/mm^2, 1 % hardening, R0 20). Yielding spreads over the members' ends and along them, not
  story by story.
- Mass is lumped at the joints (`ops.mass`, horizontal and vertical: the floor's 3 t/m of beam and
  the steel), so the ground force is exactly `-M*iota*ag` with either excitation path.
- The specimen is a brace tested by a horizontal actuator at the first floor's left joint
  (`SPECIMEN_NODE`): in this model a `zeroLength` element (`SPECIMEN_ELEMENT`) in direction 1
  to a fixed node, elastic of `BRACE_K_KN_PER_MM`, the numerical stand-in of the brace.
- Rayleigh damping of 2 % in the first and the third mode, proportional to the initial stiffness
  (`-betaKinit`), so the damping is the elastic model's while the frame yields.
- No gravity load (the frame's axial forces are left out: the example is about lateral yielding).
"""

import math

import openseespy.opensees as ops

RTHS_UNITS = "mm-kn"
BAYS, STORIES = 3, 3
STORY_HEIGHT_MM, BAY_WIDTH_MM = 3500.0, 6000.0
E_KN_PER_MM2, FY_KN_PER_MM2, HARDENING = 200.0, 0.345, 0.01
# Wide-flange shapes (depth, flange width, flange thickness, web thickness, mm): columns
# W310x97-like, beams W360x57-like (a weak-beam frame: the beams yield first, then the column bases).
COLUMN_SHAPE = (308.0, 305.0, 15.4, 9.9)
BEAM_SHAPE = (358.0, 172.0, 13.1, 7.9)
FLOOR_MASS_PER_MM = 3.0e-6
STEEL_DENSITY = 7.85e-12
BRACE_K_KN_PER_MM = 20.0
DAMPING_RATIO = 0.02
SPECIMEN_NODE = 5  # the first floor's left joint: joint(0, 1)
SPECIMEN_ELEMENT = 1000


def joint(column, floor):
    """Tag of the joint of column line `column` at floor `floor` (0: ground)."""
    return 1 + floor * (BAYS + 1) + column


def wide_flange(tag, shape):
    """A fiber section of an I shape bent about its strong axis; returns its area, mm^2."""
    d, bf, tf, tw = shape
    ops.section("Fiber", tag)
    h = d / 2.0
    ops.patch("rect", 1, 4, 1, h - tf, -bf / 2.0, h, bf / 2.0)
    ops.patch("rect", 1, 4, 1, -h, -bf / 2.0, -h + tf, bf / 2.0)
    ops.patch("rect", 1, 8, 1, -h + tf, -tw / 2.0, h - tf, tw / 2.0)
    return 2.0 * bf * tf + (d - 2.0 * tf) * tw


def build():
    """Build the frame in the current OpenSees domain; returns the specimen's node tag."""
    ops.wipe()
    ops.model("basic", "-ndm", 2, "-ndf", 3)
    for f in range(STORIES + 1):
        for c in range(BAYS + 1):
            ops.node(joint(c, f), c * BAY_WIDTH_MM, f * STORY_HEIGHT_MM)
            if f == 0:
                ops.fix(joint(c, f), 1, 1, 1)
    ops.uniaxialMaterial("Steel02", 1, FY_KN_PER_MM2, E_KN_PER_MM2, HARDENING, 20.0, 0.925, 0.15)
    column_area = wide_flange(1, COLUMN_SHAPE)
    beam_area = wide_flange(2, BEAM_SHAPE)
    ops.geomTransf("Linear", 1)
    ops.beamIntegration("Lobatto", 1, 1, 5)
    ops.beamIntegration("Lobatto", 2, 2, 5)
    e = 1
    for f in range(STORIES):
        for c in range(BAYS + 1):
            ops.element("forceBeamColumn", e, joint(c, f), joint(c, f + 1), 1, 1)
            e += 1
        for c in range(BAYS):
            ops.element("forceBeamColumn", e, joint(c, f + 1), joint(c + 1, f + 1), 1, 2)
            e += 1
    # Lumped mass: each joint takes half of every member it ends.
    beam_mass = (STEEL_DENSITY * beam_area + FLOOR_MASS_PER_MM) * BAY_WIDTH_MM
    column_mass = STEEL_DENSITY * column_area * STORY_HEIGHT_MM
    for f in range(1, STORIES + 1):
        for c in range(BAYS + 1):
            beams = (c > 0) + (c < BAYS)
            columns = 1 + (f < STORIES)
            m = 0.5 * beams * beam_mass + 0.5 * columns * column_mass
            ops.mass(joint(c, f), m, m, 0.0)
    anchor = joint(BAYS, STORIES) + 1
    ops.node(anchor, *ops.nodeCoord(SPECIMEN_NODE))
    ops.fix(anchor, 1, 1, 1)
    ops.uniaxialMaterial("Elastic", 2, BRACE_K_KN_PER_MM)
    ops.element("zeroLength", SPECIMEN_ELEMENT, anchor, SPECIMEN_NODE, "-mat", 2, "-dir", 1)
    w = [math.sqrt(v) for v in ops.eigen("-fullGenLapack", 3)]
    w1, w3 = w[0], w[2]
    alpha_m = DAMPING_RATIO * 2.0 * w1 * w3 / (w1 + w3)
    beta_k = DAMPING_RATIO * 2.0 / (w1 + w3)
    ops.rayleigh(alpha_m, 0.0, beta_k, 0.0)
    return SPECIMEN_NODE


build()
