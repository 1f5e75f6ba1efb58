"""Reproduce the continuum_discrete robot's curve (docs/robots.md): `python scenes/continuum_discrete/reproduce.py [--preview] [--out DIR]`.

Writes continuum_discrete.csv, continuum_discrete.png, continuum_discrete.gif and result.json (default folder runs/reproduce/continuum_discrete[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["continuum_discrete", *sys.argv[1:]]))
