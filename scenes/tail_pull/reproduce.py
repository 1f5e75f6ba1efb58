"""Reproduce the tail_pull robot's curve (docs/robots.md): `python scenes/tail_pull/reproduce.py [--preview] [--out DIR]`.

Writes tail_pull.csv, tail_pull.png, tail_pull.gif and result.json (default folder runs/reproduce/tail_pull[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["tail_pull", *sys.argv[1:]]))
