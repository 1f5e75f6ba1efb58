"""``magsoro epm-pose``: external permanent magnet pose giving a wanted field (dipole inverse, seed 004 eqs 14-16)."""

import json
import sys

import numpy as np

from magsoro.errors import MagsoroError


def register(sub):
    p = sub.add_parser(
        "epm-pose",
        help="external magnet pose that gives a wanted field at a point",
        description=(
            "Position and moment vector of an external permanent magnet (point dipole of moment M) producing "
            "the field (BX, BY, BZ) at a point (seed 004 eqs 14-16). Default: the axial pose, magnet behind the "
            "point along -B and moment along B."
        ),
    )
    p.add_argument("--field", nargs=3, type=float, required=True, metavar=("BX", "BY", "BZ"), help="wanted field, tesla")
    p.add_argument("--moment", type=float, required=True, metavar="M", help="magnet dipole moment magnitude, A m^2")
    p.add_argument("--at", nargs=3, type=float, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"), help="point where the field is wanted, metres (default origin)")
    p.add_argument("--distance", type=float, metavar="D", help="required magnet-to-point distance, metres (default: free)")
    p.add_argument("--zero-component", choices=["x", "y", "z"], help="among valid poses, keep this field component flattest around the point")
    p.add_argument("--json", action="store_true", help='print {"position": [x, y, z], "moment": [mx, my, mz]}')
    p.set_defaults(func=run)


def run(args) -> int:
    from magsoro.fields.epm import distance_range, epm_pose

    field = np.asarray(args.field, dtype=float)
    try:
        pose = epm_pose(field, args.moment, at=args.at, distance=args.distance, zero_component=args.zero_component)
    except ValueError as exc:
        raise MagsoroError(str(exc)) from None
    if args.json:
        print(json.dumps(pose.as_dict()))
        return 0
    at = np.asarray(args.at, dtype=float)
    achieved = pose.field(at)[0]
    d_min, d_max = distance_range(float(np.linalg.norm(field)), args.moment)
    out = sys.stdout
    print(f"magnet position  [m]     : {np.array2string(pose.position, precision=6)}", file=out)
    print(f"magnet moment    [A m^2] : {np.array2string(pose.moment, precision=6)}", file=out)
    print(f"distance to point [m]    : {np.linalg.norm(pose.position - at):.6g} (possible {d_min:.6g} .. {d_max:.6g})", file=out)
    print(f"field at point   [T]     : {np.array2string(achieved, precision=6)} (dipole model)", file=out)
    return 0
