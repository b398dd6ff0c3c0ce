"""Batch runs on Ray: a studio capture's frames as Ray tasks, each a call of a frame-range entry
point of `dynamic_shapes.batch` with plain arguments (paths and numbers, which Ray pickles;
the bindings' objects do not pickle).

    pip install './python[ray]'
    python python/examples/batch_ray.py [--check] [--workers N] [--frames N] [--out DIR]

`ray.init()` connects to the cluster named by `RAY_ADDRESS` when it is set (the same script
runs unchanged on a cluster, with the capture and output folders on storage every node
mounts), and starts a local one otherwise. Every worker runs with `RAYON_NUM_THREADS` set
(`--threads`, default 1) so that workers x threads does not oversubscribe the cores.

What runs where:
- photometric reconstruction: one task per frame (frames are independent);
- needle observations: one task per chunk of frames; the chunks' stores merge in frame order
  in a last task (bit for bit the store of one run over all frames);
- template tracking: chunks of one sequence depend on each other through the pose of the
  frame before each chunk: the first chunk starts from the given pose (the user's fit of
  frame 0), every later chunk from the previous chunk's last pose, passed as the previous
  task's result (Ray runs them in order, beside the independent tasks);
- the inertial pipeline: one task per recording (the EKF is sequential within one).

`--check` writes a small studio capture, runs every task on 2 local workers and again
serially in this process, and asserts the outputs are equal byte for byte. `--throughput`
times the photometric frames serially (Rayon on every core) and on 1 and 2 workers (one
Rayon thread each).
"""

import argparse
import filecmp
import json
import os
import tempfile
import time
from pathlib import Path

import dynamic_shapes as ds
from dynamic_shapes import batch

REPO = Path(__file__).resolve().parents[2]
MAKEHUMAN = REPO / "data" / "makehuman"
FIXTURES = REPO / "target" / "tmp" / "python-fixtures"


def make_captures(root, frames, cameras, size):
    """A photometric and a silhouette studio capture under `root`."""
    photo, sil = root / "photometric", root / "silhouette"
    if not (photo / "capture.json").exists():
        batch.write_photometric_capture(str(MAKEHUMAN), str(photo), 60, 60 + frames, cameras=cameras, size=size)
    if not (sil / "capture.json").exists():
        batch.write_silhouette_capture(str(MAKEHUMAN), str(sil), first=40, frames=2 * frames, cameras=4,
                                       width=240, height=180, template_vertices=1500)
    return photo, sil


def inertial_inputs(root):
    """The fixtures' simulated suit recording and the human skeleton it is for (None without the
    fixtures: `cargo test --release -p dynamic-shapes-py --test python_fixtures`)."""
    rec = FIXTURES / "recording"
    if not rec.exists():
        return None
    skel = root / "human_skeleton.json"
    skel.write_text(ds.Skeleton.human().to_json())
    return str(rec), str(skel)


def call(name, *args):
    """`dynamic_shapes.batch.<name>(*args)`, imported where it runs: Ray ships this function,
    and the extension's module and functions are imported by name on the worker."""
    from dynamic_shapes import batch as b

    return getattr(b, name)(*args)


def chunks(n, size):
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def plan(photo, sil, inertial, out):
    """The work as (name, function, args) in dependency order; the tracking chunks take the
    previous chunk's result (None: the first pose from the capture's mocap, the stand-in for the
    user's fit of frame 0)."""
    photo_frames = json.loads((photo / "capture.json").read_text())["frames"]
    info = json.loads((sil / "capture.json").read_text())
    sil_frames, first_pose = info["frames"], info["thetas"][0]
    jobs = [("photometric", batch.photometric_frames, (str(photo), f, f + 1, f"{out}/photometric/", 7))
            for f in range(photo_frames)]
    needle_chunks = chunks(sil_frames, 2)
    jobs += [("needle", batch.needle_accumulate, (str(sil), a, b, f"{out}/needle/")) for a, b in needle_chunks]
    jobs += [("track", batch.track_chunk, (str(sil), a, b, None if k == 0 else "previous", f"{out}/track/"))
             for k, (a, b) in enumerate(chunks(sil_frames, 2))]
    if inertial:
        rec, skel = inertial
        jobs.append(("inertial", batch.inertial_recording, (rec, skel, 0, 100, f"{out}/inertial/")))
    return jobs, first_pose, [f"{out}/needle/store_{a:06}_{b:06}.json" for a, b in needle_chunks]


def run_serial(photo, sil, inertial, out):
    jobs, first_pose, stores = plan(photo, sil, inertial, out)
    pose = first_pose
    for name, fn, args in jobs:
        if name == "track":
            capture, a, b, _, prefix = args
            pose = fn(capture, a, b, pose, prefix)
        else:
            fn(*args)
    batch.needle_merge(stores, f"{out}/needle/merged.json")


def run_ray(photo, sil, inertial, out, ray):
    jobs, first_pose, stores = plan(photo, sil, inertial, out)

    @ray.remote(num_cpus=1)
    def task(name, *args):
        return call(name, *args)

    refs, needle_refs, pose = [], [], first_pose
    for name, fn, args in jobs:
        if name == "track":
            capture, a, b, _, prefix = args
            pose = task.remote("track_chunk", capture, a, b, pose, prefix)  # after the previous chunk
            refs.append(pose)
        else:
            r = task.remote(fn.__name__, *args)
            refs.append(r)
            if name == "needle":
                needle_refs.append(r)

    @ray.remote(num_cpus=1)
    def merge(paths, out_path, *_chunk_results):
        return call("needle_merge", paths, out_path)

    refs.append(merge.remote(stores, f"{out}/needle/merged.json", *needle_refs))
    ray.get(refs)


def outputs(folder):
    return sorted(p.relative_to(folder) for p in Path(folder).rglob("*") if p.is_file())


def init_ray(workers, threads):
    import ray

    env = {"env_vars": {"RAYON_NUM_THREADS": str(threads)}}
    if os.environ.get("RAY_ADDRESS"):
        ray.init(runtime_env=env)  # the cluster's resources
    else:
        ray.init(num_cpus=workers, runtime_env=env, include_dashboard=False, log_to_driver=False)
    return ray


def check(args):
    root = Path(args.out or tempfile.mkdtemp(prefix="batch-ray-"))
    photo, sil = make_captures(root / "captures", args.frames, args.cameras, args.size)
    inertial = inertial_inputs(root)
    t0 = time.perf_counter()
    run_serial(photo, sil, inertial, root / "serial")
    serial_s = time.perf_counter() - t0
    ray = init_ray(2, args.threads)
    t0 = time.perf_counter()
    run_ray(photo, sil, inertial, root / "ray", ray)
    ray_s = time.perf_counter() - t0
    ray.shutdown()
    a, b = outputs(root / "serial"), outputs(root / "ray")
    assert a == b, f"different files: {set(a) ^ set(b)}"
    differing = [str(p) for p in a if not filecmp.cmp(root / "serial" / p, root / "ray" / p, shallow=False)]
    assert not differing, f"outputs differ: {differing}"
    sizes = sum((root / "serial" / p).stat().st_size for p in a)
    print(f"{len(a)} output files ({sizes / 1e6:.1f} MB) equal byte for byte between the serial run "
          f"({serial_s:.1f} s) and 2 Ray workers with RAYON_NUM_THREADS={args.threads} ({ray_s:.1f} s):")
    for p in a:
        print(f"  {p}")
    print(json.dumps({"files": len(a), "bytes": sizes, "serial_s": serial_s, "ray_2_workers_s": ray_s,
                      "inertial": inertial is not None}))


def throughput(args):
    """Photometric frames per hour: serial (Rayon on all cores) against 1 and 2 Ray workers
    with one Rayon thread each."""
    root = Path(args.out or tempfile.mkdtemp(prefix="batch-ray-"))
    photo, _ = make_captures(root / "captures", args.frames, args.cameras, args.size)
    n = json.loads((photo / "capture.json").read_text())["frames"]
    out = {}
    t0 = time.perf_counter()
    for f in range(n):
        batch.photometric_frames(str(photo), f, f + 1, f"{root}/tp-serial/", 7)
    out["serial_rayon_all_cores_s_per_frame"] = (time.perf_counter() - t0) / n
    for workers in (1, 2):
        ray = init_ray(workers, 1)

        @ray.remote(num_cpus=1)
        def frame(f, prefix):
            t = time.perf_counter()
            call("photometric_frames", str(photo), f, f + 1, prefix, 7)
            return time.perf_counter() - t

        t0 = time.perf_counter()
        per = ray.get([frame.remote(f, f"{root}/tp-{workers}/") for f in range(n)])
        out[f"ray_{workers}_workers_s_per_frame"] = (time.perf_counter() - t0) / n
        out[f"ray_{workers}_workers_task_s"] = sum(per) / n
        ray.shutdown()
    out["frames"], out["cameras"], out["size_px"] = n, args.cameras, args.size
    print(json.dumps(out, indent=1))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--check", action="store_true", help="2 local workers against a serial run, byte for byte")
    p.add_argument("--throughput", action="store_true", help="photometric frames: serial, 1 and 2 workers")
    p.add_argument("--frames", type=int, default=4, help="photometric frames (the silhouette capture has twice)")
    p.add_argument("--cameras", type=int, default=8)
    p.add_argument("--size", type=int, default=128, help="photometric image size, px")
    p.add_argument("--threads", type=int, default=1, help="RAYON_NUM_THREADS of each worker")
    p.add_argument("--out", help="folder of the captures and outputs (default: a temporary one)")
    args = p.parse_args()
    if args.check:
        check(args)
    elif args.throughput:
        throughput(args)
    else:
        root = Path(args.out or tempfile.mkdtemp(prefix="batch-ray-"))
        photo, sil = make_captures(root / "captures", args.frames, args.cameras, args.size)
        ray = init_ray(os.cpu_count() or 1, args.threads)
        t0 = time.perf_counter()
        run_ray(photo, sil, inertial_inputs(root), root / "ray", ray)
        print(f"outputs under {root / 'ray'} in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
