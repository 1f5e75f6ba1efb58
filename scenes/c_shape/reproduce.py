"""Reproduce the c_shape robot's shapes and field sweep (docs/robots.md): `python scenes/c_shape/reproduce.py [--preview] [--out DIR]`.

Writes c_shape.csv, c_shape_shapes.csv, c_shape.png, c_shape_sweep.png, c_shape.gif and result.json (default folder runs/reproduce/c_shape[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["c_shape", *sys.argv[1:]]))
