"""Reproduce the bistable_arch robot's curve (docs/robots.md): `python scenes/bistable_arch/reproduce.py [--preview] [--out DIR]`.

Writes bistable_arch.csv, bistable_arch.png, bistable_arch.gif and result.json (default folder runs/reproduce/bistable_arch[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["bistable_arch", *sys.argv[1:]]))
