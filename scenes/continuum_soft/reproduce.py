"""Reproduce the continuum_soft robot's curve (docs/robots.md): `python scenes/continuum_soft/reproduce.py [--preview] [--out DIR]`.

Writes continuum_soft.csv, continuum_soft.png, continuum_soft.gif and result.json (default folder runs/reproduce/continuum_soft[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["continuum_soft", *sys.argv[1:]]))
