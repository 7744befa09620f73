#!/usr/bin/env python3
"""Run `musculo augment` over a Dask cluster: one task per shard, then `musculo merge`.

Every shard is the same command with `--shard K/N` (a deterministic split of the dataset's
clips), so the shards may run on any worker in any order; `musculo merge OUT` then writes
the manifest and statistics, byte-identical to a single-machine run. OUT must be a folder
every worker can write to (a shared filesystem).

    # on this machine, two worker processes:
    python examples/dask_augment.py --local-workers 2 --shards 8 -- --demo --out out/demo

    # on an existing cluster:
    python examples/dask_augment.py --scheduler tcp://scheduler:8786 --shards 64 -- \
        --input /data/HumanML3D/new_joints --format humanml3d --out /shared/augmented

Arguments after `--` go to `musculo augment` unchanged (except `--shard` and `--jobs`,
which this script sets). Needs `dask[distributed]` (scripts/setup-dask.sh installs it).
"""

import argparse
import shutil
import subprocess
import sys


def run_shard(musculo, augment_args, k, n, jobs):
    """Runs shard k of n; returns (k, exit status, the end of its stderr)."""
    cmd = [musculo, "augment", *augment_args, "--shard", f"{k}/{n}", "--jobs", str(jobs)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    return k, done.returncode, done.stderr[-2000:]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--musculo", default=shutil.which("musculo") or "target/release/musculo",
                        help="path of the musculo binary (default: on PATH, else target/release)")
    parser.add_argument("--shards", type=int, default=8, help="number of shards N")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler")
    parser.add_argument("--local-workers", type=int, default=2,
                        help="worker processes of a LocalCluster (when no --scheduler)")
    parser.add_argument("--jobs", type=int, default=1, help="threads per shard (musculo --jobs)")
    parser.add_argument("augment", nargs=argparse.REMAINDER,
                        help="-- then the arguments of musculo augment (must include --out)")
    args = parser.parse_args()
    augment_args = args.augment[1:] if args.augment[:1] == ["--"] else args.augment
    if "--out" not in augment_args:
        parser.error("give musculo augment's arguments after --, including --out DIR")
    out = augment_args[augment_args.index("--out") + 1]

    from dask.distributed import Client, LocalCluster

    if args.scheduler:
        client = Client(args.scheduler)
        cluster = None
    else:
        cluster = LocalCluster(n_workers=args.local_workers, threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        futures = [client.submit(run_shard, args.musculo, augment_args, k, args.shards,
                                 args.jobs, pure=False)
                   for k in range(args.shards)]
        failed = 0
        for k, status, stderr in client.gather(futures):
            # exit status 1 with a finished shard means some clips failed (recorded in the
            # manifest); anything else is a shard that did not finish
            print(f"shard {k}/{args.shards}: exit status {status}", file=sys.stderr)
            if status != 0:
                failed += 1
                print(stderr, file=sys.stderr)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    merged = subprocess.run([args.musculo, "merge", out])
    if merged.returncode != 0:
        return merged.returncode
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
