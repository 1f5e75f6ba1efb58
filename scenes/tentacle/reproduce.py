"""Reproduce the tentacle robot's curve: `python scenes/tentacle/reproduce.py [--preview] [--out DIR]`
(the same as `magsoro reproduce tentacle`; see src/magsoro/robots/tentacle.py and docs/robots.md)."""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["tentacle", *sys.argv[1:]]))
