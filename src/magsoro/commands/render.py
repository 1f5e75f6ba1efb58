"""``magsoro render RUN_DIR --out FILE.(png|gif|mp4)``: pictures and animations of a run's particle series."""

from magsoro.errors import MagsoroError


def register(sub):
    p = sub.add_parser(
        "render",
        help="draw a run's particles (PNG) or animate them (GIF, MP4), headless",
        description="Draw the particle frames of a run, coloured by part, speed, strain or magnetisation, with the "
        "scene's colliders (translucent), the uniform applied field (arrow, mT), a time label and a scale bar. "
        "Uses PyVista (shaded spheres; pip install 'magsoro[render]') when it imports, else matplotlib; 2D runs "
        "are drawn flat with matplotlib. Needs no display. See docs/render.md.",
    )
    p.add_argument("directory", metavar="RUN_DIR", help="a run folder written by 'magsoro run'")
    p.add_argument("--out", required=True, help="output file: .png (one frame), .gif or .mp4 (needs ffmpeg)")
    p.add_argument("--color", "--colour", dest="color", default="part", metavar="MODE",
                   help="part (body), speed (|v|), strain (equivalent deviatoric log strain from I1bar) or "
                        "magnetisation (angle the magnetisation has turned since t = 0); default part")
    p.add_argument("--view", default=None, metavar="VIEW",
                   help="iso, x, y or z: the axis the camera looks along (default iso; 2D runs: the flat view)")
    p.add_argument("--frames", default=None, metavar="SPEC",
                   help="frames to draw: an index (0, -1), a slice (0:10:2, ::5), t=TIME (nearest frame), first, last "
                        "or all, comma-separated; default: the last frame for a .png, the whole run (at most 120 "
                        "frames, spread) for an animation")
    p.add_argument("--backend", default="auto", metavar="NAME",
                   help="auto (PyVista when importable, else matplotlib; MAGSORO_RENDER_BACKEND sets it), pyvista or "
                        "matplotlib")
    p.add_argument("--size", default="960x720", metavar="WxH", help="picture size in pixels (default 960x720)")
    p.add_argument("--fps", type=float, default=10.0, help="frames per second of an animation (default 10)")
    p.add_argument("--max-particles", type=int, default=None, metavar="N",
                   help="draw at most N particles (an evenly spaced subset; default all)")
    p.set_defaults(func=run)


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise MagsoroError(f"--size: '{text}' is not WIDTHxHEIGHT in pixels, e.g. 960x720") from None
    return w, h


def run(args) -> int:
    from magsoro.viz.render import render_run

    res = render_run(args.directory, args.out, color=args.color, view=args.view, frames=args.frames,
                     backend=args.backend, size=_size(args.size), fps=args.fps, max_particles=args.max_particles)
    for note in res.notes:
        print(f"note: {note}")
    what = "frame" if res.frames == 1 else "frames"
    print(f"{res.out}: {res.frames} {what}, {res.particles} particles, drawn with {res.backend} in {res.seconds:.1f} s")
    return 0
