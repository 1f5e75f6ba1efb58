"""Shape sensing (seed 004 eqs 17-23): marker dipole model, inverses of eq 20, constant-curvature reconstruction,
noisy +-90 degree bends of a 60 mm robot, calibration and the ``magsoro sense`` command."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from magsoro.actuation.sensing import (
    Q_MIN,
    SensingStation,
    calibrate_lever_arm,
    low_pass,
    marker_field_z,
    normalised_ratio,
    offset_closed_form,
    offset_exact,
    peak_field,
    reconstruct_centreline,
    synthetic_readings,
    write_centrelines,
)
from magsoro.cli import main
from magsoro.fields import Dipole

ROOT = Path(__file__).resolve().parents[1]
CALIB = ROOT / "examples" / "actuation" / "calib_two_stations.toml"


def test_marker_model_is_the_dipole_field():
    m, h = 2e-5, 0.6e-3
    rho = np.linspace(0.0, 3e-3, 31)
    # sensor at the origin, marker dipole (moment along z) at gap h below it, offset rho sideways
    ref = np.array([Dipole([0, 0, m], [-r, 0.0, -h]).B([[0.0, 0.0, 0.0]])[0, 2] for r in rho])
    assert np.allclose(marker_field_z(rho, h, m), ref, rtol=1e-12, atol=0)
    assert float(marker_field_z(0.0, h, m)) == pytest.approx(float(peak_field(h, m)), rel=1e-14)  # eq 19
    assert np.allclose(marker_field_z(rho, h, m) / peak_field(h, m), normalised_ratio(rho / h), rtol=1e-12, atol=1e-15)  # eq 20


def test_exact_inverse_on_every_q():
    q = np.concatenate([np.linspace(Q_MIN, 1.0, 4001), [0.0, 1.0, Q_MIN]])
    x = offset_exact(q)
    assert np.max(np.abs(normalised_ratio(x) - q)) < 1e-12
    assert np.all((x >= 0) & (x <= 2.0))
    assert np.all(x[q > 0] < np.sqrt(2)) and np.all(x[(q < 0)] > np.sqrt(2))
    # out-of-range readings clip to the ends of the branch
    assert offset_exact(1.01) == 0.0 and offset_exact(-0.5) == pytest.approx(2.0)
    # round trip from x
    xs = np.linspace(0.0, 2.0, 2001)
    assert np.max(np.abs(offset_exact(normalised_ratio(xs)) - xs)[xs < 1.95]) < 1e-9


def test_exact_inverse_agrees_with_eq_21_above_0p7():
    q = np.linspace(0.7, 0.99999, 3000)
    rel = np.abs(offset_closed_form(q) / offset_exact(q) - 1.0)
    # eq 21 is the first-order expansion: its relative error is (5/16)(1 - q) + O((1 - q)^2)
    assert rel.max() < 0.103  # measured 0.1025 at q = 0.7
    assert np.all(rel < 0.35 * (1.0 - q))
    assert rel[q > 0.99].max() < 3.2e-3


def test_single_arc_matches_eq_23():
    beta = np.radians([-80.0, -30.0, -1e-9, 0.0, 1e-6, 45.0, 80.0])
    L = 0.03
    s, pts = reconstruct_centreline(beta[:, None], [L], points_per_segment=50)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = L / beta
        # eq 23 with r (1 - cos beta) written as 2 r sin^2(beta/2), which keeps its digits for tiny beta
        tip = np.stack([2 * r * np.sin(beta / 2) ** 2, np.zeros_like(beta), r * np.sin(beta)], axis=1)
    tip[beta == 0] = [0.0, 0.0, L]
    assert np.allclose(pts[:, -1], tip, rtol=0, atol=1e-15)
    # points are arc-length parametrised: equal chords along each arc
    d = np.linalg.norm(np.diff(pts, axis=1), axis=2)
    assert np.allclose(d, d[:, :1], rtol=1e-9) and s[-1] == pytest.approx(L)


def test_chained_segments_follow_the_tangent():
    s, pts = reconstruct_centreline([[np.pi / 2, -np.pi / 2]], [0.02, 0.02], 30)
    r = 0.02 / (np.pi / 2)
    # first quarter circle ends heading +x at (r, 0, r); the second turns back to +z
    assert np.allclose(pts[0, 29], [r, 0, r], atol=1e-12)
    assert np.allclose(pts[0, -1], [2 * r, 0, 2 * r], atol=1e-12)


def test_noisy_plus_minus_90_degree_bends_of_a_60mm_robot():
    """Constant-curvature bends of the whole 60 mm robot from -90 to +90 degrees, two stations (30 mm each),
    B0 = 25 mT markers at 0.6 mm, 5 uT Gaussian sensor noise, 20 noisy readings per angle."""
    stations = [SensingStation(0.03, 0.025, 0.6e-3, column=c) for c in ("s1", "s2")]
    total = np.repeat(np.radians(np.linspace(-90.0, 90.0, 181)), 20)
    beta = np.stack([total / 2, total / 2], axis=1)
    readings = synthetic_readings(stations, beta, noise=5e-6, rng=2026)
    est = np.stack([st.bend_angle(readings[:, k]) for k, st in enumerate(stations)], axis=1)
    _, truth = reconstruct_centreline(beta, [0.03, 0.03])
    _, recon = reconstruct_centreline(est, [0.03, 0.03])
    err = np.linalg.norm(truth[:, -1] - recon[:, -1], axis=1)
    assert err.max() < 1e-3  # measured 0.6 mm, at the dead zone around 0 degrees
    assert np.sqrt(np.mean(err**2)) < 1e-4  # measured 0.03 mm
    # the largest errors sit in the dead zone near beta = 0 (seed sec IV), not at the large bends
    assert np.degrees(np.abs(total[np.argmax(err)])) < 10.0
    # the sign of H_z gives the direction
    assert np.all(np.sign(est[np.abs(total) > np.radians(10)]) == np.sign(beta[np.abs(total) > np.radians(10)]))


def test_lever_arm_calibration_from_plus_minus_90_degrees():
    true = SensingStation(0.03, 0.025, 0.6e-3, lever_arm=0.45e-3)
    beta = np.radians(np.repeat([-90.0, 90.0], 50))
    readings = synthetic_readings([true], beta[:, None], noise=5e-6, rng=7)[:, 0]
    guess = SensingStation(0.03, 0.025, 0.6e-3)
    d = calibrate_lever_arm(guess, beta, readings)
    assert d == pytest.approx(0.45e-3, rel=2e-3)
    calibrated = SensingStation(0.03, 0.025, 0.6e-3, lever_arm=d)
    assert np.allclose(calibrated.bend_angle(true.reading(np.radians([-60, 20, 90]))), np.radians([-60, 20, 90]), atol=2e-3)


def test_low_pass_of_bend_angles():
    t = np.linspace(0.0, 1.0, 1001)
    step = np.where(t > 0, 1.0, 0.0)
    y = low_pass(t, step, 0.1)
    # a first-order lag holding each new sample over the interval before it: 1 - exp(-(t - t0) / tau)
    assert np.allclose(y, 1.0 - np.exp(-(t - t[0]) / 0.1), rtol=0, atol=1e-12)
    assert np.allclose(low_pass(t, np.full(1001, 0.3), 0.1), 0.3)
    assert np.array_equal(low_pass(t, step, 0.0), step)


def _write_stream(folder: Path):
    stations = [SensingStation(0.03, 0.025, 0.6e-3, 0.6e-3, c) for c in ("s1", "s2")]
    t = np.arange(0.0, 1.0, 0.01)
    beta = np.stack([np.radians(60) * np.sin(2 * np.pi * t), -np.radians(70) * np.sin(2 * np.pi * t + 0.4)], axis=1)
    readings = synthetic_readings(stations, beta, 5e-6, 11)
    with (folder / "readings.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "s1", "s2"])
        for k in range(len(t)):
            w.writerow([f"{t[k]:.6f}", readings[k, 0], readings[k, 1]])
    s, pts = reconstruct_centreline(beta, [0.03, 0.03], 16)
    write_centrelines(folder / "truth.csv", t, s, pts)
    return t


def test_sense_cli_reports_rmse(tmp_path, capsys):
    t = _write_stream(tmp_path)
    out = tmp_path / "out"
    assert main(["sense", str(tmp_path / "readings.csv"), "--calib", str(CALIB), "--out", str(out),
                 "--truth", str(tmp_path / "truth.csv"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["matched_samples"] == len(t) == summary["samples"]
    assert summary["rmse_m"] < 1e-4 and summary["tip_max_error_m"] < 1e-3
    data = np.genfromtxt(out / "centreline.csv", delimiter=",", names=True)
    assert len(data) == len(t) * 31
    angles = np.genfromtxt(out / "angles.csv", delimiter=",", names=True)
    assert set(angles.dtype.names) >= {"t", "beta_s1", "beta_s2", "kappa_s1", "tip_x", "tip_z"}
    assert (out / "centreline.png").stat().st_size > 0


def test_sense_cli_errors_are_one_line(tmp_path, capsys):
    _write_stream(tmp_path)
    bad = tmp_path / "calib.toml"
    bad.write_text(CALIB.read_text().replace('column = "s2"', 'column = "s3"'))
    assert main(["sense", str(tmp_path / "readings.csv"), "--calib", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "s3" in err and "missing column" in err
    bad.write_text(CALIB.read_text().replace("gap = 0.6e-3", "gap = -1.0", 1))
    assert main(["sense", str(tmp_path / "readings.csv"), "--calib", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "stations[0].gap" in err and str(bad) in err
