"""A planar moment-resisting steel frame with a brace specimen, built with openseespy.

The shipped OpenSees examples of rths (`frame-2x3.py`, `frame-5x12.py`) call `build` with their
sizes. Units: kN, mm, s (mass in kN*s^2/mm), which the scripts declare as `RTHS_UNITS = "mm-kn"`.

- Columns and beams are `elasticBeamColumn` elements, every member split into `segments`
  elements, so the frame's mass (the steel's own and the floor's, given as a mass per length of
  the members: `-mass`) is distributed along the members: every node carries horizontal and
  vertical mass, the rotations carry none.
- The specimen is a brace tested by a horizontal actuator at the first floor: a `zeroLength`
  element of stiffness `BRACE_K_KN_PER_MM` in direction 1 between the first floor's left joint
  (`specimen_node`) and a fixed node at the same place. The model is the whole test structure;
  `rths import opensees --specimen NODE:1 --specimen-stiffness K` takes the brace off again to leave
  the numerical substructure.
- Rayleigh damping of 2 % in the first and the third mode (`ops.eigen`).
"""

import math

import openseespy.opensees as ops

# Steel: Young's modulus (kN/mm^2) and density (kN*s^2/mm per mm^3: 7850 kg/m^3).
E_KN_PER_MM2 = 200.0
STEEL_DENSITY = 7.85e-12
# Columns (a W360x134-like section) and beams (a W530x66-like one): area mm^2, inertia mm^4.
COLUMN_AREA_MM2, COLUMN_INERTIA_MM4 = 17100.0, 4.16e8
BEAM_AREA_MM2, BEAM_INERTIA_MM4 = 8390.0, 3.51e8
# The floor's mass per length of beam (slab, finishes, live load share): 3000 kg/m.
FLOOR_MASS_PER_MM = 3.0e-6
STORY_HEIGHT_MM, BAY_WIDTH_MM = 3500.0, 6000.0
# The brace specimen's horizontal stiffness, kN/mm.
BRACE_K_KN_PER_MM = 50.0
DAMPING_RATIO = 0.02


def joint(column, floor, bays):
    """Tag of the joint node of column line `column` at floor `floor` (0: ground)."""
    return 1 + floor * (bays + 1) + column


def build(bays, stories, segments):
    """Build the frame in the current OpenSees domain; returns the specimen's node tag."""
    ops.wipe()
    ops.model("basic", "-ndm", 2, "-ndf", 3)
    for f in range(stories + 1):
        for c in range(bays + 1):
            ops.node(joint(c, f, bays), c * BAY_WIDTH_MM, f * STORY_HEIGHT_MM)
            if f == 0:
                ops.fix(joint(c, f, bays), 1, 1, 1)
    ops.geomTransf("Linear", 1)
    next_node = [joint(bays, stories, bays) + 1]
    next_element = [1]

    def member(i, j, area, inertia, mass_per_mm):
        xi, yi = ops.nodeCoord(i)
        xj, yj = ops.nodeCoord(j)
        prev = i
        for s in range(1, segments + 1):
            if s == segments:
                node = j
            else:
                node = next_node[0]
                next_node[0] += 1
                t = s / segments
                ops.node(node, xi + t * (xj - xi), yi + t * (yj - yi))
            ops.element("elasticBeamColumn", next_element[0], prev, node, area,
                        E_KN_PER_MM2, inertia, 1, "-mass", mass_per_mm)
            next_element[0] += 1
            prev = node

    column_mass = STEEL_DENSITY * COLUMN_AREA_MM2
    beam_mass = STEEL_DENSITY * BEAM_AREA_MM2 + FLOOR_MASS_PER_MM
    for f in range(stories):
        for c in range(bays + 1):
            member(joint(c, f, bays), joint(c, f + 1, bays), COLUMN_AREA_MM2,
                   COLUMN_INERTIA_MM4, column_mass)
        for c in range(bays):
            member(joint(c, f + 1, bays), joint(c + 1, f + 1, bays), BEAM_AREA_MM2,
                   BEAM_INERTIA_MM4, beam_mass)

    # The brace specimen: a horizontal spring from a fixed node to the first floor's left joint.
    specimen = joint(0, 1, bays)
    anchor = next_node[0]
    ops.node(anchor, *ops.nodeCoord(specimen))
    ops.fix(anchor, 1, 1, 1)
    ops.uniaxialMaterial("Elastic", 1, BRACE_K_KN_PER_MM)
    ops.element("zeroLength", next_element[0], anchor, specimen, "-mat", 1, "-dir", 1)

    # Rayleigh damping: DAMPING_RATIO in the first and the third mode.
    w = [math.sqrt(v) for v in ops.eigen(3)]
    w1, w3 = w[0], w[2]
    alpha_m = DAMPING_RATIO * 2.0 * w1 * w3 / (w1 + w3)
    beta_k = DAMPING_RATIO * 2.0 / (w1 + w3)
    ops.rayleigh(alpha_m, beta_k, 0.0, 0.0)
    return specimen
