"""Material library: Table II moduli, mixture density, remanence estimates and corrections, user entries, CLI."""

import csv
import json
from pathlib import Path

import pytest

from magsoro.cli import main
from magsoro.materials import MaterialLibraryError, builtin_library, get_material, load_library, mixture_density, ndfeb_volume_fraction

# seed 001 Table II (also ../shared/data/seed001_table2_youngs_modulus.csv): E in kPa
TABLE_II = {
    ("ecoflex-00-30", 0): 42.7, ("ecoflex-00-30", 50): 73.2, ("ecoflex-00-30", 100): 102.1, ("ecoflex-00-30", 150): 128.2,
    ("dragon-skin-10", 0): 201.1, ("dragon-skin-10", 50): 343.2, ("dragon-skin-10", 100): 360.1,
}
SHARED_CSV = Path(__file__).resolve().parents[2] / "shared" / "data" / "seed001_table2_youngs_modulus.csv"


def _name(base, wt):
    return base if wt == 0 else f"{base}-ndfeb{wt}"


def test_youngs_moduli_equal_table_ii_and_shear_is_a_third():
    lib = builtin_library()
    for (base, wt), E in TABLE_II.items():
        e = lib[_name(base, wt)]
        assert e.youngs_modulus == pytest.approx(E * 1e3, rel=1e-12)
        assert e.shear_modulus == pytest.approx(E * 1e3 / 3, rel=1e-12)
        assert "youngs_modulus" in e.measured and "shear_modulus" in e.estimated and e.ndfeb_wt_percent == wt
    if SHARED_CSV.is_file():  # the shared copy of the table, when this checkout sits beside it
        rows = [r for r in csv.reader(l for l in SHARED_CSV.read_text().splitlines() if not l.startswith("#"))][1:]
        for elastomer, wt, E, *_ in rows:
            base = "ecoflex-00-30" if elastomer.startswith("Ecoflex") else "dragon-skin-10"
            assert lib[_name(base, int(wt))].youngs_modulus == pytest.approx(float(E) * 1e3, rel=1e-12)


def test_mixture_density_of_one_to_one_ecoflex():
    rho = get_material("ecoflex-00-30-ndfeb100").density
    assert abs(rho / 1876.0 - 1) < 0.01
    assert rho == pytest.approx(mixture_density(100, 1070.0), rel=1e-12)
    assert mixture_density(0, 1070.0) == 1070.0
    # volumes add: mass / density of the mixture equals the sum of the component volumes (1 kg silicone + w kg NdFeB)
    assert (1 + 1.5) / mixture_density(150, 1070.0) == pytest.approx(1 / 1070.0 + 1.5 / 7610.0, rel=1e-12)


def test_remanence_estimate_and_measured_corrections():
    lib = builtin_library()
    e100 = lib["ecoflex-00-30-ndfeb100"]
    phi = ndfeb_volume_fraction(100, 1070.0)
    assert e100.remanence == pytest.approx(phi * 0.911, rel=1e-12) and e100.remanence_correction == 0.0
    assert abs(e100.remanence - 0.107) < 0.01  # seed 001's theoretical 107 mT for this composite
    # seed 001 sec IV-C: +0.136 T per 100 wt% from 50 to 100 wt%, +0.096 T per 100 wt% from 100 to 150 wt%
    assert e100.remanence - lib["ecoflex-00-30-ndfeb50"].remanence == pytest.approx(0.068, abs=1e-12)
    assert lib["ecoflex-00-30-ndfeb150"].remanence - e100.remanence == pytest.approx(0.048, abs=1e-12)
    e50 = lib["ecoflex-00-30-ndfeb50"]
    assert e50.remanence_correction == pytest.approx(e50.remanence - ndfeb_volume_fraction(50, 1070.0) * 0.911, abs=1e-15)
    assert lib["ecoflex-00-30"].remanence == 0.0
    z = lib["sylgard-184-zhao"]
    assert (z.shear_modulus, z.remanence) == (303e3, 0.258) and set(z.measured) == {"shear_modulus", "remanence"}
    for e in lib.values():
        assert e.source and (e.measured or e.estimated)


def test_user_library_entries(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('[[materials]]\nname = "ecoflex-00-50-ndfeb80"\nsilicone_density = 1070.0\nndfeb_wt_percent = 80.0\n'
                 'youngs_modulus = 1.2e5\nsource = "our tensile tests, 2024"\nmeasured = ["youngs_modulus"]\n')
    lib = load_library([f])
    e = lib["ecoflex-00-50-ndfeb80"]
    assert e.density == pytest.approx(mixture_density(80, 1070.0)) and e.remanence == pytest.approx(ndfeb_volume_fraction(80, 1070.0) * 0.911)
    assert e.origin == str(f) and "ecoflex-00-30" in lib
    f.write_text('[[materials]]\nname = "x"\ndensity = 1000.0\nshear_modulus = 1e4\nsource = "s"\ncolour = "red"\n')
    with pytest.raises(MaterialLibraryError, match=r"mine\.toml: materials\[0\]: unknown key 'colour'"):
        load_library([f])
    f.write_text('[[materials]]\nname = "x"\ndensity = 1000.0\nshear_modulus = 1e4\n')
    with pytest.raises(MaterialLibraryError, match=r"materials\[0\]\.source: required"):
        load_library([f])


def test_materials_cli(tmp_path, capsys):
    assert main(["materials", "list"]) == 0
    out = capsys.readouterr().out
    assert "ecoflex-00-30-ndfeb150" in out and "dragon-skin-10-ndfeb100" in out and "sylgard-184-zhao" in out
    assert main(["materials", "show", "ecoflex-00-30-ndfeb50"]) == 0
    out = capsys.readouterr().out
    assert "measured" in out and "estimated" in out and "seed 001" in out and "mixture rule" in out
    assert main(["materials", "show", "ecoflex-00-30-ndfeb100", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["density"] == pytest.approx(1876.2, abs=0.1)
    assert main(["materials", "show", "ecoflex"]) == 2
    err = capsys.readouterr().err
    assert "unknown material 'ecoflex'" in err and len(err.strip().splitlines()) == 1
