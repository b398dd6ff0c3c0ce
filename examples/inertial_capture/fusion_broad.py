#!/usr/bin/env python3
"""BROAD trial 07: x-io Fusion AHRS (imufusion, 6-axis: no magnetometer) side by side with the
one-board orientation filter of inertial-acoustic, scored with one metric in one run.

Not part of CI. Needs a venv with numpy and imufusion; run through bench/inertial_vs_peers.sh,
or by hand after `cargo run --release --example inertial_capture -- --quick`:

    python3 examples/inertial_capture/fusion_broad.py \
        --csv data/imu-broad/07_undisturbed_fast_rotation_B_first60s.csv \
        --ours out/inertial_capture/broad_ours.csv

Protocol (the same as the Rust example's, `real_imu.rs`):
* error rotation q_ref * q_est^-1 (ENU); heading = its twist about z, inclination = the swing;
  the constant heading offset (circular mean) is removed; movement samples with a finite
  reference only (BROAD's `movement` flag);
* the gain is chosen on the grid GAIN_GRID (ours: accelerometer sigma in m/s^2; Fusion: its
  gain) by sqrt(incl^2 + head^2) RMSE on the first half of the movement samples; the figures
  are over all movement samples and over the held-out second half.
* Fusion runs twice: on the readings as they are, and with the gyroscope offset ours removes
  (mean over the first 20 s of rest) subtracted beforehand.
* Fusion settings: ENU convention, 286 Hz, gyroscope range 2000 deg/s, acceleration rejection
  at its default; Fusion runs from the first sample (its 3 s start-up ramp falls in BROAD's
  26 s rest). Ours is read from the example's output (`broad_ours.csv`).

Prints one JSON line.
"""
import argparse
import json
import time
from importlib.metadata import version

import numpy as np

GAIN_GRID = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0]


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
    return {"inclination_deg": float(np.degrees(np.sqrt(np.mean(incl ** 2)))),
            "heading_deg": float(np.degrees(np.sqrt(np.mean(he ** 2)))),
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csv", default="data/imu-broad/07_undisturbed_fast_rotation_B_first60s.csv")
    ap.add_argument("--ours", default="out/inertial_capture/broad_ours.csv")
    args = ap.parse_args()
    d = np.genfromtxt(args.csv, delimiter=",", names=True)
    t = d["t_s"]
    gyr = np.degrees(np.stack([d["gyr_x_rad_s"], d["gyr_y_rad_s"], d["gyr_z_rad_s"]], 1))
    acc = np.stack([d["acc_x_m_s2"], d["acc_y_m_s2"], d["acc_z_m_s2"]], 1) / 9.80665
    ref = np.stack([d["opt_qw"], d["opt_qx"], d["opt_qy"], d["opt_qz"]], 1)
    mv = d["movement"] > 0
    split_t = t[mv][len(t[mv]) // 2]
    tune, held = mv & (t < split_t), mv & (t >= split_t)

    out = {
        "workload": "broad_07_orientation",
        "peer": f"imufusion-{version('imufusion')}:Ahrs.update_no_magnetometer",
        "split_t_s": float(split_t),
    }
    # Fusion as it is, and fed the gyroscope with the same rest offset ours removes (the mean
    # reading over the first 20 s, the thesis's initialisation).
    rest = t - t[0] < 20.0
    for name, g_in in (("fusion", gyr), ("fusion_offset_removed", gyr - gyr[rest].mean(0))):
        grid = []
        for g in GAIN_GRID:
            est, secs = fusion(g_in, acc, g)
            s = score(est, ref, tune)
            grid.append({"gain": g, "tuning_score_deg": float(np.hypot(s["inclination_deg"], s["heading_deg"])),
                         "all_movement": score(est, ref, mv), "seconds": secs, "est": est})
        best = min(grid, key=lambda r: r["tuning_score_deg"])
        out[f"{name}_gain"] = best["gain"]
        out[f"{name}_rmse_deg"] = score(best["est"], ref, mv)
        out[f"{name}_heldout_rmse_deg"] = score(best["est"], ref, held)
        out[f"{name}_seconds"] = best["seconds"]
        out[f"{name}_grid"] = [{k: v for k, v in r.items() if k != "est"} for r in grid]
    try:
        o = np.genfromtxt(args.ours, delimiter=",", names=True)
        ours = np.stack([o["qw"], o["qx"], o["qy"], o["qz"]], 1)
        if len(ours) != len(t):
            raise ValueError(f"{args.ours}: {len(ours)} rows, BROAD has {len(t)}")
        out["ours_rmse_deg"] = score(ours, ref, mv)
        out["ours_heldout_rmse_deg"] = score(ours, ref, held)
    except OSError as e:
        out["ours_error"] = str(e)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
