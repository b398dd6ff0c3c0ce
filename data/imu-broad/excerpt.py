#!/usr/bin/env python3
"""Cut the first seconds of a BROAD trial into an HDF5 file in BROAD's own layout.

usage: python3 excerpt.py IN.hdf5 OUT.hdf5 [SECONDS]   (SECONDS defaults to 60)

The excerpt keeps the first n = min(N, int(SECONDS * sampling_rate)) samples of every dataset
(60 s at 285.714 Hz: 17,142 samples) with the original's names, dtypes (f64; `movement` as
h5py's bool, an i8 enum FALSE=0/TRUE=1) and storage (one whole-array chunk, gzip level 9, no
shuffle), and copies the root attributes `sampling_rate` and `info` unchanged; nothing is
added. Values are copied bit for bit. The file is written with h5py's defaults (superblock
version 0, no object time stamps), so the same input gives the same bytes.
"""
import sys

import h5py

DATASETS = ["imu_acc", "imu_gyr", "imu_mag", "movement", "opt_pos", "opt_quat"]
ATTRIBUTES = ["info", "sampling_rate"]


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    seconds = float(sys.argv[3]) if len(sys.argv) == 4 else 60.0
    with h5py.File(sys.argv[1], "r") as src, h5py.File(sys.argv[2], "w") as dst:
        if sorted(src.keys()) != DATASETS or sorted(src.attrs.keys()) != ATTRIBUTES:
            sys.exit(f"{sys.argv[1]}: not in BROAD's layout "
                     f"(datasets {sorted(src.keys())}, attributes {sorted(src.attrs.keys())})")
        rate = float(src.attrs["sampling_rate"])
        total = src["imu_gyr"].shape[0]
        n = min(total, int(seconds * rate))
        for name in DATASETS:
            d = src[name]
            if d.shape[0] != total:
                sys.exit(f"{sys.argv[1]}: {name} has {d.shape[0]} rows, imu_gyr {total}")
            data = d[:n]
            dst.create_dataset(name, data=data, dtype=d.dtype, chunks=data.shape,
                               compression="gzip", compression_opts=9, shuffle=False)
        for name in ATTRIBUTES:
            dst.attrs.create(name, src.attrs[name], dtype=src.attrs.get_id(name).dtype)
        for name in DATASETS:
            if dst[name][:].tobytes() != src[name][:n].tobytes():
                sys.exit(f"{sys.argv[2]}: {name} does not read back bit for bit")
    print(f"{sys.argv[2]}: {n} of {total} samples ({n / rate:.3f} s at {rate:.6g} Hz)")


if __name__ == "__main__":
    main()
