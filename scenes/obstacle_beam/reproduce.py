"""Reproduce the obstacle_beam robot's curve (docs/robots.md): `python scenes/obstacle_beam/reproduce.py [--preview] [--out DIR]`.

Writes obstacle_beam.csv, obstacle_beam.png, obstacle_beam.gif and result.json (default folder runs/reproduce/obstacle_beam[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["obstacle_beam", *sys.argv[1:]]))
