"""Reproduce the tail_crush robot's curve (docs/robots.md): `python scenes/tail_crush/reproduce.py [--preview] [--out DIR]`.

Writes tail_crush.csv, tail_crush.png, tail_crush.gif, tail_crush_secant.csv, tail_crush_secant.png and result.json (default folder runs/reproduce/tail_crush[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["tail_crush", *sys.argv[1:]]))
