"""Reproduce the pentahedron-shaped robot's fold angle vs field (seed 002 sec 5.3, Fig. 16).

    python scenes/pentahedron/reproduce.py [--preview] [--out DIR]

writes pentahedron.csv, pentahedron.png, pentahedron.gif and result.json (default runs/reproduce/pentahedron).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["pentahedron", *sys.argv[1:]]))
