"""A 2-bay, 3-story steel frame (members in 2 elements each, 72 DOFs) with a brace specimen at node 4
(the first floor's left joint), for rths's fast tests. See steel_frame.py."""
from steel_frame import build

RTHS_UNITS = "mm-kn"
build(bays=2, stories=3, segments=2)
