"""Reproduce the gripper robot's curve: `python scenes/gripper/reproduce.py [--preview] [--out DIR]`
(the same as `magsoro reproduce gripper`; see src/magsoro/robots/gripper.py and docs/robots.md)."""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["gripper", *sys.argv[1:]]))
