"""Reproduce the triangular robot of seed 002 sec 4.2 under one stroke of the paper's actuator at a hand's speed
(Fig. 4c), by the implicit integrator: displacement per stroke at 5, 10 and 20 mm/s. Writes triangle_stroke.csv,
triangle_stroke.png, the stroke's course and side views, and result.json.

    python scenes/triangle_stroke/reproduce.py [--preview] [--out DIR]
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["triangle_stroke", *sys.argv[1:]]))
