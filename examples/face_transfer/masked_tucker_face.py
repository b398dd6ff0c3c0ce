#!/usr/bin/env python3
"""TensorLy masked Tucker on the face_transfer example's data (run by hand, never in CI).

Reads out/face_transfer/tensorly/{set}.npy (shape [3V, ..., identities]) and
{set}_known_{pct}.npy (attribute shape, 1 = known face), runs TensorLy's masked
partial_tucker over the attribute modes (the vertex mode not factored, Eq. 5.4) with
iterations to convergence (tol 1e-7, at most 2000 sweeps instead of the default 100), and
prints one JSON line per rank setting with issue 16's metric:
||(Xhat - X)(1 - M)|| / ||(X - mean face)(1 - M)||, the mean face over all faces of X.

python3 masked_tucker_face.py [--dir out/face_transfer/tensorly] [--set trilinear] [--pct 15]
"""
import argparse
import json
import time

import numpy as np
import tensorly as tl
from tensorly.decomposition import partial_tucker
from tensorly.tenalg import multi_mode_dot


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dir", default="out/face_transfer/tensorly")
    ap.add_argument("--set", default="trilinear")
    ap.add_argument("--pct", type=int, default=15)
    ap.add_argument("--ranks", default="4,4,16;4,4,11;5,5,11;5,5,16")
    ap.add_argument("--n-iter-max", type=int, default=2000)
    ap.add_argument("--tol", type=float, default=1e-7)
    ap.add_argument("--centre", action="store_true",
                    help="subtract the known faces' mean face first (added back after)")
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
    X_obs = (X - shift_t) * mask
    modes = list(range(1, X.ndim))
    mean_face = X.reshape(X.shape[0], -1).mean(axis=1)
    hold = 1.0 - mask
    dev = (X - mean_face.reshape((-1,) + (1,) * (X.ndim - 1))) * hold
    for rs in args.ranks.split(";"):
        ranks = [int(r) for r in rs.split(",")]
        if len(ranks) != len(modes):
            continue
        t0 = time.perf_counter()
        (core, factors), errs = partial_tucker(
            X_obs, rank=ranks, modes=modes, mask=mask, init="svd",
            n_iter_max=args.n_iter_max, tol=args.tol, svd="truncated_svd", svd_mask_repeats=5)
        dt = time.perf_counter() - t0
        Xhat = multi_mode_dot(core, factors, modes=modes) + shift_t
        err = float(np.linalg.norm(((Xhat - X) * hold).ravel()) / np.linalg.norm(dev.ravel()))
        print(json.dumps({"set": args.set, "centred": args.centre, "held_out_pct": args.pct, "ranks": ranks,
                          "impute_rel_error": err, "iterations": len(errs),
                          "converged": len(errs) < args.n_iter_max, "seconds": dt,
                          "tensorly": tl.__version__}), flush=True)


if __name__ == "__main__":
    main()
