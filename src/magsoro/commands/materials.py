"""``magsoro materials list|show NAME``: the material library, with sources and what was measured."""

import json
import sys

from magsoro.errors import MagsoroError


class MaterialsError(MagsoroError):
    pass


def register(sub):
    p = sub.add_parser("materials", help="list or show material library entries", description="Material library: built-in silicone/NdFeB composites (seed 001 Table II, seed 000) plus user TOML files.")
    p.add_argument("action", choices=["list", "show"], help="list: one line per entry; show: every value with its source")
    p.add_argument("name", nargs="?", help="entry name (for show)")
    p.add_argument("--library", action="append", default=[], metavar="FILE", help="user library TOML ([[materials]] entries); may repeat")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def _fmt(v, unit="", scale=1.0, digits=4):
    return "-" if v is None else f"{v * scale:.{digits}g}{unit}"


def run(args) -> int:
    from magsoro.materials import MaterialLibraryError, get_material, load_library

    try:
        lib = load_library(args.library)
        if args.action == "list":
            if args.name:
                raise MaterialsError("'list' takes no name; use 'magsoro materials show NAME'")
            if args.json:
                sys.stdout.write(json.dumps([e.as_dict() for e in lib.values()], indent=1) + "\n")
                return 0
            rows = [("name", "density kg/m3", "G kPa", "E kPa", "Br mT", "origin")]
            for e in lib.values():
                rows.append((e.name, _fmt(e.density, digits=5), _fmt(e.shear_modulus, scale=1e-3), _fmt(e.youngs_modulus, scale=1e-3), _fmt(e.remanence, scale=1e3, digits=3), e.origin))
            widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
            for r in rows:
                print("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
            return 0
        if not args.name:
            raise MaterialsError("'show' needs an entry name; see 'magsoro materials list'")
        e = get_material(args.name, lib)
    except MaterialLibraryError as exc:
        raise MaterialsError(str(exc)) from None
    if args.json:
        sys.stdout.write(json.dumps(e.as_dict(), indent=1) + "\n")
        return 0

    def status(key):
        return "measured" if key in e.measured else ("estimated" if key in e.estimated else "given")

    print(f"{e.name}: {e.title}")
    print(f"  density          {_fmt(e.density, ' kg/m^3', digits=5):>16}  {status('density')}" + (f"  [{e.derivation['density']}]" if "density" in e.derivation else ""))
    if e.youngs_modulus is not None:
        sd = f" +- {_fmt(e.youngs_modulus_std, ' kPa', 1e-3)}" if e.youngs_modulus_std is not None else ""
        print(f"  Young's modulus  {_fmt(e.youngs_modulus, ' kPa', 1e-3):>16}  {status('youngs_modulus')}{sd}")
    print(f"  shear modulus    {_fmt(e.shear_modulus, ' kPa', 1e-3):>16}  {status('shear_modulus')}" + (f"  [{e.derivation['shear_modulus']}]" if "shear_modulus" in e.derivation else ""))
    print(f"  remanence        {_fmt(e.remanence, ' mT', 1e3):>16}  {status('remanence')}" + (f"  [{e.derivation['remanence']}]" if "remanence" in e.derivation else ""))
    if e.remanence_estimate is not None:
        print(f"    volume-fraction estimate {_fmt(e.remanence_estimate, ' mT', 1e3)} (NdFeB volume fraction {_fmt(e.volume_fraction)}), correction {_fmt(e.remanence_correction, ' mT', 1e3, 3)}")
    if e.ndfeb_wt_percent is not None:
        print(f"  NdFeB            {e.ndfeb_wt_percent:g} wt% of the silicone mass")
    print(f"  measured:  {', '.join(e.measured) or 'none'}")
    print(f"  estimated: {', '.join(e.estimated) or 'none'}")
    print(f"  source: {e.source}")
    if e.notes:
        print(f"  notes: {e.notes}")
    print(f"  from: {e.origin}")
    return 0
