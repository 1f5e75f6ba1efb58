"""Synthetic S-shape sensing data for examples/actuation/calib_two_stations.toml.

Writes OUTDIR/readings.csv (t, s1, s2 in s and T) and OUTDIR/truth.csv (t, s, x, y, z: the true centrelines)
for two 30 mm segments bending in opposite senses (an S), sampled at 100 Hz for 2 s, with 5 uT of Gaussian
sensor noise. Then:

    magsoro sense OUTDIR/readings.csv --calib examples/actuation/calib_two_stations.toml --out OUTDIR/sense \
        --truth OUTDIR/truth.csv
"""

import csv
import sys
from pathlib import Path

import numpy as np

from magsoro.actuation.config import SensingCalibration, load
from magsoro.actuation.sensing import reconstruct_centreline, stations_from_calibration, synthetic_readings, write_centrelines


def main(out: Path, noise: float = 5e-6, rate: float = 100.0, duration: float = 2.0, seed: int = 4) -> None:
    calib = load(SensingCalibration, Path(__file__).with_name("calib_two_stations.toml"))
    stations = stations_from_calibration(calib)
    t = np.arange(0.0, duration, 1.0 / rate)
    phase = 2 * np.pi * 0.5 * t
    beta = np.stack([np.radians(60.0) * np.sin(phase), -np.radians(70.0) * np.sin(phase + 0.4)], axis=1)
    readings = synthetic_readings(stations, beta, noise, seed)
    out.mkdir(parents=True, exist_ok=True)
    with (out / "readings.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", *[s.column for s in stations]])
        for k in range(len(t)):
            w.writerow([f"{t[k]:.6f}", *[f"{v:.9e}" for v in readings[k]]])
    s, pts = reconstruct_centreline(beta, [st.segment_length for st in stations], calib.points_per_segment,
                                    calib.base_position, calib.base_tangent, calib.bend_normal)
    write_centrelines(out / "truth.csv", t, s, pts)
    print(f"wrote {out / 'readings.csv'} and {out / 'truth.csv'}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "out/sensing_example"))
