"""``magsoro docs scenes``: print the scene-file reference generated from the pydantic models."""

import sys


def register(sub):
    p = sub.add_parser("docs", help="print generated reference documentation")
    p.add_argument("topic", choices=["scenes"], help="which reference: scenes (docs/scenes.md)")
    p.add_argument("--out", help="write to this file instead of standard output")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.scene.docs import scene_reference

    text = scene_reference()
    if args.out:
        from magsoro.io.files import atomic_write_text

        atomic_write_text(args.out, text)
    else:
        sys.stdout.write(text)
    return 0
