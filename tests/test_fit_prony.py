"""Prony (generalised Maxwell) fits of `magsoro fit-material --relaxation/--frequency-sweep`
(magsoro.characterization.viscoelastic) and the ``prony`` key of material entries."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from magsoro.characterization import CharacterizationDataError, uniaxial_stress
from magsoro.characterization.material_file import material_toml, read_material
from magsoro.characterization.viscoelastic import (
    FrequencySweepData,
    RelaxationData,
    fit_prony,
    prony_relaxation,
    prony_storage_loss,
    read_frequency_sweep_csv,
    read_relaxation_csv,
)
from magsoro.cli import main

G0 = 2.3e4  # Pa
# relaxation times off the fit's half-decade start grid and spread over decades (s)
TRUTHS = {
    2: ((0.3, 0.2), (0.037, 23.0)),
    3: ((0.22, 0.18, 0.15), (0.013, 0.71, 47.0)),
}
TIME = np.geomspace(1e-3, 1e4, 150)  # s: resolves tau 0.013 .. 47 s with room on both sides
FREQ = np.geomspace(1e-4, 1e2, 61)  # Hz: 1/w = 1.6e-3 .. 1.6e3 s
# The noise-free fits reach relative residuals ~1e-13, so the truth is recovered to far better than these
# tolerances; they are set well below what a fit stuck in a wrong basin gives (tens of percent) and above the
# error sums of exponentials can turn a 1e-10 stopping tolerance into (exponential fitting is ill-conditioned).
CURVE_TOL = 0.005  # noise-free: fitted curve vs truth, relative, everywhere on the data's range
PARAM_TOL = 0.02  # noise-free: g_i, tau_i, G0 relative
NOISY_CURVE_TOL = 0.02  # 1 % multiplicative noise (fixed seed): fitted curve vs the noise-free truth


def _write_csv(path, header, columns):
    with open(path, "w") as f:
        f.write("# synthetic test data\n" + header + "\n")
        for row in zip(*columns):
            f.write(",".join(repr(float(v)) for v in row) + "\n")
    return path


def _relaxation_file(tmp_path, n, noise=0.0, seed=0, name="relax.csv"):
    g, tau = TRUTHS[n]
    modulus = prony_relaxation(TIME, G0, g, tau)
    modulus = modulus * (1.0 + noise * np.random.default_rng(seed).standard_normal(TIME.size))
    return _write_csv(tmp_path / name, "time,shear_modulus", (TIME, modulus))


def _sweep_file(tmp_path, n, noise=0.0, seed=0, name="sweep.csv"):
    g, tau = TRUTHS[n]
    storage, loss = prony_storage_loss(FREQ, G0, g, tau)
    rng = np.random.default_rng(seed)
    storage = storage * (1.0 + noise * rng.standard_normal(FREQ.size))
    loss = loss * (1.0 + noise * rng.standard_normal(FREQ.size))
    return _write_csv(tmp_path / name, "frequency,storage_modulus,loss_modulus", (FREQ, storage, loss))


def _tensile_file(tmp_path):
    strain = np.linspace(0.0, 2.0, 60)
    return _write_csv(tmp_path / "tensile.csv", "strain,stress", (strain, uniaxial_stress("neo-hookean", [1.2e4], strain)))


def _max_rel(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) / np.asarray(b) - 1.0)))


def _assert_parameters(fit, n):
    g, tau = TRUTHS[n]
    assert fit.n_terms == n
    assert np.allclose(fit.g, g, rtol=PARAM_TOL, atol=0), fit.g
    assert np.allclose(fit.tau, tau, rtol=PARAM_TOL, atol=0), fit.tau
    assert fit.shear_modulus == pytest.approx(G0, rel=PARAM_TOL)
    assert fit.g_inf == pytest.approx(1.0 - sum(g), rel=PARAM_TOL)


# --------------------------------------------------------------------------------------------------------------
# recovery of known series


@pytest.mark.parametrize("n", [2, 3])
def test_relaxation_fit_recovers_known_series(tmp_path, n):
    fit = fit_prony(read_relaxation_csv(_relaxation_file(tmp_path, n)), n_terms=n)
    g, tau = TRUTHS[n]
    t = np.geomspace(TIME[0], TIME[-1], 2000)
    assert _max_rel(fit.relaxation_modulus(t), prony_relaxation(t, G0, g, tau)) < CURVE_TOL
    _assert_parameters(fit, n)
    assert fit.rms_error < 0.01 and fit.mape < 0.01  # percent
    assert fit.notes == []


@pytest.mark.parametrize("n", [2, 3])
def test_relaxation_fit_with_one_percent_noise(tmp_path, n):
    fit = fit_prony(read_relaxation_csv(_relaxation_file(tmp_path, n, noise=0.01, seed=7)), n_terms=n)
    g, tau = TRUTHS[n]
    t = np.geomspace(TIME[0], TIME[-1], 2000)
    assert _max_rel(fit.relaxation_modulus(t), prony_relaxation(t, G0, g, tau)) < NOISY_CURVE_TOL
    # the residual is the noise: RMS close to 1 %
    assert 0.8 < fit.rms_error < 1.2


@pytest.mark.parametrize("n", [2, 3])
def test_frequency_sweep_fit_recovers_known_series(tmp_path, n):
    fit = fit_prony(read_frequency_sweep_csv(_sweep_file(tmp_path, n)), n_terms=n)
    g, tau = TRUTHS[n]
    f = np.geomspace(FREQ[0], FREQ[-1], 2000)
    storage, loss = fit.storage_loss(f)
    true_storage, true_loss = prony_storage_loss(f, G0, g, tau)
    assert _max_rel(storage, true_storage) < CURVE_TOL
    assert _max_rel(loss, true_loss) < CURVE_TOL
    _assert_parameters(fit, n)
    # the relaxation modulus follows from the same terms
    t = np.geomspace(1e-3, 1e3, 200)
    assert _max_rel(fit.relaxation_modulus(t), prony_relaxation(t, G0, g, tau)) < CURVE_TOL


@pytest.mark.parametrize("n", [2, 3])
def test_frequency_sweep_fit_with_one_percent_noise(tmp_path, n):
    fit = fit_prony(read_frequency_sweep_csv(_sweep_file(tmp_path, n, noise=0.01, seed=3)), n_terms=n)
    g, tau = TRUTHS[n]
    f = np.geomspace(FREQ[0], FREQ[-1], 2000)
    storage, loss = fit.storage_loss(f)
    true_storage, true_loss = prony_storage_loss(f, G0, g, tau)
    assert _max_rel(storage, true_storage) < NOISY_CURVE_TOL
    assert _max_rel(loss, true_loss) < NOISY_CURVE_TOL
    assert 0.8 < fit.rms_error < 1.2


def test_tensile_modulus_and_held_stress_columns_give_the_shear_modulus(tmp_path):
    """E(t) = 3 G(t); a held tension P(t) = G(t) (lam - lam^-2) (incompressible Neo-Hookean), here at 25 %."""
    g, tau = TRUTHS[2]
    shear = prony_relaxation(TIME, G0, g, tau)
    lam = 1.25
    files = {
        "tensile_modulus": _write_csv(tmp_path / "e.csv", "time,tensile_modulus", (TIME, 3.0 * shear)),
        "stress": _write_csv(
            tmp_path / "p.csv", "Time, Stress, Strain", (TIME, shear * (lam - lam**-2), np.full(TIME.size, 0.25))
        ),
    }
    for column, path in files.items():
        data = read_relaxation_csv(path)
        assert data.column == column
        assert np.allclose(data.shear_modulus, shear, rtol=1e-12)
        fit = fit_prony(data, 2)
        assert fit.shear_modulus == pytest.approx(G0, rel=PARAM_TOL)
        assert np.allclose(fit.tau, tau, rtol=PARAM_TOL)


def test_tensile_sweep_columns_give_the_shear_moduli(tmp_path):
    """A tensile DMA gives E' = 3 G' and E'' = 3 G''; the rows may come from high to low frequency."""
    g, tau = TRUTHS[2]
    storage, loss = prony_storage_loss(FREQ, G0, g, tau)
    path = _write_csv(tmp_path / "dma.csv", "frequency,tensile_storage_modulus,tensile_loss_modulus",
                      (FREQ[::-1], 3 * storage[::-1], 3 * loss[::-1]))
    data = read_frequency_sweep_csv(path)
    assert data.column == "tensile_storage_modulus"
    assert np.allclose(data.frequency, FREQ) and np.allclose(data.storage_modulus, storage, rtol=1e-12)
    assert np.allclose(data.loss_modulus, loss, rtol=1e-12)
    assert fit_prony(data, 2).shear_modulus == pytest.approx(G0, rel=PARAM_TOL)


def test_terms_the_data_do_not_support_are_dropped():
    t = np.geomspace(1e-2, 1e2, 50)
    fit = fit_prony(RelaxationData.from_arrays(t, prony_relaxation(t, 1e5, [0.4], [1.0])), n_terms=3)
    assert fit.n_terms == 1 and fit.n_terms_requested == 3
    assert fit.g[0] == pytest.approx(0.4, rel=1e-6) and fit.tau[0] == pytest.approx(1.0, rel=1e-6)
    assert fit.shear_modulus == pytest.approx(1e5, rel=1e-6)
    assert any("dropped" in note or "merged" in note for note in fit.notes)


def test_a_relaxation_time_beyond_the_data_is_flagged():
    f = np.geomspace(1e-2, 1e2, 41)  # 1/w = 1.6 ms .. 16 s
    storage, loss = prony_storage_loss(f, G0, [0.3, 0.2], [0.1, 100.0])
    fit = fit_prony(FrequencySweepData.from_arrays(f, storage, loss), 2)
    assert fit.rms_error < 0.01  # the curve is matched, but tau_2 cannot be told from the data
    assert any(note.startswith("tau_2 = ") and "outside the range" in note for note in fit.notes), fit.notes


def test_every_decade_weighs_the_same_whatever_the_logging_rate():
    """A record logged at a fixed rate has 10x more points per decade at late times; the residual weights
    (squared: each point's share of the log axis) give each decade the same total."""
    from magsoro.characterization.viscoelastic import _log_axis_weights

    t = np.arange(1, 100_001) * 1e-3  # 1 ms .. 100 s at 1 kHz
    w2 = _log_axis_weights(t) ** 2
    per_decade = [w2[(t > 10.0**k) & (t <= 10.0 ** (k + 1))].sum() for k in range(-2, 2)]
    assert np.allclose(per_decade, per_decade[0], rtol=0.05), per_decade
    assert np.allclose(_log_axis_weights(np.geomspace(1e-3, 1e3, 50)), 1.0)


def test_unsorted_sweep_is_sorted_and_prony_closed_forms_agree():
    """A sweep listed from high to low frequency fits the same; G'' / G' and G(t) are the textbook forms."""
    g, tau = TRUTHS[2]
    storage, loss = prony_storage_loss(FREQ, G0, g, tau)
    data = FrequencySweepData.from_arrays(FREQ[::-1], storage[::-1], loss[::-1])
    assert np.all(np.diff(data.frequency) > 0)
    fit = fit_prony(data, 2)
    assert np.allclose(fit.tau, tau, rtol=PARAM_TOL)
    # one Maxwell term by hand: w = 2 pi f
    w = 2 * np.pi * 0.5
    s, l = prony_storage_loss(0.5, 10.0, [0.4], [2.0])
    assert float(s) == pytest.approx(10.0 * (0.6 + 0.4 * (2 * w) ** 2 / (1 + (2 * w) ** 2)))
    assert float(l) == pytest.approx(10.0 * 0.4 * 2 * w / (1 + (2 * w) ** 2))
    assert float(prony_relaxation(3.0, 10.0, [0.4], [2.0])) == pytest.approx(10.0 * (0.6 + 0.4 * math.exp(-1.5)))


# --------------------------------------------------------------------------------------------------------------
# command line


def test_cli_relaxation_prints_the_prony_table(tmp_path, capsys):
    path = _relaxation_file(tmp_path, 3)
    assert main(["fit-material", "--relaxation", str(path), "--prony-terms", "3"]) == 0
    out = capsys.readouterr().out
    assert "relax.csv" in out and "g_i" in out and "tau_i [s]" in out
    assert "G0 = 23 kPa" in out and "g_inf = 0.45000" in out
    line = next(ln for ln in out.splitlines() if ln.startswith("prony = "))
    pairs = json.loads(line[len("prony = "):])
    assert np.allclose(pairs, np.transpose(TRUTHS[3]), rtol=1e-3)


def test_cli_frequency_sweep_json_and_out(tmp_path, capsys):
    path = _sweep_file(tmp_path, 2)
    out = tmp_path / "out"
    assert main(["fit-material", "--frequency-sweep", str(path), "--prony-terms", "2", "--json", "--out", str(out)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert list(result) == ["prony"]
    rec = result["prony"]
    assert rec["kind"] == "frequency-sweep" and rec["n_terms"] == 2 and rec["plot"] == "fit_prony.png"
    assert np.allclose(rec["g"], TRUTHS[2][0], rtol=PARAM_TOL) and np.allclose(rec["tau"], TRUTHS[2][1], rtol=PARAM_TOL)
    assert rec["prony"] == [[a, b] for a, b in zip(rec["g"], rec["tau"])]
    assert rec["shear_modulus"] == pytest.approx(G0, rel=PARAM_TOL)
    assert rec["g_inf"] == pytest.approx(1 - sum(rec["g"]))
    assert (out / "fit_prony.png").stat().st_size > 10_000
    assert json.loads((out / "fit_material.json").read_text()) == result
    assert not (out / "fit_material.png").exists()  # no tensile data, no tensile figure


@pytest.mark.parametrize("option, maker", [("--relaxation", _relaxation_file), ("--frequency-sweep", _sweep_file)])
def test_save_material_round_trip(tmp_path, capsys, monkeypatch, option, maker):
    tensile = _tensile_file(tmp_path)
    visco = maker(tmp_path, 2)
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir(out)  # without --out the entry goes to the current folder (and no figures: faster)
    argv = ["fit-material", str(tensile), "--models", "neo-hookean,yeoh", option, str(visco), "--prony-terms", "2",
            "--json", "--save-material", "visco_a", "--density", "1070"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert list(result) == ["models", "prony"]
    path = out / "visco_a.toml"
    entry = read_material(path)
    assert entry["prony"] == result["prony"]["prony"]  # floats written with repr: exact
    assert np.allclose(entry["prony"], np.transpose(TRUTHS[2]), rtol=PARAM_TOL)
    assert entry["model"] in ("neo-hookean", "yeoh") and entry["density"] == 1070.0
    assert str(visco) in entry["source"] and str(tensile) in entry["source"]
    assert set(entry["parameters"]) >= {"C10"}
    text = path.read_text()
    assert text.index("prony = ") < text.index("[parameters]")  # a top-level key, before the table
    # the scene builder reads the same file (and, where it knows the key, the same terms)
    from magsoro.scene.build import resolve_material
    from magsoro.scene.schema import Material

    resolved = resolve_material(Material(file=path.name), out, "bodies[0].material")
    assert resolved["density"] == 1070.0
    if "prony" in resolved:
        assert resolved["prony"] == entry["prony"]


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("magsoro fit-material: error: ")
    return lines[0]


@pytest.mark.parametrize("name, text, expected", [
    ("negtime.csv", "time,shear_modulus\n0.1,100\n-1,90\n2,80\n", ["negtime.csv", "'time'", "line 3", "> 0 s"]),
    ("zerotime.csv", "time,shear_modulus\n0,100\n1,90\n2,80\n", ["zerotime.csv", "'time'", "line 2"]),
    ("nocol.csv", "time,load\n0.1,100\n1,90\n", ["nocol.csv", "'shear_modulus'", "'tensile_modulus'", "'stress'"]),
    ("notime.csv", "t,shear_modulus\n0.1,100\n1,90\n", ["notime.csv", "'time'"]),
    ("nostrain.csv", "time,stress\n0.1,100\n1,90\n", ["nostrain.csv", "'stress'", "'strain'"]),
    ("two.csv", "time,shear_modulus,tensile_modulus\n0.1,1,3\n", ["two.csv", "only one"]),
    ("unsorted.csv", "time,shear_modulus\n0.1,100\n2,90\n1,80\n", ["unsorted.csv", "'time'", "strictly increasing", "line 4"]),
    ("dup.csv", "time,shear_modulus\n0.1,100\n1,90\n1,80\n", ["dup.csv", "'time'", "strictly increasing"]),
    ("negmod.csv", "time,shear_modulus\n0.1,100\n1,-90\n", ["negmod.csv", "'shear_modulus'", "line 3", "> 0 Pa"]),
    ("nan.csv", "time,shear_modulus\n0.1,100\n1,nan\n", ["nan.csv", "'shear_modulus'", "not finite"]),
    ("short.csv", "time,shear_modulus\n0.1,100\n1,90\n2,85\n5,80\n10,79\n20,78\n",
     ["short.csv", "6 rows", "7 parameters"]),
])
def test_cli_bad_relaxation_files(tmp_path, capsys, name, text, expected):
    path = tmp_path / name
    path.write_text(text)
    assert main(["fit-material", "--relaxation", str(path)]) == 2
    line = _one_line_error(capsys)
    for part in expected:
        assert part in line, line


@pytest.mark.parametrize("name, text, expected", [
    ("nosl.csv", "frequency,storage_modulus\n1,100\n", ["nosl.csv", "'loss_modulus'", "'frequency'"]),
    ("dupf.csv", "frequency,storage_modulus,loss_modulus\n1,100,10\n2,110,9\n1,100,10\n",
     ["dupf.csv", "'frequency'", "repeats 1 Hz", "line 2", "line 4"]),
    ("zerof.csv", "frequency,storage_modulus,loss_modulus\n0,100,10\n2,110,9\n", ["zerof.csv", "'frequency'", "> 0 Hz"]),
    ("zeroloss.csv", "frequency,storage_modulus,loss_modulus\n1,100,0\n2,110,9\n",
     ["zeroloss.csv", "'loss_modulus'", "line 2"]),
    ("shortf.csv", "frequency,storage_modulus,loss_modulus\n1,100,10\n2,110,9\n3,115,8\n",
     ["shortf.csv", "6 values", "7 parameters"]),
])
def test_cli_bad_sweep_files(tmp_path, capsys, name, text, expected):
    path = tmp_path / name
    path.write_text(text)
    assert main(["fit-material", "--frequency-sweep", str(path)]) == 2
    line = _one_line_error(capsys)
    for part in expected:
        assert part in line, line


def test_cli_option_errors(tmp_path, capsys):
    relax = _relaxation_file(tmp_path, 2)
    sweep = _sweep_file(tmp_path, 2)
    cases = [
        (["fit-material"], "no data"),
        (["fit-material", "--relaxation", str(relax), "--frequency-sweep", str(sweep)], "not both"),
        (["fit-material", "--relaxation", str(relax), "--prony-terms", "0"], "--prony-terms: must be 1, 2 or 3"),
        (["fit-material", "--relaxation", str(relax), "--prony-terms", "4"], "--prony-terms: must be 1, 2 or 3"),
        (["fit-material", str(_tensile_file(tmp_path)), "--prony-terms", "2"], "needs --relaxation"),
        (["fit-material", "--relaxation", str(relax), "--save-material", "x"], "--save-material: a material entry"),
    ]
    for argv, part in cases:
        assert main(argv) == 2, argv
        line = _one_line_error(capsys)
        assert part in line, line
    assert not (tmp_path / "x.toml").exists()


# --------------------------------------------------------------------------------------------------------------
# the material entry's `prony` key


def _entry_with(prony_toml: str) -> str:
    return (
        'name = "m"\nmodel = "neo-hookean"\nshear_modulus = 24000.0\n'
        f"prony = {prony_toml}\n\n[parameters]\nC10 = 12000.0\n"
    )


@pytest.mark.parametrize("value, part", [
    ('"0.3"', "must be a table [[g, tau], ...]"),
    ("[]", "1 to 3 rows"),
    ("[[0.1, 1.0], [0.1, 2.0], [0.1, 3.0], [0.1, 4.0]]", "1 to 3"),
    ("[[0.3]]", "row 0 must be two numbers"),
    ("[[0.3, 1.0], [0.2, true]]", "row 1 must be two finite numbers"),
    ("[[0.3, -1.0]]", "tau must be > 0 s"),
    ("[[0.0, 1.0]]", "g must be > 0"),
    ("[[0.3, nan]]", "finite"),
    ("[[0.6, 1.0], [0.4, 2.0]]", "less than 1"),
])
def test_material_file_reader_rejects_bad_prony(tmp_path, value, part):
    path = tmp_path / "bad.toml"
    path.write_text(_entry_with(value))
    with pytest.raises(CharacterizationDataError) as info:
        read_material(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg and "'prony'" in msg and part in msg, msg


def test_material_file_reader_accepts_prony_and_checks_the_rest(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text(_entry_with("[[0.25, 0.01], [0.2, 1]]"))
    entry = read_material(path)
    assert entry["prony"] == [[0.25, 0.01], [0.2, 1.0]] and isinstance(entry["prony"][1][1], float)
    assert entry["parameters"] == {"C10": 12000.0}
    # an entry in the engine's own parameter names (as a scene reads it) is accepted too
    engine_style = tmp_path / "engine.toml"
    engine_style.write_text('model = "ogden"\nprony = [[0.2, 1.0]]\n[parameters]\nmu = [1e4, 50.0]\nalpha = [1.5, 8]\n')
    assert read_material(engine_style)["prony"] == [[0.2, 1.0]]
    for text, part in [
        ('prony = [[0.2, 1.0]]\n', "'model'"),
        ('model = "yeoh"\nshear_modulus = -1.0\n', "'shear_modulus'"),
        ('model = "yeoh"\n[parameters]\nC10 = "a"\n', "'parameters.C10'"),
    ]:
        bad = tmp_path / "bad_entry.toml"
        bad.write_text(text)
        with pytest.raises(CharacterizationDataError, match=r"bad_entry\.toml") as info:
            read_material(bad)
        assert part in str(info.value)


def test_material_toml_refuses_bad_prony():
    from magsoro.characterization import TensileData, fit_model

    strain = np.linspace(0, 1, 20)
    fit = fit_model(TensileData.from_arrays(strain, uniaxial_stress("neo-hookean", [1e4], strain)), "neo-hookean")
    text = material_toml("m", fit, "t.csv", prony=[[0.3, 0.1]])
    assert "prony = [[0.3, 0.1]]" in text
    with pytest.raises(CharacterizationDataError, match="less than 1"):
        material_toml("m", fit, "t.csv", prony=[[0.7, 0.1], [0.4, 1.0]])
