"""Reproduce the pentagram-shaped robot of seed 002 sec 5.2: grip closure against the flux density at the robot
(upward field, Fig. 14b) and the displacement in one pass of the magnet (downward field, Fig. 14a). Writes
pentagram.csv, pentagram.png, pentagram_crawl.csv, pentagram_crawl.png, pentagram.gif and result.json.

    python scenes/pentagram/reproduce.py [--preview] [--out DIR]
"""

if __name__ == "__main__":
    import sys

    from magsoro.robots.cli import main

    sys.exit(main(["pentagram", *sys.argv[1:]]))
