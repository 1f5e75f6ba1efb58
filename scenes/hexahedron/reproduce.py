"""Reproduce the hexahedron-shaped robot's closure angle vs field (seed 002 sec 5.4, Fig. 18).

    python scenes/hexahedron/reproduce.py [--preview] [--out DIR]

writes hexahedron.csv, hexahedron.png, hexahedron.gif and result.json (default runs/reproduce/hexahedron).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["hexahedron", *sys.argv[1:]]))
