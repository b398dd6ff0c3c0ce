#!/usr/bin/env python3
"""TensorLy masked Tucker on the face_transfer example's data (run by hand, never in CI).

Reads out/face_transfer/tensorly/{set}.npy (shape [3V, ..., identities]),
{set}_known_{pct}.npy (attribute shape, 1 = known face) and, with --start,
{set}_start_{pct}.npy (the tensor with its missing faces filled by the averaging baseline,
where our imputation starts). Runs TensorLy's masked partial_tucker over the attribute modes
(the vertex mode not factored, Eq. 5.4) from that fill (else from 0 in the missing entries)
until its own stopping rule (the change of the reconstruction error below --tol, checked from
the third sweep) or --max-seconds of wall time, whichever comes first, and prints one JSON
line per rank setting with the example's metric:
||(Xhat - X)(1 - M)|| / ||(X - mean face)(1 - M)||, the mean face over all faces of X.

The sweeps run one call at a time (init = the previous call's core and factors, n_iter_max 1,
TensorLy's own stopping test disabled), which is TensorLy's iteration unchanged: each sweep
first refills the missing entries from the current core and factors; the stopping rule is
applied here with TensorLy's formula (error = sqrt(|‖T₀‖² − ‖core‖²|) / ‖T₀‖, T₀ the
tensor given at the start) so that the wall-time limit can stop it between sweeps.

python3 masked_tucker_face.py [--dir out/face_transfer/tensorly] [--set trilinear] [--pct 15]
    [--ranks 4,4,11] [--centre] [--start] [--tol 1e-7] [--n-iter-max 100000] [--max-seconds 1800]
"""
import argparse
import json
import time

import numpy as np
import tensorly as tl
from tensorly.decomposition import partial_tucker
from tensorly.tenalg import multi_mode_dot


def run(X_in, mask, modes, ranks, args):
    """TensorLy's masked partial Tucker, one sweep per call; returns (core, factors), sweeps,
    what stopped it, seconds."""
    t0 = time.perf_counter()
    norm0 = float(np.linalg.norm(X_in.ravel()))
    (core, factors), _ = partial_tucker(
        X_in, rank=ranks, modes=modes, mask=mask, init="svd", n_iter_max=1, tol=0,
        svd="truncated_svd", svd_mask_repeats=5)
    errors = [np.sqrt(abs(norm0**2 - float(np.linalg.norm(core.ravel()))**2)) / norm0]
    stopped = "n_iter_max"
    while len(errors) < args.n_iter_max:
        if time.perf_counter() - t0 > args.max_seconds:
            stopped = "time"
            break
        (core, factors), _ = partial_tucker(
            X_in, rank=ranks, modes=modes, mask=mask, init=(core, factors), n_iter_max=1,
            tol=0, svd="truncated_svd")
        errors.append(np.sqrt(abs(norm0**2 - float(np.linalg.norm(core.ravel()))**2)) / norm0)
        if len(errors) > 2 and abs(errors[-2] - errors[-1]) < args.tol:
            stopped = "tol"
            break
    return (core, factors), len(errors), stopped, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", default="out/face_transfer/tensorly")
    ap.add_argument("--set", default="trilinear")
    ap.add_argument("--pct", type=int, default=15)
    ap.add_argument("--ranks", default="4,4,11")
    ap.add_argument("--n-iter-max", type=int, default=100000)
    ap.add_argument("--tol", type=float, default=1e-7)
    ap.add_argument("--max-seconds", type=float, default=1800.0)
    ap.add_argument("--centre", action="store_true",
                    help="subtract the known faces' mean face first (added back after)")
    ap.add_argument("--start", action="store_true",
                    help="missing entries start at the averaging baseline's fill (ours starts there)")
    args = ap.parse_args()
    tl.set_backend("numpy")
    X = np.load(f"{args.dir}/{args.set}.npy")
    known = np.load(f"{args.dir}/{args.set}_known_{args.pct:02d}.npy")
    mask = np.broadcast_to(known[None, ...], X.shape).astype(np.float64).copy()
    shift = np.zeros(X.shape[0])
    if args.centre:
        flat_known = known.ravel() > 0.5
        shift = X.reshape(X.shape[0], -1)[:, flat_known].mean(axis=1)
    shift_t = shift.reshape((-1,) + (1,) * (X.ndim - 1))
    if args.start:
        X_start = np.load(f"{args.dir}/{args.set}_start_{args.pct:02d}.npy")
        X_in = X * mask + X_start * (1.0 - mask) - shift_t
    else:
        X_in = (X - shift_t) * mask
    modes = list(range(1, X.ndim))
    mean_face = X.reshape(X.shape[0], -1).mean(axis=1)
    hold = 1.0 - mask
    dev = (X - mean_face.reshape((-1,) + (1,) * (X.ndim - 1))) * hold
    norm_dev = np.linalg.norm(dev.ravel())
    start_err = float(np.linalg.norm(((X_in + shift_t - X) * hold).ravel()) / norm_dev)
    for rs in args.ranks.split(";"):
        ranks = [int(r) for r in rs.split(",")]
        if len(ranks) != len(modes):
            continue
        (core, factors), sweeps, stopped, dt = run(X_in, mask, modes, ranks, args)
        Xhat = multi_mode_dot(core, factors, modes=modes) + shift_t
        err = float(np.linalg.norm(((Xhat - X) * hold).ravel()) / norm_dev)
        print(json.dumps({"set": args.set, "centred": args.centre, "start": args.start,
                          "held_out_pct": args.pct, "ranks": ranks, "impute_rel_error": err,
                          "start_rel_error": start_err, "iterations": sweeps,
                          "stopped_by": stopped, "converged": stopped == "tol",
                          "seconds": dt, "tol": args.tol, "max_seconds": args.max_seconds,
                          "tensorly": tl.__version__}), flush=True)


if __name__ == "__main__":
    main()
