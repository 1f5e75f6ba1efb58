"""``magsoro render``: pictures of a run's particle series, with PyVista or the matplotlib fallback.

The runs drawn here are made by writing a run folder the way :class:`magsoro.io.recorder.RunWriter` does
(run.json with the scene, frames/*.vtp through :func:`magsoro.io.vtk.write_vtp`, particles.pvd), so no kernel
is compiled; one slow test renders a real run made through the Python API.
"""

import json

import numpy as np
import pytest
from PIL import Image

from magsoro.cli import main
from magsoro.io.files import atomic_write_json
from magsoro.io.vtk import write_pvd, write_vtp
from magsoro.viz import render as R

SIZE = (320, 240)
BODY_RGB = [np.array([int(c[i : i + 2], 16) for i in (1, 3, 5)]) for c in R._BODY_COLOURS]


def _pyvista_works():
    ok, why = R.pyvista_available()
    return ok, f"PyVista not importable ({why}); pip install -e '.[render]' to run these tests"


PV_OK, PV_WHY = _pyvista_works()
needs_pyvista = pytest.mark.skipif(not PV_OK, reason=PV_WHY)


def make_run(path, dim=3, n_frames=3, colliders=True, fields=None, drop=(), status="completed"):
    """A small run folder: a bending two-part beam (spacing 0.5 mm), a floor, a box, a sphere and a cylinder."""
    h = 0.5e-3
    if dim == 3:
        g = np.stack(np.meshgrid(np.arange(16), np.arange(4), np.arange(2), indexing="ij"), -1).reshape(-1, 3) * h
    else:
        g = np.stack(np.meshgrid(np.arange(16), np.arange(3), indexing="ij"), -1).reshape(-1, 2) * h
    n = len(g)
    body = (g[:, 0] > 11 * h).astype(np.int32)
    (path / "frames").mkdir(parents=True)
    entries = []
    for k in range(n_frames):
        a = 0.4 * k / max(n_frames - 1, 1)  # bend angle at the tip, rad
        s = g[:, 0] / g[:, 0].max()
        x = np.zeros((n, 3))
        x[:, : g.shape[1]] = g
        up = 1 if dim == 2 else 2
        x[:, up] += 0.5 * a * s**2 * g[:, 0].max()
        v = np.zeros((n, dim))
        v[:, up] = 20e-3 * s * (k + 1)
        theta = a * s
        m = np.stack([np.cos(theta), np.zeros(n), np.sin(theta)], 1) if dim == 3 else np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], 1)
        m[body == 1] = 0.0  # a non-magnetic tip part
        data = {"velocity": v.astype(np.float32), "body": body, "clamped": (g[:, 0] == 0).astype(np.uint8),
                "J": np.ones(n, np.float32), "I1bar": (3 + 0.01 * a * (1 - s)).astype(np.float32),
                "magnetization_direction": m.astype(np.float32)}
        for d in drop:
            data.pop(d)
        name = f"frames/frame_{k:05d}.vtp"
        write_vtp(path / name, x, data)
        entries.append((0.01 * k, name))
    write_pvd(path / "particles.pvd", entries)
    scene = {"name": "tiny", "simulation": {"dim": dim, "dx": 1e-3, "domain_lo": [-0.01] * dim, "domain_hi": [0.02] * dim,
                                             "duration": 0.02},
             "bodies": [], "fields": fields if fields is not None else [
                 {"type": "uniform", "B": [0.0, 0.0, 0.02] if dim == 3 else [0.0, 0.02, 0.0], "profile": {"type": "ramp", "duration": 0.02}},
                 {"type": "dipole", "moment": [0.0, 0.0, 1e-3], "position": [0.0, 0.0, 0.05]}]}
    if colliders:
        if dim == 3:
            scene["colliders"] = [{"type": "half_space", "point": [0, 0, -0.5e-3], "normal": [0, 0, 1]},
                                  {"type": "box", "center": [-1.5e-3, 0.75e-3, 0.25e-3], "size": [2e-3, 3e-3, 3e-3], "mode": "sticky"},
                                  {"type": "sphere", "center": [9e-3, 4e-3, 1e-3], "radius": 1e-3},
                                  {"type": "cylinder", "center": [4e-3, -3e-3, 1e-3], "radius": 0.8e-3, "length": 3e-3, "axis": [0, 1, 0],
                                   "path": {"times": [0, 0.02], "positions": [[4e-3, -3e-3, 1e-3], [4e-3, -3e-3, 3e-3]]}}]
        else:
            scene["colliders"] = [{"type": "half_space", "point": [0, -0.5e-3], "normal": [0, 1]},
                                  {"type": "sphere", "center": [9e-3, 4e-3], "radius": 1e-3}]
    info = {"status": status, "message": "", "magsoro_version": "0.1.0", "dim": dim, "n_particles": n,
            "bodies": [{"body": "beam", "particles": int((body == 0).sum())}, {"body": "tip", "particles": int((body == 1).sum())}],
            "scene": scene, "frames": n_frames}
    atomic_write_json(path / "run.json", info)
    return path


@pytest.fixture(scope="module")
def run3d(tmp_path_factory):
    return make_run(tmp_path_factory.mktemp("run3d"))


@pytest.fixture(scope="module")
def run2d(tmp_path_factory):
    return make_run(tmp_path_factory.mktemp("run2d"), dim=2)


def _image(path):
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def _near(img, rgb, tol=70):
    return int((np.abs(img - rgb).sum(axis=2) < tol).sum())


def _check_picture(path, colour_mode):
    img = _image(path)
    assert img.shape == (SIZE[1], SIZE[0], 3)
    assert img.std() > 10, "blank picture"
    assert (img.sum(axis=2) < 600).mean() > 0.01, "hardly anything drawn"
    if colour_mode == "part":  # both parts' colours are on the picture
        assert _near(img, BODY_RGB[0]) > 20 and _near(img, BODY_RGB[1]) > 5


# ------------------------------------------------------------------------------------------ matplotlib
@pytest.mark.parametrize("color", ["part", "speed", "strain", "magnetisation"])
def test_matplotlib_png_each_colour(run3d, tmp_path, color):
    out = tmp_path / f"{color}.png"
    res = R.render_run(run3d, out, color=color, backend="matplotlib", size=SIZE)
    assert res.backend.startswith("matplotlib") and res.frames == 1 and res.particles == 128
    _check_picture(out, color)
    # the dipole is named as not drawn
    assert any("dipole" in n for n in res.notes)


def test_matplotlib_gif_has_every_frame(run3d, tmp_path):
    out = tmp_path / "a.gif"
    res = R.render_run(run3d, out, color="speed", view="y", backend="matplotlib", size=SIZE, fps=5)
    assert res.frames == 3
    with Image.open(out) as im:
        assert im.n_frames == 3
        assert im.info.get("duration") == 200


def test_2d_run_is_drawn_flat(run2d, tmp_path):
    out = tmp_path / "flat.png"
    res = R.render_run(run2d, out, color="part", backend="auto", size=SIZE)
    assert res.backend.startswith("matplotlib") and any("2D run" in n for n in res.notes)
    _check_picture(out, "part")
    out = tmp_path / "flat.gif"
    res = R.render_run(run2d, out, color="magnetisation", frames="0,-1", size=SIZE)
    with Image.open(out) as im:
        assert im.n_frames == 2


def test_auto_falls_back_to_matplotlib_without_pyvista(run3d, tmp_path, monkeypatch):
    monkeypatch.setattr(R, "pyvista_available", lambda: (False, "ModuleNotFoundError: No module named 'pyvista'"))
    out = tmp_path / "fallback.png"
    res = R.render_run(run3d, out, color="strain", size=SIZE)
    assert res.backend.startswith("matplotlib")
    assert any("fell back to matplotlib" in n for n in res.notes)
    _check_picture(out, "strain")
    with pytest.raises(R.RenderError, match="--backend pyvista"):
        R.render_run(run3d, out, backend="pyvista", size=SIZE)


def test_environment_variable_picks_the_backend(run3d, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(R.BACKEND_ENV, "matplotlib")
    assert main(["render", str(run3d), "--out", str(tmp_path / "e.png"), "--size", "320x240"]) == 0
    assert "drawn with matplotlib" in capsys.readouterr().out


def test_field_and_colliders_follow_the_frame_time(run3d):
    ov = R.Overlays(R.open_run(run3d))
    np.testing.assert_allclose(ov.field(0.01), [0, 0, 0.01])  # half-way up the ramp
    shapes = ov.collider_shapes(0.01)
    assert [s["kind"] for s in shapes] == ["half_space", "box", "sphere", "cylinder"]
    np.testing.assert_allclose(shapes[3]["centre"], [4e-3, -3e-3, 2e-3])  # on its path


def test_static_run_frames_are_load_levels(tmp_path):
    run = make_run(tmp_path / "static", colliders=False)
    info = json.loads((run / "run.json").read_text())
    info["static"] = {"t_loads": 0.02, "converged": True}
    atomic_write_json(run / "run.json", info)
    series = R.open_run(run)
    ov = R.Overlays(series)
    np.testing.assert_allclose(ov.field(0.5), [0, 0, 0.01])  # level 0.5 of the full field at t_loads
    assert R.time_label(series, 0.5, 1).startswith("level 0.5")


def test_frame_selection():
    st = [0.0, 0.01, 0.02, 0.03, 0.04]
    assert R.select_frames(None, st, animated=False)[0] == [4]
    assert R.select_frames(None, st, animated=True)[0] == [0, 1, 2, 3, 4]
    assert R.select_frames("0,-1", st, False)[0] == [0, 4]
    assert R.select_frames("::2", st, False)[0] == [0, 2, 4]
    assert R.select_frames("t=0.021,last,first", st, False)[0] == [2, 4, 0]
    assert R.select_frames("all", st, False)[0] == [0, 1, 2, 3, 4]
    idx, note = R.select_frames(None, list(np.arange(500) * 1.0), animated=True)
    assert len(idx) == R.MAX_ANIMATION_FRAMES and idx[0] == 0 and idx[-1] == 499 and "--frames all" in note
    for bad in ("x", "5", "-6", "1:2:0", "3:1", "t=abc", "1:2:3:4", ""):
        with pytest.raises(R.RenderError, match="--frames"):
            R.select_frames(bad, st, False)


def test_strain_scalar_matches_the_log_stretch():
    # uniaxial isochoric stretch 1.05: I1bar = l^2 + 2/l, equivalent log strain = ln l (to second order)
    lam = 1.05
    v = R.colour_values("strain", {"I1bar": np.array([lam**2 + 2 / lam, 3.0])}, 3, None, "f")
    assert v[0] == pytest.approx(100 * np.log(lam), rel=0.02) and v[1] == 0


# ------------------------------------------------------------------------------------------ bad input
def _one_line_error(capsys, argv, *words):
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def test_bad_inputs_give_one_line(run3d, tmp_path, capsys, monkeypatch):
    out = str(tmp_path / "x.png")
    _one_line_error(capsys, ["render", str(tmp_path / "nope"), "--out", out], "RUN_DIR", "does not exist")
    (tmp_path / "empty").mkdir()
    _one_line_error(capsys, ["render", str(tmp_path / "empty"), "--out", out], "RUN_DIR", "not a magsoro run")
    noframes = tmp_path / "noframes"
    noframes.mkdir()
    atomic_write_json(noframes / "run.json", {"status": "completed", "magsoro_version": "0.1.0", "dim": 3, "scene": {}})
    _one_line_error(capsys, ["render", str(noframes), "--out", out], "RUN_DIR", "no particle frames")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--frames", "7"], "--frames", "out of range", "3 frames")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--frames", "a-b"], "--frames", "slice")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--frames", "0:2"], "--frames", ".png holds one frame")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--color", "rainbow"], "--color", "part, speed, strain, magnetisation")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--view", "top"], "--view", "iso, x, y, z")
    _one_line_error(capsys, ["render", str(run3d), "--out", str(tmp_path / "x.jpg")], "--out", ".png", ".gif", ".mp4")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--size", "big"], "--size", "WIDTHxHEIGHT")
    _one_line_error(capsys, ["render", str(run3d), "--out", out, "--backend", "povray"], "--backend", "auto, pyvista, matplotlib")
    monkeypatch.setattr(R, "find_ffmpeg", lambda: None)
    _one_line_error(capsys, ["render", str(run3d), "--out", str(tmp_path / "x.mp4")], "--out", "ffmpeg", "pip install imageio-ffmpeg", ".gif")


def test_missing_data_and_2d_views_give_one_line(tmp_path, run2d, capsys):
    run = make_run(tmp_path / "nostrain", drop=("I1bar", "velocity"))
    out = str(tmp_path / "x.png")
    err = _one_line_error(capsys, ["render", str(run), "--out", out, "--color", "strain", "--backend", "matplotlib"],
                          "--color strain", "'I1bar'")
    assert "part, magnetisation" in err
    _one_line_error(capsys, ["render", str(run2d), "--out", out, "--view", "iso"], "--view", "2D run")


def test_mp4_when_ffmpeg_is_there(run3d, tmp_path):
    if R.find_ffmpeg() is None:
        pytest.skip("no ffmpeg (pip install imageio-ffmpeg)")
    out = tmp_path / "a.mp4"
    R.render_run(run3d, out, color="part", backend="matplotlib", size=SIZE, frames="0,-1")
    data = out.read_bytes()
    assert len(data) > 1000 and b"ftyp" in data[:32]


# ------------------------------------------------------------------------------------------ PyVista
@needs_pyvista
@pytest.mark.parametrize("color", ["part", "speed", "strain", "magnetisation"])
def test_pyvista_png_each_colour(run3d, tmp_path, color):
    out = tmp_path / f"pv_{color}.png"
    res = R.render_run(run3d, out, color=color, backend="pyvista", size=SIZE, view="iso" if color != "speed" else "x")
    assert res.backend.startswith("pyvista")
    _check_picture(out, color)


@needs_pyvista
def test_pyvista_gif_and_auto_choice(run3d, tmp_path, monkeypatch):
    monkeypatch.delenv(R.BACKEND_ENV, raising=False)
    out = tmp_path / "pv.gif"
    res = R.render_run(run3d, out, color="magnetisation", view="z", size=SIZE)
    assert res.backend.startswith("pyvista") and res.frames == 3
    with Image.open(out) as im:
        assert im.n_frames == 3


# ------------------------------------------------------------------------------------------ a real run
@pytest.mark.slow
def test_render_a_real_tiny_run(tmp_path, capsys):
    """A short 3D run through the command line (compiles the kernels on a cold cache), then drawn."""
    scene = tmp_path / "s.toml"
    scene.write_text(
        'name = "tiny3d"\n[simulation]\ndim = 3\ndx = 1.0e-3\nparticles_per_cell = 2\ndomain_lo = [-0.004, -0.004, -0.006]\n'
        "domain_hi = [0.012, 0.004, 0.006]\nduration = 0.002\ndamping = 100.0\n"
        '[[bodies]]\nname = "beam"\nshape = { type = "box", center = [0.004, 0.0, 0.0], size = [0.008, 0.002, 0.002] }\n'
        "material = { density = 1030.0, shear_modulus = 3.0e5 }\nmagnetization = [0.1, 0.0, 0.0]\n"
        '[[clamps]]\nregion = { type = "box", center = [0.0, 0.0, 0.0], size = [0.001, 0.004, 0.004] }\n'
        '[[colliders]]\ntype = "half_space"\npoint = [0.0, 0.0, -0.003]\nnormal = [0.0, 0.0, 1.0]\n'
        '[[fields]]\ntype = "uniform"\nB = [0.0, 0.0, 0.01]\n[output]\nevery = 0.001\n'
    )
    assert main(["run", str(scene), "--out", str(tmp_path / "r"), "--quiet"]) == 0
    info = json.loads((tmp_path / "r" / "run.json").read_text())
    for color in R.COLOR_MODES:
        out = tmp_path / f"{color}.png"
        assert main(["render", str(tmp_path / "r"), "--out", str(out), "--color", color, "--size", "320x240"]) == 0
        _check_picture(out, "speed")
    assert info["frames"] >= 2


def test_held_particles_are_drawn_dark_grey(run2d, tmp_path):
    """The frames' ``clamped`` flag: held particles are drawn in the held colour in any colour mode and a note
    says so. Pixels of that colour: 323 with the flag, 50 without (text and scale bar edges)."""
    held_rgb = np.array([0x3a, 0x3a, 0x3a])
    out = tmp_path / "held.png"
    res = R.render_run(run2d, out, color="speed", backend="matplotlib", size=SIZE)
    assert any("held by a clamp" in n for n in res.notes)
    n_held = _near(_image(out), held_rgb, tol=12)
    bare = make_run(tmp_path / "bare", dim=2, drop=("clamped",))
    out2 = tmp_path / "bare.png"
    res2 = R.render_run(bare, out2, color="speed", backend="matplotlib", size=SIZE)
    assert not any("held by a clamp" in n for n in res2.notes)
    assert n_held > 3 * _near(_image(out2), held_rgb, tol=12)


def test_field_label_drops_round_off():
    """A field turned by 90 degrees has components of 1e-15 of its magnitude: shown as 0."""
    label = R.field_label(np.array([0.02 * np.cos(np.pi / 2), 0.02, 0.0]), 3)
    assert label == "B = 20 mT (0, 20, 0)"
