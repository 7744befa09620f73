#!/usr/bin/env bash
# Checks examples/dask_augment.py on a Dask LocalCluster with 2 worker processes: the demo
# clips with 2 variants in 4 shards, merged, must give the same bytes (manifest, statistics,
# every clip) as one `musculo augment` run on this machine.
#
# Usage: validation/dask/run.sh     (builds the release binary; installs Dask if needed)
set -euo pipefail
cd "$(dirname "$0")/../.."
eval "$(scripts/setup-dask.sh)"
cargo build --release --quiet
musculo=$(pwd)/target/release/musculo
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$musculo" augment --demo --variants 2 --out "$work/single" 2>/dev/null
"$MUSCULO_DASK_PYTHON" examples/dask_augment.py --musculo "$musculo" --local-workers 2 \
    --shards 4 -- --demo --variants 2 --out "$work/dask"
status=0
count=0
while IFS= read -r f; do
    count=$((count + 1))
    if ! cmp -s "$work/single/$f" "$work/dask/$f"; then
        echo "dask: $f differs from the single-machine run" >&2
        status=1
    fi
done < <(cd "$work/single" && find . -type f ! -path './.musculo/*' | sort)
if [ "$count" -lt 8 ]; then
    echo "dask: expected at least 8 files (manifest, stats, 6 clips), found $count" >&2
    status=1
fi
[ "$status" = 0 ] && echo "dask: PASS — 4 shards on a LocalCluster with 2 workers, merged: $count files byte-identical to one run"
exit $status
