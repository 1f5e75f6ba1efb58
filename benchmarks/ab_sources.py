"""Two versions of the engine timed against each other in one run, by ``magsoro bench``:

    python benchmarks/ab_sources.py --old REV_OR_SRC [--new REV_OR_SRC] [--scenes walker beam2d]
                                    [--rounds 3] [--device cpu] [--threads 1] [--steps N] [--label NAME]

Each of ``--old`` and ``--new`` is a git revision (checked out into a temporary worktree) or a folder holding the
``magsoro`` package (a ``src`` folder); ``--new`` defaults to this checkout's ``src`` (the working tree, changes
included). The two run ``magsoro bench SCENES --json`` alternately, ``--rounds`` times each, in fresh processes
(PYTHONPATH set to the version's ``src``), so the machine's drift falls on both alike; the first round of each
compiles its kernels and is timed like the rest (Warp caches the compiled modules, the bench times after its
warm-up steps). Per scene the medians over rounds of ms/step (checked), ms/step in check windows and the ratio to
the bench's bare reference step are reported, with new/old ratios. Writes
benchmarks/results/<date>-<device>-<commit>-ab-<label>.json with the machine, both versions and every round.
"""

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from magsoro.bench.runner import _commit as commit

ROOT = Path(__file__).resolve().parents[1]


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


def _commit() -> str:
    """The checkout's commit (:func:`magsoro.bench.runner._commit`), marked '+changes' when tracked files differ."""
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return commit() + ("+changes" if dirty else "")


def _source(spec: str | None, tmp: Path, name: str) -> tuple[Path, str]:
    """The ``src`` folder of a version and how it is named in the results."""
    if spec is None:
        return ROOT / "src", f"working tree at {_commit()}"
    path = Path(spec)
    if path.is_dir():
        src = path / "src" if (path / "src" / "magsoro").is_dir() else path
        if not (src / "magsoro").is_dir():
            sys.exit(f"ab_sources: {spec}: no magsoro package there (expected {spec}/src/magsoro or {spec}/magsoro)")
        return src, f"folder {spec}"
    rev = _git("rev-parse", "--short", spec)
    if not rev:
        sys.exit(f"ab_sources: --{name} {spec}: neither a folder nor a git revision of this repository")
    tree = tmp / name
    subprocess.run(["git", "worktree", "add", "--detach", "-f", str(tree), rev], cwd=ROOT, check=True,
                   capture_output=True)
    return tree / "src", f"commit {rev}"


def _bench(src: Path, args) -> dict:
    cmd = [sys.executable, "-m", "magsoro", "bench", *args.scenes, "--json", "--device", args.device]
    if args.threads:
        cmd += ["--threads", str(args.threads)]
    if args.steps:
        cmd += ["--steps", str(args.steps)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(src)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        sys.exit(f"ab_sources: {' '.join(cmd)} with PYTHONPATH={src} failed:\n{p.stderr[-2000:]}")
    return json.loads(p.stdout[p.stdout.index("{"):])


def _summary(rounds: list[dict]) -> dict:
    out = {}
    for scene in rounds[0]["scenes"]:
        name = scene["name"]
        rows = [next(s for s in r["scenes"] if s["name"] == name) for r in rounds]

        def med(key, rows=rows):
            vals = [r[key] for r in rows if r.get(key) is not None]
            return statistics.median(vals) if vals else None

        out[name] = {"ms_per_step": med("ms_per_step"), "window_ms_per_step": med("window_ms_per_step"),
                     "ratio_to_reference": med("ratio_to_reference"),
                     "phases_ms": {k: statistics.median(r["phases_ms"][k] for r in rows)
                                   for k in rows[0].get("phases_ms", {})}}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="git revision or folder of the version to compare against")
    ap.add_argument("--new", default=None, help="git revision or folder (default: this checkout's working tree)")
    ap.add_argument("--scenes", nargs="+", default=["walker", "beam2d"])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--threads", type=int, default=0, help="CPU threads per step (0: the engine's choice)")
    ap.add_argument("--steps", type=int, default=0, help="timed steps per scene (0: the bench's default)")
    ap.add_argument("--label", default="ab", help="name of the comparison in the results file")
    args = ap.parse_args()
    if args.rounds < 1:
        sys.exit("ab_sources: --rounds must be at least 1")
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        versions = {"old": _source(args.old, tmp, "old"), "new": _source(args.new, tmp, "new")}
        rounds = {"old": [], "new": []}
        try:
            for i in range(args.rounds):
                for name in ("old", "new") if i % 2 == 0 else ("new", "old"):
                    rounds[name].append(_bench(versions[name][0], args))
                    print(f"round {i + 1} {name} done", file=sys.stderr)
        finally:
            for name in ("old", "new"):
                if str(versions[name][0]).startswith(str(tmp)):
                    subprocess.run(["git", "worktree", "remove", "--force", str(versions[name][0].parent)], cwd=ROOT,
                                   capture_output=True)
    summary = {name: _summary(rounds[name]) for name in rounds}
    ratios = {}
    for scene, new in summary["new"].items():
        old = summary["old"][scene]
        ratios[scene] = {k: (old[k] / new[k] if old[k] and new[k] else None)
                         for k in ("ms_per_step", "window_ms_per_step")}
        ratios[scene]["ratio_to_reference_new_over_old"] = (new["ratio_to_reference"] / old["ratio_to_reference"]
                                                            if old["ratio_to_reference"] else None)
    first = rounds["new"][0]
    result = {
        "what": "benchmarks/ab_sources.py: two engine versions, magsoro bench alternately in one run",
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": _commit(), "device": args.device, "device_name": first.get("device_name"),
        "machine": first.get("machine", {"node": platform.node(), "processor": platform.processor()}),
        "python": platform.python_version(), "threads": args.threads or "engine's choice",
        "old": versions["old"][1], "new": versions["new"][1], "rounds": args.rounds,
        "summary": summary, "speedup_old_over_new": ratios, "raw": rounds,
    }
    out = ROOT / "benchmarks" / "results" / (
        f"{datetime.date.today().isoformat()}-{args.device.split(':')[0]}-{_commit().replace('+', '-')}-ab-{args.label}.json")
    out.write_text(json.dumps(result, indent=1) + "\n")
    def f(x, fmt=".4g"):
        return "-" if x is None else format(x, fmt)

    for scene, r in ratios.items():
        s_old, s_new = summary["old"][scene], summary["new"][scene]
        print(f"{scene}: ms/step old {f(s_old['ms_per_step'])} new {f(s_new['ms_per_step'])} "
              f"(old/new {f(r['ms_per_step'], '.3f')}); windows old {f(s_old['window_ms_per_step'])} "
              f"new {f(s_new['window_ms_per_step'])} (old/new {f(r['window_ms_per_step'], '.3f')}); "
              f"ratio to reference old {f(s_old['ratio_to_reference'], '.3f')} new {f(s_new['ratio_to_reference'], '.3f')}")
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
