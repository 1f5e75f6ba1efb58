"""Reproduce the walker robot's curve: `python scenes/walker/reproduce.py [--preview] [--out DIR]`
(the same as `magsoro reproduce walker`; see src/magsoro/robots/walker.py and docs/robots.md)."""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["walker", *sys.argv[1:]]))
