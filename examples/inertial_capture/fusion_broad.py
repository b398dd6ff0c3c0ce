#!/usr/bin/env python3
"""BROAD: x-io Fusion AHRS (imufusion, 6-axis: no magnetometer) side by side with the one-board
orientation filter of inertial-acoustic, tuned on one trial and scored on another with one
metric in one run.

Not part of CI. Needs a venv with numpy, h5py and imufusion; run through
bench/inertial_vs_peers.sh, or by hand after
`cargo run --release --example inertial_capture -- --real-only`:

    python3 examples/inertial_capture/fusion_broad.py \
        --tuning data/imu-broad/09_undisturbed_fast_rotation_with_breaks_B_first60s.hdf5 \
        --test data/imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5 \
        --ours out/inertial_capture/broad_ours.csv

The trials are read from BROAD's HDF5 layout (the excerpts in data/imu-broad/ or the
published files) as the Rust reader reads them: sample k at k / sampling_rate seconds.

Protocol (the same as the Rust example's, `real_imu.rs`):
* error rotation q_ref * q_est^-1 (ENU); heading = its twist about z, inclination = the swing;
  the constant heading offset (circular mean) is removed; movement samples with a finite
  reference only (BROAD's `movement` flag); combined = sqrt(incl^2 + head^2);
* Fusion's gain is chosen on GAIN_GRID by the combined RMSE over the tuning trial's (09)
  movement samples; the figures are over the test trial's (07) movement samples. The grid runs
  from gain 0 (gyroscope integration only) to 10 and its choice is reported as interior or
  not (`*_tuning_interior`). Ours is tuned by the example on its own grid, on trial 09 too,
  and read from its output (`broad_ours.csv`, the test trial's estimate).
* Fusion runs twice: on the readings as they are, and with the gyroscope offset ours removes
  (each trial's mean reading over its first 20 s of rest) subtracted beforehand.
* Fusion settings: ENU convention, 286 Hz, gyroscope range 2000 deg/s, acceleration rejection
  at its default; Fusion runs from the first sample (its 3 s start-up ramp falls in the
  trials' rest: movement starts at 30.1 s in 09 and at 26.5 s in 07).

Prints one JSON line.
"""
import argparse
import json
import time
from importlib.metadata import version

import h5py
import numpy as np

GAIN_GRID = [0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0]
REST_S = 20.0


def qmul(a, b):
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], 1)


def score(est, ref, mask):
    m = mask & np.isfinite(ref).all(1)
    e = qmul(ref[m], est[m] * np.array([1, -1, -1, -1]))
    head = 2 * np.arctan2(e[:, 3], e[:, 0])
    incl = 2 * np.arccos(np.minimum(1.0, np.hypot(e[:, 0], e[:, 3])))
    off = np.arctan2(np.sin(head).mean(), np.cos(head).mean())
    he = np.angle(np.exp(1j * (head - off)))
    i = float(np.degrees(np.sqrt(np.mean(incl ** 2))))
    h = float(np.degrees(np.sqrt(np.mean(he ** 2))))
    return {"inclination_deg": i, "heading_deg": h, "combined_deg": float(np.hypot(i, h)),
            "samples": int(m.sum())}


def fusion(gyr_dps, acc_g, gain):
    import imufusion
    ahrs = imufusion.Ahrs()
    s = imufusion.AhrsSettings()
    s.convention = imufusion.CONVENTION_ENU
    s.gain = gain
    s.gyroscope_range = 2000
    s.sample_rate = 286
    ahrs.set_settings(s)
    est = np.empty((len(gyr_dps), 4))
    t0 = time.perf_counter()
    for i in range(len(gyr_dps)):
        ahrs.update_no_magnetometer(gyr_dps[i], acc_g[i])
        est[i] = ahrs.get_quaternion()
    return est, time.perf_counter() - t0


def load(path):
    """A BROAD trial (HDF5): times, gyroscope deg/s, accelerometer g, reference, movement."""
    with h5py.File(path, "r") as f:
        gyr = np.degrees(f["imu_gyr"][:])
        acc = f["imu_acc"][:] / 9.80665
        ref = f["opt_quat"][:]
        mv = f["movement"][:].astype(bool)
        t = np.arange(len(gyr)) / float(f.attrs["sampling_rate"])
    return {"t": t, "gyr": gyr, "acc": acc, "ref": ref, "mv": mv, "rest": t - t[0] < REST_S}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tuning",
                    default="data/imu-broad/09_undisturbed_fast_rotation_with_breaks_B_first60s.hdf5")
    ap.add_argument("--test", default="data/imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5")
    ap.add_argument("--ours", default="out/inertial_capture/broad_ours.csv")
    args = ap.parse_args()
    tune, test = load(args.tuning), load(args.test)

    out = {
        "workload": "broad_orientation_tune_09_test_07",
        "peer": f"imufusion-{version('imufusion')}:Ahrs.update_no_magnetometer",
        "tuning_trial": args.tuning,
        "test_trial": args.test,
    }
    # Fusion as it is, and fed the gyroscope with the same rest offset ours removes (the mean
    # reading over each trial's first 20 s, the thesis's initialisation).
    for name, offset in (("fusion", False), ("fusion_offset_removed", True)):
        def gyro(d):
            return d["gyr"] - d["gyr"][d["rest"]].mean(0) if offset else d["gyr"]
        grid = []
        for g in GAIN_GRID:
            est, _ = fusion(gyro(tune), tune["acc"], g)
            grid.append({"gain": g, "tuning": score(est, tune["ref"], tune["mv"])})
        best = min(range(len(grid)), key=lambda k: grid[k]["tuning"]["combined_deg"])
        gain = GAIN_GRID[best]
        for r in grid:
            est, secs = fusion(gyro(test), test["acc"], r["gain"])
            r["test"] = score(est, test["ref"], test["mv"])
            r["seconds"] = secs
        out[f"{name}_gain"] = gain
        out[f"{name}_tuning_interior"] = 0 < best < len(GAIN_GRID) - 1
        out[f"{name}_tuning_rmse_deg"] = grid[best]["tuning"]
        out[f"{name}_test_rmse_deg"] = grid[best]["test"]
        out[f"{name}_gyro_only_test_rmse_deg"] = grid[GAIN_GRID.index(0.0)]["test"]
        out[f"{name}_seconds"] = grid[best]["seconds"]
        out[f"{name}_grid"] = grid
    try:
        o = np.genfromtxt(args.ours, delimiter=",", names=True)
        ours = np.stack([o["qw"], o["qx"], o["qy"], o["qz"]], 1)
        if len(ours) != len(test["t"]):
            raise ValueError(f"{args.ours}: {len(ours)} rows, the test trial has {len(test['t'])}")
        out["ours_test_rmse_deg"] = score(ours, test["ref"], test["mv"])
    except OSError as e:
        out["ours_error"] = str(e)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
