"""Write docs/robots.md (the robot gallery) from the robot registry and docs/robots/NAME/result.json.

    python scripts/make_robot_gallery.py            # after: magsoro reproduce NAME --out docs/robots/NAME

On top of ``magsoro.robots.gallery.gallery_markdown`` this script

- states which engine produced the committed results (the "Engine of the results" paragraph, ``ENGINE`` below:
  edit it when results are re-run);
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

ENGINE = """Engine of the results: every result was computed with the engine of issue "Engine 2.0"
or a later one (scene default `formulation = "auto"`: total Lagrangian for one body, updated with contact;
frictional contact between bodies with free separation; self-contact where a scene asks for it). walker was
re-run with it and magnetic_chain was made on 2026-11-24; gripper and pentagram were re-run on 2026-11-26 with the
contact law of commit a03a409 (a minimum mass fraction at contact nodes between bodies): gripper at commit 47cb910
on one core shared with other jobs (hence its wall time), pentagram with its magnet under the plate (commit
71a6c38), and arch once more at commit 52e7539 (the same result; its summary now says why it saturates); bistable_arch, curling_strip,
c_shape, l_shape and s_shape were made on 2026-11-26. On 2026-11-26 (the repository between commits 8547b65 and
9d708e2) arch, cross, obstacle_beam, pentahedron, strip_magnet and triangle were re-run in full, and
continuum_discrete, continuum_soft and tentacle were redone once their reproductions solved the field levels with
the static solver. Later on 2026-11-26 cross and triangle were re-run in full with their speeds under the moving
magnet (commits d4e276a and f543fcc; their field sweeps came out as before), and hexahedron, whose result had
predated "Engine 2.0", at commit d05a375 (974 s on one core; beta at 45 mT 45.9 deg against 46.8 deg with the old
engine). Later still, pentagram was re-run once its domain was widened to x = -80 mm (commit 3bd8e1b: a strip had
come within the walls' reach at -50 mm; crawl +54.45 mm against +54.4, the grip unchanged; 417 s beside the test
suite). obstacle_beam was redone once its reproduction solved the field levels with the static solver, whose
colliders now meet the beam's surface (49 s against 174 s; one level, 10 mT, also settled by the dynamics as a
check: 0.4 % apart). Against the gallery's earlier dynamic sweep of the same scene, the pressed twin differs by
+10.4 % at 3 mT, +2.4 % at 6 mT, +0.75 % at 10 mT and within 0.5 % above: at first touch the engine's node contact
holds the beam about a cell (1.5 mm) off the pin, and it comes to the surface only as the contact is pressed
(particle centres 1.56, 1.20, 0.92, 0.61, 0.37 mm from the pin at 3-20 mT; their radius is 0.375 mm).
strip_magnet was redone once its reproduction solved each magnet gap with the static solver (184 s against 579 s
for the dynamic sweep; the strain 0.4-0.7 % below the dynamic sweep's at every gap, e.g. 7.29 % against 7.35 %
at 37 mm). tail_crush and tail_pull (seed 004's bench tests of the everted growing robot) were made on
2026-11-28 with the engine of commit 0641bf2 (the contact classification that no longer crashes with self-contact
beside two contact groups); tail_crush's checks and summary were recomputed from its committed CSV after two
corrections to the report (commit abb6c58). triangle and cross were re-run in full on 2026-11-28 once their field
sweeps were solved by the static solver along the magnet's path (triangle at commit cec654f, cross at 4985439; the
speeds under the moving magnet by the dynamics, as before): triangle 2069 s
against 2184 s (the sweep 123 s against 243 s; W_t and H_t within 1.2 % of the dynamic sweep's from 15 to 45 mT,
W_t 22 % and 5 % below at 5 and 10 mT), cross 791 s against 886 s (the two sweeps 70 s against 143 s); every check
still passes. everting_tube (seed 004's tube everted in axisymmetric MPM) was made on 2026-11-30 at commit
a0da799, the implicit integrator without contact rounds on self-contact: 1820 s, with the test suite running on the
second core for most of it. Engine changes committed after a result was made are not in it.

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
| triangle locomotion speed (magnet from a vertex to the opposite side) | 1.5 mm/s | moves with the magnet: 37.3 / 39.4 mm/s (63.4 / 33.5 mm per pass) at 100 / 200 mm/s (dx 1 mm) | no lift-and-push gait: pushed or dragged, sliding, by the magnet's rim; 1.5 mm/s not reached |
| cross arching speed (field down) | 4.8 mm/s | 4.4 / 8.8 / 17.8 mm/s at 50 / 100 / 200 mm/s (dx 1 mm); ~0.09 x the magnet speed | quasi-static: 4.8 mm/s with the magnet rising at 55 mm/s |
| cross grabbing speed (field reversed) | 3.5 mm/s | 4.0 / 7.9 / 15.9 mm/s at 50 / 100 / 200 mm/s (dx 1 mm) | quasi-static: 3.5 mm/s needs a magnet below 50 mm/s (~44 mm/s in proportion; not run) |
| pentagram crawling speed | 3.5 mm/s | moves with the magnet: +54.4 mm per pass at 200 mm/s (reproduction), +53.6 and +55.9 mm at 50 and 25 mm/s (`python scripts/pentagram_magnet_speed.py 50`, preview resolution): 54, 13.4 and 7.0 mm/s, 0.27-0.28 x the magnet's | folded into a heap and carried by the magnet's rim, not the gait of Fig. 14a; at 25 mm/s within a factor of 2 of 3.5 mm/s, by being carried |
| arch flip time | 0.5 s | 0.02 s after the field reaches 45 mT (reproduction) | the paper does not say how fast its magnet approached |"""

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
