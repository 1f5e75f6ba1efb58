"""Reproduce the arch-shaped robot of seed 002 sec 5.5 flipping over under the paper's actuator, turned over and
10 mm to the side, rising at a hand's speed, by the implicit integrator: the field level at which the arch flips
and how long the flip takes at 5, 10 and 20 mm/s. Writes arch_flip_speeds.csv and .png, the net moment through
the flip (arch_flip_course.csv and .png), pictures of the flip (arch_flip_views.png) and result.json.

    python scenes/arch_flip/reproduce.py [--preview] [--out DIR]
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["arch_flip", *sys.argv[1:]]))
