"""Reproduce the cross-shaped robot of seed 002 sec 5.1 arching and grabbing under the paper's actuator rising at
a hand's speed, by the implicit integrator: the strips' deflection rate at 5, 10 and 20 mm/s. Writes
cross_rise_speeds.csv and .png, the deflection against the magnet's height (cross_rise_course.csv and .png), and
result.json.

    python scenes/cross_rise/reproduce.py [--preview] [--out DIR]
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["cross_rise", *sys.argv[1:]]))
