"""Reproduce the strip_magnet robot's curve (docs/robots.md): `python scenes/strip_magnet/reproduce.py [--preview] [--out DIR]`.

Writes strip_magnet.csv, strip_magnet.png, strip_magnet.gif and result.json (default folder runs/reproduce/strip_magnet[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["strip_magnet", *sys.argv[1:]]))
