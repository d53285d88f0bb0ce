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
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from site_frame import run  # noqa: E402 (after the path)


def main():
    run(stories=3, clients=2,
        elastic_help="every brace an elastic element of this stiffness (kN/mm); also the third story's")


if __name__ == "__main__":
    main()
