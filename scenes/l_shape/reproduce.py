"""Reproduce the l_shape robot's shapes and field sweep (docs/robots.md): `python scenes/l_shape/reproduce.py [--preview] [--out DIR]`.

Writes l_shape.csv, l_shape_shapes.csv, l_shape.png, l_shape_sweep.png, l_shape.gif and result.json (default folder runs/reproduce/l_shape[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["l_shape", *sys.argv[1:]]))
