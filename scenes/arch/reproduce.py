"""Reproduce the arch-shaped robot's major-axis length vs field and its flipping (seed 002 sec 5.5, Fig. 19-20).

    python scenes/arch/reproduce.py [--preview] [--out DIR]

writes arch.csv, arch_flip.csv, arch.png, arch.gif and result.json (default runs/reproduce/arch).
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["arch", *sys.argv[1:]]))
