"""A 5-bay, 12-story steel frame (members in 4 elements each, 1,404 DOFs, 936 with mass) with a
brace specimen at node 7 (the first floor's left joint). See steel_frame.py."""
from steel_frame import build

RTHS_UNITS = "mm-kn"
build(bays=5, stories=12, segments=4)
