"""``magsoro live SCENE.toml [--port P]``: run a scene with a live 3D view and field sliders in the browser."""

import math
import os
import sys
import threading

from magsoro.errors import SceneError, Terminated


def register(sub):
    p = sub.add_parser(
        "live", help="run a scene with a live view and field controls in the browser",
        description="Run a scene and serve a page on 127.0.0.1 with a 3D view of the particles as they move, sliders "
                    "for the uniform field's magnitude and direction and for each non-uniform source's strength, "
                    "pause, step, reset and the speed of the run, the colliders and the floor, colours by part, speed, "
                    "strain or magnetisation, a live plot of a probe, and moving and turning each magnet source. With "
                    "--out DIR the page can save its settings as a scene file and record frames into a run folder "
                    "(magsoro render and report read it), both inside DIR; without it nothing is written to disk. "
                    "Stops on Ctrl-C or when the page is closed (docs/live.md).")
    p.add_argument("scene", help="scene file (TOML)")
    p.add_argument("--port", type=int, default=8765, help="port on 127.0.0.1 (default 8765; 0: any free port)")
    p.add_argument("--no-browser", action="store_true", help="print the address only; do not open a browser")
    p.add_argument("--device", help="cpu, cuda or cuda:N (overrides simulation.device)")
    p.add_argument("--preview", action="store_true", help="use the scene's [preview] settings (coarser grid)")
    p.add_argument("--paused", action="store_true", help="start paused (press Resume on the page)")
    p.add_argument("--max-field", type=float, help="top of the |B| slider, T (default: twice the scene's uniform "
                   "field, at least 0.02 T); the time step allows for it")
    p.add_argument("--max-gain", type=float, default=2.0, help="top of the source-strength sliders (default 2)")
    p.add_argument("--max-points", type=int, default=20000, help="particles sent to the page, at most 20000 (default)")
    p.add_argument("--out", metavar="DIR", help="folder the page may write into (made when missing): 'Save as scene' "
                   "writes DIR/NAME.toml, 'Record' a run folder DIR/record_NNN; nothing else is written, and nothing "
                   "there is replaced")
    p.add_argument("--idle-timeout", type=float, default=75.0,
                   help="stop after this many seconds without a request from the page (default 75)")
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.scene import load_scene
    from magsoro.viz.live import LiveServer

    if args.device is not None and not (args.device == "cpu" or args.device.startswith("cuda")):
        raise SceneError(f"--device: '{args.device}' is not allowed; use cpu, cuda or cuda:N")
    if not 1 <= args.max_points <= 20000:
        raise SceneError(f"--max-points: must be in [1, 20000], got {args.max_points}")
    for flag, v in (("--max-field", args.max_field), ("--max-gain", args.max_gain), ("--idle-timeout", args.idle_timeout)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise SceneError(f"{flag}: must be a finite number > 0, got {v}")
    scene = load_scene(args.scene, preview=args.preview)
    server = LiveServer(scene, args.scene, port=args.port, device=args.device, max_points=args.max_points,
                        max_field=args.max_field, max_gain=args.max_gain, idle_timeout=args.idle_timeout,
                        paused=args.paused, out_dir=args.out)
    server.start()
    n, shown = server.session.sim.model.n_particles, len(server.session.index)
    print(f"magsoro live: {scene.name or args.scene}, {n} particles" + (f" ({shown} shown)" if shown < n else ""), flush=True)
    if server.session.out_dir is not None:
        print(f"magsoro live: saved scenes and recordings go into {server.session.out_dir}", flush=True)
    print(f"magsoro live: open {server.url}  (Ctrl-C stops)", flush=True)
    if not args.no_browser:
        _open_browser(server.url)
    try:
        reason = server.wait()
    except KeyboardInterrupt as exc:
        signum = exc.signum if isinstance(exc, Terminated) else None
        server.close("stopped by " + ("Ctrl-C" if signum is None else exc.signame))
        print(f"magsoro live: {server.session.stop_reason}; stopped at t = {server.session.sim.time:.6g} s", flush=True)
        return 0 if signum is None else 128 + signum
    print(f"magsoro live: {reason}; stopped at t = {server.session.sim.time:.6g} s", flush=True)
    return 0


def _open_browser(url: str) -> None:
    """Open ``url`` in a graphical browser when there is one: on Linux only with a display (a console browser
    would take over the terminal), in a thread (some launchers block)."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        print("magsoro live: no display; open the address above in a browser", flush=True)
        return
    import webbrowser

    try:
        browser = webbrowser.get()
    except webbrowser.Error:
        print("magsoro live: no browser found; open the address above in one", flush=True)
        return
    threading.Thread(target=browser.open, args=(url,), daemon=True).start()
