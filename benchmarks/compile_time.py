"""How long the engine's kernels take to compile on a cold cache: CUDA (PTX or CUBIN through NVRTC, no GPU needed)
and CPU (Clang), module by module.

    python benchmarks/compile_time.py [--match "engine 3D float32"] [--arch 90] [--cubin] [--cpu]

A first run on a machine compiles every engine module it launches; on a GPU the CUBIN of the 3D contact
transfers was what a lent H100 spent its calls on (benchmarks/README.md, "On a GPU"). Each module listed by
:func:`magsoro.cuda_compile.warp_modules` whose label contains ``--match`` is compiled into a fresh folder (so
Warp's kernel cache is neither read nor written), one at a time, for PTX sm_``--arch``, and with ``--cubin`` also
CUBIN, with ``--cpu`` also the CPU object. Compare two versions by running the script under each checkout's
``src`` (``PYTHONPATH=OLD/src python benchmarks/compile_time.py``) in one session. Writes
benchmarks/results/<date>-cpu-<commit>-compile-time.json with the machine and the commit.
"""

import argparse
import datetime
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--match", default="engine 3D float32", help="compile the modules whose label contains this")
    ap.add_argument("--arch", type=int, default=90, help="CUDA arch (default 90: H100, H200)")
    ap.add_argument("--cubin", action="store_true", help="also CUBIN (what a GPU run loads when NVRTC supports its arch)")
    ap.add_argument("--cpu", action="store_true", help="also the CPU object (Clang)")
    ap.add_argument("--out", default=None, help="output JSON (default benchmarks/results/<date>-cpu-<commit>-compile-time.json)")
    args = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    wp.init()
    import magsoro
    from magsoro import cuda_compile as cc
    from magsoro.bench.runner import _commit

    modules = [(label, m) for label, m in cc.warp_modules() if args.match in label]
    if not modules:
        print(f"compile_time: no module label contains {args.match!r}", file=sys.stderr)
        return 2
    targets = [("ptx", dict(device=None, arch=args.arch, use_ptx=True))]
    if args.cubin:
        targets.append(("cubin", dict(device=None, arch=args.arch, use_ptx=False)))
    if args.cpu:
        targets.append(("cpu", dict(device="cpu")))
    rows = []
    for label, module in modules:
        for target, kw in targets:
            with tempfile.TemporaryDirectory(prefix="magsoro-compile-time-") as d:
                t0 = time.perf_counter()
                wp.compile_aot_module(module, module_dir=d, **kw)
                seconds = time.perf_counter() - t0
            rows.append({"module": label, "target": target, "seconds": seconds, "kernels": len(module.kernels)})
            print(f"{label:45s} {target:5s} {seconds:8.1f} s", flush=True)
    commit = _commit()
    result = {
        "what": "cold-cache compile time of the engine's Warp modules, one at a time",
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "commit": commit,
        "magsoro_source": str(Path(magsoro.__file__).resolve().parent),
        "machine": {"node": platform.node(), "processor": platform.processor() or platform.machine(),
                    "cpu_count": os.cpu_count(), "python": platform.python_version()},
        "warp_version": wp.__version__,
        "arch": args.arch,
        "match": args.match,
        "rows": rows,
        "total_seconds": {t: sum(r["seconds"] for r in rows if r["target"] == t) for t, _ in targets},
    }
    out = Path(args.out) if args.out else ROOT / "benchmarks" / "results" / (
        f"{datetime.date.today().isoformat()}-cpu-{commit}-compile-time.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
