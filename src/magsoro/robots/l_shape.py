"""Seed 003's "L"-shaped robot (Note S1, Figs S6-S9): a straight strip of ten magnetised segments bends into an
L as a uniform field rises to 20 mT (MPM, static solver, against seed 003's Cosserat rod and the designed
letter), and the two parameter studies seed 003 shows for it: the tip displacement against the field for
several NdFeB concentrations (Fig S8, 1-10 mT) and several matrix stiffnesses (Fig S9, 1-20 mT).

Concentration (Fig S8): the material library's mixture rules with the matrix density (library entry
``dragon-skin-10``) and seed 003's particles: volume fraction phi = (w / rho_p) / (w / rho_p + 1 / rho_s), remanence
phi x 911 mT, density (1 + w) / (1 / rho_s + w / rho_p), w = wt% / 100. Each segment keeps its designed direction
and its fraction of the design concentration's remanence. The modulus is held at the design composite's (seed
003's model, Note S1, takes the particles through Br only); so is the shape of the study: in a uniform field
without gravity the shape depends on Br B / E alone, and both studies rescale one field axis.
Stiffness (Fig S9): the shear modulus times 0.5, 1, 2, 4 (bulk modulus 20 G), the design concentration.
"""

import numpy as np

from magsoro.robots._letters import (
    Centreline,
    Letter,
    make_robot,
    mpm_sweep,
    plane_strain_modulus,
    plot_family,
    rod_model,
    rod_sweep,
)
from magsoro.robots.base import simulation, write_csv

LETTER = Letter(
    name="l_shape",
    letter="L",
    # an 11 mm straight stem, a 2 mm corner turning 90 degrees, a 7 mm straight foot (our reading of the letter)
    pieces=((0.55, 0.0), (0.1, 90.0), (0.35, 0.0)),
    title='"L"-shaped robot (designed magnetisation; concentration and stiffness studies)',
    sentence=("A 20 x 0.5 mm Dragon Skin 10 + NdFeB strip with ten segments, magnetised as designed by magsoro "
              "optimize, bends into an L as a uniform field rises to 20 mT, as in MPM so in seed 003's Cosserat rod; "
              "its tip displacement grows with the NdFeB concentration (Fig S8) and falls with the matrix "
              "stiffness (Fig S9)."),
)

#: Fig S8: NdFeB wt% (grams per 100 g of silicone); Dragon Skin 10 holds at most 100 wt% (seed 001 sec III-B)
CONCENTRATIONS = (20.0, 40.0, 60.0, 80.0, 100.0)
CONCENTRATION_FIELDS = tuple(1e-3 * np.arange(1, 11))          # T, 1-10 mT (Fig S8)
#: Fig S9: factors on the design composite's shear modulus
STIFFNESS_FACTORS = (0.5, 1.0, 2.0, 4.0)
STIFFNESS_FIELDS = tuple(1e-3 * np.arange(1, 21))              # T, 1-20 mT (Fig S9)
PREVIEW = {"concentrations": (20.0, 60.0, 100.0), "concentration_fields": (0.002, 0.006, 0.01),
           "factors": (0.5, 2.0), "stiffness_fields": (0.005, 0.01, 0.02)}
#: MPM and rod tip displacements within 3 % of the strip length (the issue's shape tolerance)
DISPLACEMENT_TOL = 0.03


def composite(wt_percent: float, library_name: str) -> dict:
    """NdFeB volume fraction, remanence (T) and density (kg/m^3) of the design composite's matrix loaded with
    ``wt_percent``, by the material library's mixture rules (magsoro.materials.library)."""
    from magsoro.materials import get_material
    from magsoro.materials.library import (
        NDFEB_REMANENCE,
        mixture_density,
        ndfeb_volume_fraction,
    )

    matrix = library_name.split("-ndfeb")[0]           # dragon-skin-10-ndfeb100 -> dragon-skin-10 (0 wt%)
    rho_s = get_material(matrix).density
    phi = ndfeb_volume_fraction(wt_percent, rho_s)
    return {"wt_percent": wt_percent, "volume_fraction": phi, "remanence": phi * NDFEB_REMANENCE,
            "density": mixture_density(wt_percent, rho_s), "matrix": matrix}


def _variant(data: dict, st, scale_br: float = 1.0, material: dict | None = None) -> dict:
    import copy

    out = copy.deepcopy(data)
    for p in out["robot"]["parts"]:
        if material is not None:
            lib = p["material"] if isinstance(p["material"], str) else p["material"]["library"]
            p["material"] = {"library": lib, **material}
        if p["name"] in st.segments:
            p["magnetization"] = [float(c) * scale_br for c in p["magnetization"]]
    return out


def _tip_displacement(shapes, st, s_tip) -> np.ndarray:
    tip0 = st.origin + st.axis * s_tip
    return np.linalg.norm(shapes[:, -1] - tip0, axis=1) * 1e3


def studies(ctx, data, st, mat, case):
    """Figs S8 and S9: tip displacement against field per concentration and per stiffness, MPM and rod."""
    from magsoro.materials import get_material
    from magsoro.robots._letters import library_remanence
    from magsoro.validation.registry import Row

    lib_name, br_design = library_remanence(data)
    design_wt = get_material(lib_name).ndfeb_wt_percent
    pv = ctx.preview
    concs = PREVIEW["concentrations"] if pv else CONCENTRATIONS
    cfields = np.array(PREVIEW["concentration_fields"] if pv else CONCENTRATION_FIELDS)
    factors = PREVIEW["factors"] if pv else STIFFNESS_FACTORS
    sfields = np.array(PREVIEW["stiffness_fields"] if pv else STIFFNESS_FIELDS)
    top = float(np.linalg.norm(st.field))

    def run(variant, fields, E_ps, scale_br):
        sim = simulation(LETTER.name, variant, preview=pv, device=ctx.device)
        line = Centreline(sim, st)
        mpm, _res, msg = mpm_sweep(sim, fields / top, line)
        rod = rod_model(st, E_ps, st.vectors * scale_br)
        rods, rmsg = rod_sweep(rod, [st.field * (b / top) for b in fields], line.s)
        return _tip_displacement(mpm, st, line.s[-1]), _tip_displacement(rods, st, line.s[-1]), msg or rmsg

    conc_rows, conc_curves, msgs = [], {}, []
    cols = {"B_mT": cfields * 1e3}
    for wt in concs:
        c = composite(wt, lib_name)
        k = c["remanence"] / br_design
        m, r, msg = run(_variant(data, st, k, {"density": c["density"]}), cfields, mat["E_ps"], k)
        msgs += [msg] if msg else []
        conc_curves[f"{wt:.0f} wt% (Br {c['remanence'] * 1e3:.0f} mT)"] = (m, r)
        cols[f"mpm_{wt:.0f}wt_mm"], cols[f"rod_{wt:.0f}wt_mm"] = m, r
        conc_rows.append(c)
        ctx.log(f"  {LETTER.name}: {wt:.0f} wt% NdFeB (phi {c['volume_fraction']:.4f}, Br {c['remanence'] * 1e3:.1f} mT): "
                f"tip displacement at {cfields[-1] * 1e3:.0f} mT {m[-1]:.2f} mm (rod {r[-1]:.2f} mm)")
    write_csv(ctx.out / f"{LETTER.name}_concentration.csv", cols)
    plot_family(ctx.out / f"{LETTER.name}_concentration.png", cfields * 1e3, conc_curves, "uniform field |B| (mT)",
                "tip displacement (mm)", "'L' robot: NdFeB concentration (seed 003 Fig S8)",
                note=f"mixture rules on {conc_rows[0]['matrix']}; modulus held at {lib_name}'s")

    stiff_curves = {}
    cols = {"B_mT": sfields * 1e3}
    for f in factors:
        G = mat["G"] * f
        m, r, msg = run(_variant(data, st, 1.0, {"shear_modulus": G}), sfields, plane_strain_modulus(G, 20.0 * G), 1.0)
        msgs += [msg] if msg else []
        stiff_curves[f"E = {3 * G / 1e3:.0f} kPa"] = (m, r)
        cols[f"mpm_G{f:g}_mm"], cols[f"rod_G{f:g}_mm"] = m, r
        ctx.log(f"  {LETTER.name}: G x {f:g} ({G / 1e3:.0f} kPa): tip displacement at {sfields[-1] * 1e3:.0f} mT "
                f"{m[-1]:.2f} mm (rod {r[-1]:.2f} mm)")
    write_csv(ctx.out / f"{LETTER.name}_stiffness.csv", cols)
    plot_family(ctx.out / f"{LETTER.name}_stiffness.png", sfields * 1e3, stiff_curves, "uniform field |B| (mT)",
                "tip displacement (mm)", "'L' robot: matrix stiffness (seed 003 Fig S9)",
                note=f"E = 3 G; {design_wt:.0f} wt% NdFeB")

    L_mm = st.length * 1e3
    inp = {"concentrations_wt": list(concs), "stiffness_factors": list(factors)}
    conc_m = np.array([v[0] for v in conc_curves.values()])
    conc_r = np.array([v[1] for v in conc_curves.values()])
    st_m = np.array([v[0] for v in stiff_curves.values()])
    st_r = np.array([v[1] for v in stiff_curves.values()])
    d_conc = float(np.max(np.abs(conc_m - conc_r)) / L_mm)
    d_stiff = float(np.max(np.abs(st_m - st_r)) / L_mm)
    rise = float(np.min(np.diff(conc_m, axis=0)))    # more particles: more displacement at every field (mm)
    fall = float(np.min(-np.diff(st_m, axis=0)))     # stiffer: less displacement at every field (mm)
    rows = [
        Row(case, "Fig S8: largest |MPM - rod| tip displacement over concentrations and fields / strip length", inp,
            0.0, d_conc, d_conc, DISPLACEMENT_TOL),
        Row(case, "Fig S9: largest |MPM - rod| tip displacement over stiffnesses and fields / strip length", inp,
            0.0, d_stiff, d_stiff, DISPLACEMENT_TOL),
        Row(case, "Fig S8: smallest rise of the MPM tip displacement from one concentration to the next (mm); "
                  "passes when >= 0 at every field", inp, 0.0, rise, max(0.0, -rise), 0.0),
        Row(case, "Fig S9: smallest fall of the MPM tip displacement from one stiffness to the next (mm); passes "
                  "when >= 0 at every field", inp, 0.0, fall, max(0.0, -fall), 0.0),
    ]
    info = {"concentration_volume_fractions": [round(c["volume_fraction"], 5) for c in conc_rows],
            "concentration_remanence_T": [round(c["remanence"], 5) for c in conc_rows],
            "concentration_density_kg_m3": [round(c["density"], 1) for c in conc_rows],
            "concentration_tip_mm_at_top": {k: round(float(v[0][-1]), 3) for k, v in conc_curves.items()},
            "stiffness_tip_mm_at_top": {k: round(float(v[0][-1]), 3) for k, v in stiff_curves.items()}}
    lo, hi = list(conc_curves), list(stiff_curves)
    summary = (f"at {cfields[-1] * 1e3:.0f} mT the tip moves {conc_m[0, -1]:.1f} mm with {lo[0]} and "
               f"{conc_m[-1, -1]:.1f} mm with {lo[-1]} (rod {conc_r[0, -1]:.1f}, {conc_r[-1, -1]:.1f}; Fig S8), at "
               f"{sfields[-1] * 1e3:.0f} mT {st_m[0, -1]:.1f} mm with {hi[0]} and {st_m[-1, -1]:.1f} mm with {hi[-1]} "
               f"(rod {st_r[0, -1]:.1f}, {st_r[-1, -1]:.1f}; Fig S9)")
    if msgs:
        summary += " (" + "; ".join(msgs) + ")"
    return rows, info, summary


ROBOT = make_robot(
    LETTER, extra=studies, source="seed 003 Note S1, Figs S6-S9",
    quantity=("centreline at 0-20 mT: MPM (static) vs Cosserat rod vs designed letter; tip displacement vs field per "
              "NdFeB concentration and per stiffness (Figs S8-S9)"))
ROBOT.sentence += ("\n\n![l_shape: Fig S8, NdFeB concentration](robots/l_shape/l_shape_concentration.png) "
                   "![l_shape: Fig S9, stiffness](robots/l_shape/l_shape_stiffness.png)")
