"""magsoro validate: JSON schema and pass flags of the fast closed-form cases, the MPM beam's dependence on
Br B / (mu0 G) and L / t only, and (slow) the whole quick validation end to end."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from magsoro.cli import main

FAST = ["uniform_torque", "dipole_force", "neo_hookean", "momentum"]
KEYS = {"case", "quantity", "inputs", "reference", "value", "error", "tolerance", "passed"}


def _check_rows(rows):
    assert isinstance(rows, list) and rows
    for row in rows:
        assert set(row) == KEYS, row
        assert isinstance(row["case"], str) and isinstance(row["quantity"], str)
        assert isinstance(row["inputs"], dict)
        for key in ("reference", "value", "error", "tolerance"):
            assert isinstance(row[key], float) and math.isfinite(row[key]), (key, row)
        assert row["passed"] is (row["error"] <= row["tolerance"])


def test_fast_cases_json_schema_and_pass(capsys, tmp_path):
    code = main(["validate", *FAST, "--json", "--out", str(tmp_path)])
    rows = json.loads(capsys.readouterr().out)
    _check_rows(rows)
    assert {r["case"] for r in rows} == set(FAST)
    assert all(r["passed"] for r in rows), [r for r in rows if not r["passed"]]
    assert code == 0
    summary = json.loads((tmp_path / "results.json").read_text())
    assert [c["case"] for c in summary["cases"]] == FAST


def test_list_names_every_case_and_unknown_case_is_an_error(capsys):
    from magsoro.validation import CASES

    assert main(["validate", "--list"]) == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines() if line.strip()]
    assert listed == list(CASES)
    assert {"beam", "beam_3d", "beam_convergence", *FAST} <= set(listed)
    assert main(["validate", "no_such_case"]) == 2
    assert "no_such_case" in capsys.readouterr().err


def test_failing_row_gives_exit_status_1(monkeypatch, capsys):
    from magsoro.validation import registry

    def bad(ctx):
        return registry.CaseResult("bad", [registry.Row("bad", "x", {}, 1.0, 1.5, 0.5, 0.1)])

    monkeypatch.setitem(registry.CASES, "bad", registry.Case("bad", "always fails", bad))
    assert main(["validate", "bad"]) == 1
    assert "NO" in capsys.readouterr().out


def test_beam_tip_depends_only_on_normalised_field_and_slenderness():
    """Seed 000 Fig 2b: Br B / (mu0 G) makes the result independent of the material. Scaling G and Br by 3.7
    (same B, same normalised field) and, separately, every length by 1.6 (same L / t) must leave the engine's
    tip displacement over L unchanged, at a coarse resolution and a short beam to keep the test fast."""
    from dataclasses import replace

    from magsoro.validation.beam import BeamSetup, run_sweep, scaled_setup

    base = BeamSetup(length=6.72e-3, thickness=0.84e-3, width=2e-3, dim=2, t_over_dx=2, hold=2.0, ramp=1.0)
    fields = (0.003,)
    ref = run_sweep(base, fields, 90.0)
    material = run_sweep(scaled_setup(base, 3.7), fields, 90.0)
    k = 1.6
    geometry = run_sweep(replace(base, length=k * base.length, thickness=k * base.thickness, width=k * base.width),
                         fields, 90.0)
    assert ref.tip_dy[0] > 0.05  # a real, large deflection
    for other in (material, geometry):
        assert other.particles == ref.particles
        assert abs(other.tip_dy[0] - ref.tip_dy[0]) < 1e-4 * ref.tip_dy[0], (other.tip_dy, ref.tip_dy)
        assert abs(other.tip_dx[0] - ref.tip_dx[0]) < 1e-3 * abs(ref.tip_dx[0]), (other.tip_dx, ref.tip_dx)
    # and a different normalised field does change it: the check can fail
    stronger = run_sweep(base, (0.004,), 90.0)
    assert stronger.tip_dy[0] > 1.05 * ref.tip_dy[0]


@pytest.mark.slow
def test_quick_validation_end_to_end(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "magsoro.cli", "validate", "--quick", "--json", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=1200)
    rows = json.loads(proc.stdout)
    _check_rows(rows)
    cases = {r["case"] for r in rows}
    assert {"beam", *FAST} <= cases
    beam = [r for r in rows if r["case"] == "beam"]
    assert {r["quantity"] for r in beam} >= {"tip_dy_over_L", "tip_dx_over_L"}
    for r in beam:
        assert {"bn", "psi_deg", "L_over_t", "dim"} <= set(r["inputs"])
    assert (tmp_path / "beam.png").stat().st_size > 10_000
    assert all(r["passed"] for r in rows), [r for r in rows if not r["passed"]]
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert np.isfinite([r["value"] for r in rows]).all()
