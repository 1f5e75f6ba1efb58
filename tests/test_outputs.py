"""Output folders and output errors (issue "Reliability", findings 2 and 11): a full disk, a read-only folder or an
--out naming a file gives one line, and a run that loses its output mid-way ends 'failed' with the reason in
run.json; a folder is reused only when it holds a previous run and --overwrite is given, and then nothing of the
old run remains; run.json carries the pid and a heartbeat, and a run killed without writing reads as stale."""

import errno
import json
import os
import tempfile
import types

import pytest

from magsoro.cli import main
from magsoro.io import files
from magsoro.io.outdir import run_state

SCENE = """
[simulation]
dim = 2
dx = 1e-3
domain_lo = [0.0, 0.0]
domain_hi = [0.02, 0.02]
duration = 0.004
gravity = [0.0, -9.81]

[[bodies]]
name = "block"
shape = { type = "rectangle", center = [0.01, 0.01], size = [0.004, 0.004] }
material = { density = 1000.0, shear_modulus = 1e5 }

[[probes]]
type = "centroid"
name = "c"
body = "block"

[output]
every = 0.001
"""


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "block.toml"
    path.write_text(SCENE)
    return path


def _run(scene, out, *extra):
    return main(["run", str(scene), "--out", str(out), "--quiet", *extra])


def _one_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _fail_writes(monkeypatch, err_no: int, after: int = 0, names=None):
    """Atomic writes fail with ``err_no`` after ``after`` successful ones (only for files named in ``names``)."""
    calls = {"n": 0}
    real = tempfile.mkstemp

    def mkstemp(*args, **kw):
        target = kw.get("prefix", "")
        if names is None or any(target.startswith(f".{n}") for n in names):
            calls["n"] += 1
            if calls["n"] > after:
                raise OSError(err_no, os.strerror(err_no))
        return real(*args, **kw)

    monkeypatch.setattr(files, "tempfile", types.SimpleNamespace(mkstemp=mkstemp))


def test_out_naming_an_existing_file_is_refused(scene, tmp_path, capsys):
    target = tmp_path / "results.txt"
    target.write_text("keep me")
    assert _run(scene, target) == 2
    line = _one_line(capsys.readouterr().err)
    assert str(target) in line and "is a file" in line
    assert target.read_text() == "keep me"


def test_a_full_disk_at_the_start_is_one_line(scene, tmp_path, monkeypatch, capsys):
    _fail_writes(monkeypatch, errno.ENOSPC)
    assert _run(scene, tmp_path / "out") == 2
    line = _one_line(capsys.readouterr().err)
    assert "run.json" in line and "No space left on device" in line


def test_a_read_only_folder_is_one_line(scene, tmp_path, monkeypatch, capsys):
    """(As root, chmod does not stop writes, so the operating system's answer is simulated.)"""
    _fail_writes(monkeypatch, errno.EACCES)
    assert _run(scene, tmp_path / "out") == 2
    assert "Permission denied" in _one_line(capsys.readouterr().err)


def test_a_full_disk_mid_run_ends_failed_with_the_reason(scene, tmp_path, monkeypatch, capsys):
    """metrics.csv cannot be written from the third record on (a quota reached): the run stops, run.json (still
    writable) says 'failed' and why, and the state reached is kept."""
    _fail_writes(monkeypatch, errno.ENOSPC, after=2, names=("metrics.csv",))
    out = tmp_path / "out"
    assert _run(scene, out) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "failed" in err
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "failed"
    assert "No space left on device" in info["message"] and "metrics.csv" in info["message"]
    assert info["message"].startswith("output at t = 0.002 s") and (out / "last_good.npz").exists()


def test_a_previous_run_is_replaced_only_with_overwrite(scene, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(scene, out) == 0
    n_frames = len(list((out / "frames").glob("*.vtp")))
    (out / "report.html").write_text("old report")
    (out / "frames" / "frame_09999.vtp").write_text("old frame")
    capsys.readouterr()
    assert _run(scene, out) == 2
    line = _one_line(capsys.readouterr().err)
    assert "previous run" in line and "--overwrite" in line
    assert (out / "report.html").exists()  # refused: nothing touched
    assert _run(scene, out, "--overwrite") == 0
    assert not (out / "report.html").exists()
    assert len(list((out / "frames").glob("*.vtp"))) == n_frames
    assert json.loads((out / "run.json").read_text())["status"] == "completed"


def test_a_folder_with_other_files_is_refused_even_with_overwrite(scene, tmp_path, capsys):
    out = tmp_path / "thesis"
    out.mkdir()
    (out / "chapter1.tex").write_text("precious")
    for extra in ((), ("--overwrite",)):
        assert _run(scene, out, *extra) == 2
        assert "not empty" in _one_line(capsys.readouterr().err)
    assert (out / "chapter1.tex").read_text() == "precious"


def test_run_json_has_pid_and_heartbeat_and_a_killed_run_reads_stale(scene, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(scene, out) == 0
    info = json.loads((out / "run.json").read_text())
    assert info["pid"] == os.getpid() and isinstance(info["heartbeat_unix"], float)
    assert run_state(info) == ("completed", "")
    # what a SIGKILLed run leaves: status 'running', its process gone
    info.update(status="running", pid=2**22 + 12345)
    assert run_state(info)[0] == "stale"
    info.update(pid=os.getpid())
    assert run_state(info)[0] == "running"
    info.update(machine="another-host", heartbeat_unix=info["heartbeat_unix"] - 3600)
    assert run_state(info)[0] == "stale"
    info.update(status="running", pid=2**22 + 12345, machine=json.loads((out / "run.json").read_text())["machine"])
    (out / "run.json").write_text(json.dumps(info))
    capsys.readouterr()
    assert main(["report", str(out), "--out", str(tmp_path / "r.html")]) == 0
    assert "stale" in capsys.readouterr().err
    assert "stale" in (tmp_path / "r.html").read_text()


def test_run_json_is_strict_json(tmp_path):
    """NaN and inf have no JSON form: written as null, never as the non-JSON tokens NaN / Infinity."""
    import math

    files.atomic_write_json(tmp_path / "x.json", {"a": math.inf, "b": [1.0, math.nan]})
    text = (tmp_path / "x.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    assert json.loads(text) == {"a": None, "b": [1.0, None]}


def test_atomic_writes_give_files_the_umask_mode(tmp_path):
    """Outputs written through a temp file (mkstemp makes it 0600) end with the mode open() would give them."""
    import os

    from magsoro.io.files import atomic_save_npz, atomic_write_bytes

    mask = os.umask(0o022)
    os.umask(mask)
    atomic_write_bytes(tmp_path / "a.bin", b"x")
    atomic_save_npz(tmp_path / "b.npz", x=[1.0])
    for name in ("a.bin", "b.npz"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~mask
