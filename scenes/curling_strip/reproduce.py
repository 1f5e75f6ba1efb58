"""Reproduce the curling_strip robot's curve (docs/robots.md): `python scenes/curling_strip/reproduce.py [--preview] [--out DIR]`.

Writes curling_strip.csv, curling_strip.png, curling_strip.gif and result.json (default folder runs/reproduce/curling_strip[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["curling_strip", *sys.argv[1:]]))
