"""``magsoro validate``: run the validation cases and print case, quantity, reference, simulated value, error,
tolerance and pass for every compared quantity (docs/validation.md)."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="run validation cases (closed forms, MPM beam vs Kirchhoff rod) and print a table",
        description=(
            "Run validation cases and print one row per compared quantity: case, quantity, reference, simulated "
            "value, error, tolerance, pass. Without CASE: every case (with --quick: the quick ones). Exit status "
            "0 when every row passes, 1 otherwise. See docs/validation.md."
        ),
    )
    p.add_argument("cases", nargs="*", metavar="CASE", help="case names (see --list)")
    p.add_argument("--quick", action="store_true",
                   help="only the quick cases (closed forms and the 2D beam; under 10 min on 2 CPU cores)")
    p.add_argument("--all", action="store_true",
                   help="every case, including the robot library's (robot-NAME: each robot's preview run and "
                        "acceptance checks; about 3 min each)")
    p.add_argument("--json", action="store_true",
                   help="print the rows as a JSON list (keys case, quantity, inputs, reference, value, error, "
                        "tolerance, passed); progress goes to stderr")
    p.add_argument("--out", metavar="DIR", help="write a PNG plot per case and results.json into DIR")
    p.add_argument("--list", action="store_true", help="list the cases and exit")
    p.set_defaults(func=run_validate)


def run_validate(args) -> int:
    from magsoro.validation import CASES, run_validation, select_cases
    from magsoro.validation.report import json_rows, text_table

    if args.list:
        for case in CASES.values():
            tag = "quick" if case.quick else ("robot" if case.group == "robots" else "full ")
            print(f"{case.name:18s} {tag} {case.cost:>10s}  {case.summary}")
        return 0
    try:
        select_cases(args.cases, args.quick, args.all)
    except KeyError as exc:
        print(f"magsoro validate: error: {exc.args[0]}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    t0, c0 = time.perf_counter(), time.process_time()
    # stdout carries only the table or the JSON: anything the engine or Warp prints while the cases run
    # (kernel compilation notices) goes to stderr
    with contextlib.redirect_stdout(sys.stderr):
        results = run_validation(args.cases, quick=args.quick, out=out, all_cases=args.all)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rows = [r for res in results for r in res.rows]
    if out is not None:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=Path(__file__).resolve().parent).stdout.strip()
        summary = {
            "quick": bool(args.quick),
            "argv": sys.argv[1:],
            "wall_s": round(wall, 1),
            "cpu_s": round(cpu, 1),  # wall time on shared cores overstates the cost
            "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "commit": commit,
            "cases": [{"case": res.case, "wall_s": round(res.wall_s, 1), "passed": res.passed, "info": res.info,
                       "figures": [str(f) for f in res.figures]} for res in results],
            "rows": [r.as_dict() for r in rows],
        }
        (out / "results.json").write_text(json.dumps(summary, indent=1))
    if args.json:
        print(json_rows(rows))
    else:
        print(text_table(rows))
        failed = sum(not r.passed for r in rows)
        print(f"\n{len(rows) - failed}/{len(rows)} rows pass; "
              + ", ".join(f"{res.case} {res.wall_s:.0f} s" for res in results) + f"; {wall:.0f} s in all")
    return 0 if rows and all(r.passed for r in rows) else 1
