"""Reproduce the growing_retroflexion robot's curve (docs/robots.md): `python scenes/growing_retroflexion/reproduce.py [--preview] [--out DIR]`.

Writes growing_retroflexion.csv, growing_retroflexion.png, growing_retroflexion.gif and result.json (default folder runs/reproduce/growing_retroflexion[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["growing_retroflexion", *sys.argv[1:]]))
