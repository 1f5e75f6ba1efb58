"""Write docs/robots.md (the robot gallery) from the robot registry and docs/robots/NAME/result.json.

    python scripts/make_robot_gallery.py            # after: magsoro reproduce NAME --out docs/robots/NAME
"""

from pathlib import Path

from magsoro.robots.gallery import write_gallery

if __name__ == "__main__":
    print(write_gallery(Path(__file__).resolve().parents[1] / "docs"))
