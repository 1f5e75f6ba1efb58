"""``magsoro doctor``: the JSON report and its CPU parity result, the text naming what was not checked, the refused
CUDA device, a failing compile check, and the real PTX compile path when magsoro.cuda_compile exists."""

import importlib.util
import json
import math
import subprocess
import sys
import types

import pytest
import warp as wp

# run the command as `magsoro doctor` does, registering it when cli.COMMANDS does not name it (yet)
_RUN = ("import sys, magsoro.cli as c\n"
        "'magsoro.commands.doctor' in c.COMMANDS or c.COMMANDS.append('magsoro.commands.doctor')\n"
        "sys.exit(c.main(sys.argv[1:]))")

HAS_CUDA = wp.get_cuda_device_count() > 0


def _doctor(*args, timeout=1800):
    # generous timeout: on a cold kernel cache the parity runs compile the engine first (minutes on 2 cores)
    return subprocess.run([sys.executable, "-c", _RUN, "doctor", *args], check=False, capture_output=True, text=True, timeout=timeout)


@pytest.fixture
def cli(monkeypatch):
    import magsoro.cli

    if "magsoro.commands.doctor" not in magsoro.cli.COMMANDS:
        monkeypatch.setattr(magsoro.cli, "COMMANDS", [*magsoro.cli.COMMANDS, "magsoro.commands.doctor"])
    return magsoro.cli.main


# slow: on a cold kernel cache (CI) the parity runs compile the 3D contact engine for CPU in both precisions,
# about 6 minutes on 2 cores; warm, a few seconds
@pytest.mark.slow
def test_doctor_json_has_parity_result_and_names_what_was_not_checked():
    from magsoro.doctor import PARITY_DX, PARITY_THRESHOLD_CELLS

    out = _doctor("--json", "--no-compile")
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)  # stdout carries only the JSON object
    for key in ("versions", "cpu", "memory", "cuda", "devices", "kernel_cache", "checks", "not_checked", "ok"):
        assert key in report
    assert report["versions"]["warp"] == wp.config.version and report["versions"]["magsoro"]
    assert report["memory"]["total_bytes"] > 0 and report["cpu"]["cores"] >= 1
    assert report["kernel_cache"]["dir"]
    parity = report["checks"]["parity"]
    assert parity["status"] == "passed" and report["ok"] and report["exit_code"] == 0
    assert parity["reference"]["device"] == "cpu" and parity["contact_active"] and parity["field_gradient_max_T_per_m"] > 0
    diff = parity["max_position_difference_m"]
    assert math.isfinite(diff) and diff <= parity["threshold_m"] == pytest.approx(PARITY_THRESHOLD_CELLS * PARITY_DX)
    assert parity["max_displacement_m"] > 100 * parity["threshold_m"]  # the scene moves: the difference means something
    assert all(r["steps_per_s"] > 0 for r in parity["runs"]) and len(parity["runs"]) == 2
    assert report["checks"]["compile"] == {"status": "not checked", "reason": "--no-compile"}
    assert "compile: --no-compile" in report["not_checked"]
    if not HAS_CUDA:
        assert report["device"] == "cpu"
        assert (parity["reference"]["precision"], parity["test"]["precision"]) == ("float64", "float32")
        assert report["checks"]["cuda"]["status"] == "not checked"
        assert any(t.startswith("CUDA: ") for t in report["not_checked"])
        assert report["cuda"]["device_count"] == 0
        if not report["cuda"]["driver_available"]:
            assert "CUDA: no CUDA driver" in report["not_checked"]


# slow: on a cold kernel cache (CI) the parity runs compile the 3D contact engine for CPU in both precisions,
# about 6 minutes on 2 cores; warm, a few seconds
@pytest.mark.slow
def test_doctor_text_names_each_check_not_done():
    out = _doctor("--no-compile", "--device", "cpu")
    assert out.returncode == 0, out.stderr
    text = out.stdout
    assert "parity" in text and "passed" in text and "largest position difference" in text and "steps/s" in text
    assert "not checked:" in text
    assert "compile: --no-compile" in text
    assert "CUDA: " in text.split("not checked:", 1)[1]  # CUDA named with its reason
    if not HAS_CUDA:
        assert "float32 vs cpu float64" in text


@pytest.mark.skipif(HAS_CUDA, reason="needs a machine without CUDA")
def test_doctor_refuses_cuda_without_one():
    for device in ("cuda", "cuda:0"):
        out = _doctor("--device", device, "--json", timeout=300)
        assert out.returncode == 2
        assert out.stdout == ""
        lines = out.stderr.strip().splitlines()
        assert len(lines) == 1, out.stderr  # one line: Warp's own driver warning is kept off the terminal
        assert lines[0].startswith(f"magsoro doctor: error: --device {device}: no CUDA device")


def test_doctor_refuses_unknown_device(cli, capsys):
    assert cli(["doctor", "--device", "tpu"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == "magsoro doctor: error: --device tpu: expected cpu, cuda or cuda:N"


def _fake_cuda_compile(ok: bool, calls: list):
    from dataclasses import dataclass

    @dataclass
    class CompileResult:
        name: str
        arch: int
        ok: bool
        seconds: float
        error: str

    mod = types.ModuleType("magsoro.cuda_compile")
    mod.CompileResult = CompileResult
    mod.warp_modules = lambda: [("engine 2D float64", object()), ("engine 3D float32", object()),
                                ("engine 3D float64", object()), ("field sources float32", object())]

    def compile_to_ptx(modules=None, archs=(80, 90), output_dir=None):
        calls.append(([m[0] for m in modules], tuple(archs), output_dir))
        return [CompileResult(m[0], a, ok, 0.5, "" if ok else "ptxas fatal   : Unresolved extern function 'boom'\nsecond line")
                for m in modules for a in archs]

    mod.compile_to_ptx = compile_to_ptx
    return mod


def _stub_checks(monkeypatch):
    """No parity runs (tested above) and NVRTC reported available, so the PTX compile path is taken."""
    from magsoro import doctor

    monkeypatch.setattr(doctor, "parity_check", lambda device: {
        "status": "passed", "reference": {"device": "cpu", "precision": "float64"},
        "test": {"device": "cpu", "precision": "float32"}, "steps": 1, "dt": 1e-6})
    real = doctor.cuda_info
    monkeypatch.setattr(doctor, "cuda_info", lambda: {**real(), "nvrtc_available": True})


@pytest.mark.parametrize("json_mode", [False, True])
def test_failing_compile_fails_doctor_and_shows_the_error(cli, capsys, monkeypatch, json_mode):
    calls = []
    monkeypatch.setitem(sys.modules, "magsoro.cuda_compile", _fake_cuda_compile(False, calls))
    _stub_checks(monkeypatch)
    rc = cli(["doctor", "--device", "cpu"] + (["--json"] if json_mode else []))
    out = capsys.readouterr().out
    assert rc == 1
    assert calls and calls[0][0] == ["engine 3D float32"] and calls[0][1] == (90,)  # the subset (here one label), one arch
    if json_mode:
        report = json.loads(out)
        c = report["checks"]["compile"]
        assert c["status"] == "failed" and report["failed"] == ["compile"] and report["exit_code"] == 1
        assert "Unresolved extern function 'boom'" in c["results"][0]["error"]
    else:
        assert "compile   failed" in out and "Unresolved extern function 'boom'" in out and "result: FAILED: compile" in out


def test_passing_compile_and_missing_module(cli, capsys, monkeypatch):
    calls = []
    monkeypatch.setitem(sys.modules, "magsoro.cuda_compile", _fake_cuda_compile(True, calls))
    _stub_checks(monkeypatch)
    assert cli(["doctor", "--device", "cpu", "--json"]) == 0
    c = json.loads(capsys.readouterr().out)["checks"]["compile"]
    assert c["status"] == "passed" and c["modules"] == ["engine 3D float32"] and c["modules_available"] == 4
    # a module that cannot be imported: not checked, with the reason (not a failure)
    monkeypatch.setitem(sys.modules, "magsoro.cuda_compile", None)  # import raises ImportError
    assert cli(["doctor", "--device", "cpu", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["checks"]["compile"]["status"] == "not checked"
    assert any(t.startswith("compile: magsoro.cuda_compile not importable") for t in report["not_checked"])


def test_to_json_is_strict():
    from magsoro.doctor import to_json

    assert json.loads(to_json({"a": float("nan"), "b": [1.0, float("inf")], "c": {"d": 2}})) == {"a": None, "b": [1.0, None], "c": {"d": 2}}


def test_parity_fails_on_a_difference_above_the_threshold_or_a_non_finite_position(monkeypatch):
    import numpy as np

    from magsoro import doctor

    x0 = np.zeros((8, 3))

    def fake_run(shift):
        def run(precision, device, steps=doctor.PARITY_STEPS):
            x = x0 + 1e-4 + (shift if precision == "float32" else 0.0)
            return {"x": x, "x0": x0, "particles": 8, "contact": True, "field_gradient_max": 1.0,
                    "first_step_s": 0.1, "steps_per_s": 100.0}
        return run

    monkeypatch.setattr(doctor, "_parity_run", fake_run(0.5 * doctor.PARITY_THRESHOLD_CELLS * doctor.PARITY_DX))
    assert doctor.parity_check("cpu")["status"] == "passed"
    monkeypatch.setattr(doctor, "_parity_run", fake_run(2.0 * doctor.PARITY_THRESHOLD_CELLS * doctor.PARITY_DX))
    c = doctor.parity_check("cpu")
    assert c["status"] == "failed" and "above the threshold" in c["error"]
    monkeypatch.setattr(doctor, "_parity_run", fake_run(float("nan")))
    c = doctor.parity_check("cpu")
    assert c["status"] == "failed" and c["max_position_difference_m"] is None and "non-finite" in c["error"]

    def broken(precision, device, steps=doctor.PARITY_STEPS):
        raise RuntimeError("kernel launch failed")

    monkeypatch.setattr(doctor, "_parity_run", broken)
    c = doctor.parity_check("cpu")
    assert c["status"] == "failed" and "kernel launch failed" in c["error"]
    text = doctor.format_text({**_fake_report(), "checks": {"cuda": {"status": "not checked", "reason": "no CUDA driver"},
                                                            "compile": {"status": "not checked", "reason": "--no-compile"},
                                                            "parity": c},
                               "not_checked": ["CUDA: no CUDA driver", "compile: --no-compile"], "failed": ["parity"], "ok": False})
    assert "parity    failed" in text and "kernel launch failed" in text and "result: FAILED: parity" in text


def _fake_report():
    return {"device": "cpu", "seconds": 1.0,
            "versions": {"magsoro": "0", "warp": "1", "numpy": "2", "python": "3", "os": "os", "machine": "m"},
            "cpu": {"model": "cpu", "cores": 2, "usable_cores": 2}, "memory": {"total_bytes": 2**30, "available_bytes": None},
            "cuda": {"driver_available": False, "driver_version": None, "toolkit_version": None, "nvrtc_available": False,
                     "nvrtc_archs": [], "device_count": 0},
            "devices": [{"alias": "cpu", "name": "CPU", "kind": "cpu"}],
            "kernel_cache": {"dir": "/nowhere", "exists": False}}


# can take minutes: NVRTC compiles whole Warp modules (about 20 s each on 2 cores, more when a module holds many
# engine variants)
@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("magsoro.cuda_compile") is None, reason="magsoro.cuda_compile is not in this tree yet")
def test_real_compile_check():
    # in its own process: building the engine variants for PTX adds kernels to the engine's Warp modules, which
    # would make later CPU runs in this process compile those larger modules afresh
    code = ("import json\nfrom magsoro.doctor import compile_check, init_warp\ninit_warp()\n"
            "print(json.dumps(compile_check('cpu')))")
    out = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=1800)
    assert out.returncode == 0, out.stderr
    c = json.loads(out.stdout.strip().splitlines()[-1])
    if not wp.get_cuda_supported_archs():
        assert c["status"] == "not checked"
        return
    assert c["status"] == "passed", c
    assert c["results"] and all(r["ok"] for r in c["results"])
