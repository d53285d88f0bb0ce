"""A 2-bay, 4-story steel frame (members in 3 elements each, 156 DOFs, 104 with mass) with a brace
specimen at node 4 (the first floor's left joint): the middle size of the firmware's reduced-model
budget. See steel_frame.py."""
from steel_frame import build

RTHS_UNITS = "mm-kn"
build(bays=2, stories=4, segments=3)
