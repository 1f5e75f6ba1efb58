"""A run stopped by SIGTERM (timeout, Slurm, docker stop) ends like Ctrl-C: run.json says 'interrupted' and names
the signal, the final state is written, the exit status is 143 (issue "Reliability", finding 1)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

SCENE = """
[simulation]
dim = 2
dx = 5e-4
domain_lo = [0.0, 0.0]
domain_hi = [0.02, 0.02]
duration = 100.0
gravity = [0.0, -9.81]

[[bodies]]
name = "block"
shape = { type = "rectangle", center = [0.01, 0.01], size = [0.004, 0.004] }
material = { density = 1000.0, shear_modulus = 1e5 }

[[colliders]]
type = "half_space"
point = [0.0, 0.005]
normal = [0.0, 1.0]

[output]
every = 0.002
particles = false
"""


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigterm_ends_a_run_with_a_true_run_json(tmp_path):
    scene = tmp_path / "block.toml"
    scene.write_text(SCENE)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "magsoro", "run", str(scene), "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "MAGSORO_THREADS": "1"})
    metrics = out / "metrics.csv"
    deadline = time.time() + 120
    while time.time() < deadline and not (metrics.exists() and len(metrics.read_text().splitlines()) > 3):
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    info = json.loads((out / "run.json").read_text())
    assert info["status"] == "interrupted"
    assert info["message"].startswith("terminated by SIGTERM at t = ")
    assert (out / "final.npz").exists()
    assert "Traceback" not in err
