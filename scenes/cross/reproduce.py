"""Reproduce the cross-shaped robot of seed 002 sec 5.1: maximum strip deflection against the flux density at
the robot, arching (field down) and grabbing (field reversed) (Fig. 12). Writes cross.csv, cross.png, cross.gif
and result.json.

    python scenes/cross/reproduce.py [--preview] [--out DIR]
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["cross", *sys.argv[1:]]))
