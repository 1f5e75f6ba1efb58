"""Reproduce the triangular robot of seed 002 sec 4: vertex warp height W_t and centroid height H_t against the
flux density at the robot (Figs. 6, 9). Writes triangle.csv, triangle.png, triangle.gif and result.json.

    python scenes/triangle/reproduce.py [--preview] [--out DIR]
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["triangle", *sys.argv[1:]]))
