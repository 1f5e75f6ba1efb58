"""Reproduce the magnetic_chain robot's curve (docs/robots.md): `python scenes/magnetic_chain/reproduce.py [--preview] [--out DIR]`.

Writes magnetic_chain.csv, magnetic_chain.png, magnetic_chain.gif and result.json (default folder runs/reproduce/magnetic_chain[-preview]).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["magnetic_chain", *sys.argv[1:]]))
