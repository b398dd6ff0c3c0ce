#!/usr/bin/env bash
# inertial-acoustic against its peers, in one run on this machine (not part of CI):
#  * BROAD orientation: the one-board filter vs x-io Fusion (imufusion, 6-axis), each gain tuned
#    on trial 09, both scored on trial 07 with one metric (examples/inertial_capture/fusion_broad.py);
#  * the FilterPy EKF workload (../shared/bench/peers/ekf.py) vs its Rust regeneration
#    (examples/inertial_capture/peer_ekf.rs): per-step time ratio.
# Needs a Python venv with numpy, h5py, imufusion and filterpy: PY=/path/to/venv/bin/python
# (default: the peers' venv, see ../shared/bench/peers/README.md; `pip install imufusion h5py` there).
set -euo pipefail
cd "$(dirname "$0")/.."
peers=$(cd ../shared/bench/peers && pwd)
py=${PY:-$peers/.venv/bin/python}
cargo build --release --example inertial_capture >/dev/null
# The three JSON lines go through files, not arguments: one argument is limited to 128 KiB
# (MAX_ARG_STRLEN) and the example's line grows with its tuning grids.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
target/release/examples/inertial_capture --real-only 2>/dev/null | tail -1 >"$tmp/rust.json"
$py examples/inertial_capture/fusion_broad.py \
    --tuning data/imu-broad/09_undisturbed_fast_rotation_with_breaks_B_first60s.hdf5 \
    --test data/imu-broad/07_undisturbed_fast_rotation_B_first60s.hdf5 \
    --ours out/inertial_capture/broad_ours.csv | tail -1 >"$tmp/fusion.json"
# One core for both (our figures are single-threaded; OpenBLAS threads on this shared 2-core
# machine oversubscribe and slow FilterPy down about tenfold).
(cd "$peers" && OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $py ekf.py | tail -1) >"$tmp/filterpy.json"
python3 - "$tmp/rust.json" "$tmp/fusion.json" "$tmp/filterpy.json" <<'PY'
import json, sys
def read(path):
    with open(path) as f:
        return json.load(f)
rust, fusion, filterpy = (read(a) for a in sys.argv[1:])
ekf = rust["ekf_peer_workload"]
out = {
    "broad_ours_test_rmse_deg": fusion.get("ours_test_rmse_deg"),
    "broad_ours_test_rmse_deg_rust": rust["broad_rmse_deg"],
    "broad_ours_gyro_only_test_rmse_deg": rust["broad_gyro_only_rmse_deg"],
    "broad_ours_accelerometer_sigma": rust["broad_accelerometer_sigma"],
    "broad_ours_tuning_interior": rust["broad_tuning_interior"],
    "broad_fusion_test_rmse_deg": fusion["fusion_test_rmse_deg"],
    "broad_fusion_gain": fusion["fusion_gain"],
    "broad_fusion_tuning_interior": fusion["fusion_tuning_interior"],
    "broad_fusion_offset_removed_test_rmse_deg": fusion["fusion_offset_removed_test_rmse_deg"],
    "broad_fusion_offset_removed_gain": fusion["fusion_offset_removed_gain"],
    "broad_fusion_offset_removed_tuning_interior": fusion["fusion_offset_removed_tuning_interior"],
    "broad_fusion_offset_removed_gyro_only_test_rmse_deg": fusion["fusion_offset_removed_gyro_only_test_rmse_deg"],
    "ekf_rust_s_per_step": ekf["seconds"],
    "ekf_filterpy_s_per_step": filterpy["seconds"],
    "ekf_speedup_vs_filterpy": filterpy["seconds"] / ekf["seconds"],
    "ekf_rust_rms_angle_err": ekf["quality"]["rms_angle_err"],
    "ekf_filterpy_rms_angle_err": filterpy["quality"]["rms_angle_err"],
}
print(json.dumps(out))
PY
