"""A 1-bay, 1-story steel frame (members in 2 elements each, 15 DOFs, 10 with mass) with a brace
specimen at node 3 (the first floor's left joint): the small end of the firmware's reduced-model
budget. See steel_frame.py."""
from steel_frame import build

RTHS_UNITS = "mm-kn"
build(bays=1, stories=1, segments=2)
