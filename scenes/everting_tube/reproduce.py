"""Reproduce the everting_tube robot's curve (docs/robots.md): `python scenes/everting_tube/reproduce.py [--preview] [--out DIR]`.

Writes everting_tube.csv, everting_tube.png, everting_tube.gif, the growth and section figures and result.json (default folder runs/reproduce/everting_tube[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["everting_tube", *sys.argv[1:]]))
