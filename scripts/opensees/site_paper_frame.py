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
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from site_frame import run  # noqa: E402 (after the path)


def main():
    run(stories=1, clients=1,
        elastic_help="the brace as an elastic element of this stiffness (kN/mm) instead")


if __name__ == "__main__":
    main()
