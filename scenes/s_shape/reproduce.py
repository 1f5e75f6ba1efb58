"""Reproduce the s_shape robot's shapes and field sweep (docs/robots.md): `python scenes/s_shape/reproduce.py [--preview] [--out DIR]`.

Writes s_shape.csv, s_shape_shapes.csv, s_shape.png, s_shape_sweep.png, s_shape.gif and result.json (default folder runs/reproduce/s_shape[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["s_shape", *sys.argv[1:]]))
