"""Write docs/robots.md (the robot gallery) from the robot registry and docs/robots/NAME/result.json.

    python scripts/make_robot_gallery.py            # after: magsoro reproduce NAME --out docs/robots/NAME

On top of ``magsoro.robots.gallery.gallery_markdown`` this script

- says where the committed results' provenance is (the "Engine of the results" paragraph, ``ENGINE`` below: each
  result.json's ``run`` and ``history``);
- shows a robot's 3D picture drawn by ``magsoro render`` when docs/robots/NAME/NAME_3d.png is present (and
  NAME_3d.gif beside it), with a one-line caption written from docs/robots/NAME/NAME_3d.json: which run it was
  drawn from (``magsoro run scenes/NAME.toml``, full resolution or ``--preview``), the colour mode, the view and
  the frame. ``magsoro reproduce`` keeps no particle frames (it runs the scene in memory), so these pictures come
  from a separate run of the robot's scene.
"""

import json
import re
import sys
from pathlib import Path

from magsoro.robots.gallery import gallery_markdown

ENGINE = """Engine of the results: each robot's `docs/robots/NAME/result.json` says where its result came from:
`run` (the date, commit and machine of the reproduction, recorded from 2026-11-30 on) and `history` (when and with
which engine it was made or re-run, and what changed). Engine changes committed after a result was made are not
in it.

The 3D robots' entries also show a picture and an animation drawn by `magsoro render` from one run of the robot's
scene (`magsoro run scenes/NAME.toml`): `magsoro reproduce` keeps no particle frames, so that run is separate from
the reproduction, and its caption says whether it was a full-resolution or a `--preview` run.

Speeds under a moving magnet (seed 002 reports them). The triangle's and the cross's are measured by their
reproductions (`magsoro reproduce triangle`, `magsoro reproduce cross`: NAME_speeds.csv and .png, shown in their
sections below), the pentagram's and the arch's by theirs. The actuator is the paper's (sec 4.1: disc r 50 mm,
10 mm thick, 50 mT at its face centre, under the ~1 mm plate); the paper gives no magnet speed, so each is
reported with the magnet speeds used.

| quantity | paper | ours | gap |
|---|---|---|---|
| triangle warping speed (vertex rise, magnet rising under it) | 9 mm/s | 9.9 / 19.6 / 39.8 mm/s at 50 / 100 / 200 mm/s (dx 1 mm); 0.2 x the magnet speed | the shape follows the magnet quasi-statically: 9 mm/s needs a magnet at ~46 mm/s (in proportion; not run) |
| triangle locomotion speed (magnet passing from beyond a vertex to beyond the opposite side) | 1.5 mm/s | moves with the magnet: 37.3 / 39.4 mm/s (63.4 / 33.5 mm per pass) at 100 / 200 mm/s (dx 1 mm) | no lift-and-push gait: pushed or dragged, sliding, by the magnet's rim; at 20 mm/s (implicit integrator) the rim pushes it ahead for the whole pass |
| triangle locomotion, one stroke at a hand's speed (magnet up under a vertex, level to under the opposite side, down; implicit integrator; [triangle_stroke](#triangle_stroke)) | 1.5 mm/s | +0.81 / +0.80 / +0.81 mm per stroke at 5 / 10 / 20 mm/s (dx 1 mm); +1.21 mm at 20 mm/s on the preview grid (dx 2 mm) | arch and push as in Fig. 4, independent of the magnet's speed; 0.20 mm/s over our 183 mm stroke at the magnet speed of the paper's warping speed (45 mm/s; the paper gives neither the stroke's path nor its time); the two grids 50 % apart (one and two cells through the plate): the one-cell grid bends too softly, since the static warp at 45 mT changes by 0.35 % from two to three cells through the plate (8.360 and 8.389 mm; benchmarks/README.md) |
| cross arching speed (field down) | 4.8 mm/s | 4.4 / 8.8 / 17.8 mm/s at 50 / 100 / 200 mm/s (dx 1 mm); ~0.09 x the magnet speed | quasi-static: 4.8 mm/s with the magnet rising at 55 mm/s |
| cross grabbing speed (field reversed) | 3.5 mm/s | 4.0 / 7.9 / 15.9 mm/s at 50 / 100 / 200 mm/s (dx 1 mm) | quasi-static: 3.5 mm/s needs a magnet below 50 mm/s (~44 mm/s in proportion; not run) |
| cross arching and grabbing at a hand's speed (magnet rising under the centre; implicit integrator; [cross_rise](#cross_rise)) | 4.8 / 3.5 mm/s | arching 0.44 / 0.88 / 1.75 mm/s and grabbing 0.40 / 0.79 / 1.58 mm/s at 5 / 10 / 20 mm/s (dx 1 mm): 0.088 and 0.079 x the magnet speed, as the explicit engine's at 50-200 mm/s | quasi-static from 5 to 200 mm/s: the paper's speeds need a magnet rising at 55 and 44 mm/s; at the top 5.70 and 5.64 mm against the explicit engine's 5.67 and 5.65 mm; dx 1 and 0.5 mm (four cells through the strips) within 1.6 and 1.4 % (5.61 and 5.56 mm at dx 0.5 mm), the preview grid (one cell) 55 % off |
| pentagram crawling speed | 3.5 mm/s | moves with the magnet: +54.4 mm per pass at 200 mm/s (reproduction), +53.6 and +55.9 mm at 50 and 25 mm/s (`python scripts/pentagram_magnet_speed.py 50`, preview resolution): 54, 13.4 and 7.0 mm/s, 0.27-0.28 x the magnet's | folded into a heap and carried by the magnet's rim, not the gait of Fig. 14a; at 25 mm/s within a factor of 2 of 3.5 mm/s, by being carried. With hinges of 1, 3 and 5 mm at 200 and 50 mm/s (reproduction, [pentagram](#pentagram)): +54.3 to +64.7 mm per pass, folded every time; strip 1's part 2 stands up over a resting part 3 (the arch of Fig. 14a1) in two runs (1 and 5 mm hinges at 50 mm/s), with the other strips already folded over the hub; the table of Fig. 14a3 in none |
| arch flip time (magnet brought up from far below in 0.1 s; explicit engine; [arch](#arch)) | 0.5 s | 0.02 s after the field reaches 45 mT (reproduction) | the paper does not say how fast its magnet approached |
| arch flip at a hand's speed (magnet turned over, rising 10 mm to the side; implicit integrator; [arch_flip](#arch_flip)) | 0.5 s | flips from 9.57 / 9.70 / 9.91 mT in 0.40 / 0.32 / 0.30 s at 5 / 10 / 20 mm/s (dx 0.5 mm); the explicit engine 9.90 / 10.35 / 10.97 / 11.86 mT in 0.32 / 0.29 / 0.29 / 0.25 s at 20 / 50 / 100 / 200 mm/s | within the paper's 0.5 s at every speed; the level grows as the speed to the 2/3 (a fold passed at a finite rate), the same law for both engines, which agree at 20 mm/s to 0.1 % (level) and 7 % (time); dx 0.5 and 0.25 mm (4 and 8 cells through the arch) within 0.4 % (9.91 and 9.95 mT) |"""

_ENGINE_RE = re.compile(r"^Engine of the results:.*?(?=\n\n|\n\| robot)", flags=re.MULTILINE | re.DOTALL)


def _seconds(t: float) -> str:
    return f"{t:g} s" if t >= 1 else f"{t * 1e3:.0f} ms"


def _frames(spec: str, meta: dict) -> str:
    """Words for a ``magsoro render --frames`` spec as the pictures were drawn (``last``, ``t=...``, ``all``,
    ``::k``)."""
    total, end = meta.get("frames_in_run"), meta.get("simulated_s")
    if spec in ("last", "-1") and end is not None:
        return f"last frame (t = {_seconds(end)})"
    if spec.startswith("t="):
        return f"frame nearest t = {_seconds(float(spec[2:]))}"
    count = meta.get("gif_frame_count")
    if spec == "all" and total:
        return f"all {total} frames"
    if spec.startswith("::") and total and count:
        return f"{count} of {total} frames (every {spec[2:]})"
    return f"frames `{spec}`"


def render_block(docs_dir: Path, name: str) -> list[str]:
    """Markdown lines showing robots/NAME/NAME_3d.gif and NAME_3d.png with a one-line caption from
    NAME_3d.json, or [] when there is no NAME_3d.png."""
    folder = Path(docs_dir) / "robots" / name
    png, gif, meta_path = (folder / f"{name}_3d{ext}" for ext in (".png", ".gif", ".json"))
    if not png.is_file():
        return []
    meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    lines = []
    if gif.is_file():
        lines += [f"![{name} in 3D (animation)](robots/{name}/{gif.name})", ""]
    lines += [f"![{name} in 3D](robots/{name}/{png.name})", ""]
    run = meta.get("run")
    which = {"full": "a full-resolution run", "preview": "a `--preview` run (the scene's coarse [preview] settings)"}
    src = f"{which.get(run, 'a run')} of `scenes/{name}.toml`"
    facts = [f"`{meta['run_command']}`"] if meta.get("run_command") else []
    if meta.get("particles"):
        facts.append(f"{meta['particles']} particles")
    if meta.get("simulated_s") is not None:
        facts.append(f"{_seconds(meta['simulated_s'])} simulated")
    if meta.get("run_wall_s") is not None:
        facts.append(f"{meta['run_wall_s']:.0f} s wall on the 2-core CPU")
    how = f"colour `{meta.get('color', 'part')}`, view `{meta.get('view', 'iso')}`"
    if meta.get("png_frames"):
        how += f"; picture: {_frames(meta['png_frames'], meta)}"
    if gif.is_file() and meta.get("gif_frames"):
        how += f"; animation: {_frames(meta['gif_frames'], meta)}"
    note = f" {meta['note']}" if meta.get("note") else ""
    caption = (f"*3D view drawn by `magsoro render` (PyVista) from {src} ({', '.join(facts)}), not from the "
               f"reproduction. {how[0].upper() + how[1:]}.{note}*")
    lines += [caption, ""]
    return lines


def robot_gallery_markdown(docs_dir: Path) -> str:
    text = gallery_markdown(docs_dir)
    if _ENGINE_RE.search(text):
        text = _ENGINE_RE.sub(lambda m: ENGINE, text, count=1)
    else:
        print("note: no 'Engine of the results' paragraph found in gallery_markdown's output; left as it is",
              file=sys.stderr)
    out, name = [], None
    for line in text.split("\n"):
        m = re.match(r"^## (\w+)$", line)
        if m:
            name = m.group(1)
        if name is not None and line.startswith(f"Reproduce: `magsoro reproduce {name}`"):
            out += render_block(docs_dir, name)
        out.append(line)
    return "\n".join(out)


def write_robot_gallery(docs_dir: Path) -> Path:
    from magsoro.io.files import atomic_write_text

    path = Path(docs_dir) / "robots.md"
    atomic_write_text(path, robot_gallery_markdown(docs_dir))
    return path


if __name__ == "__main__":
    print(write_robot_gallery(Path(__file__).resolve().parents[1] / "docs"))
