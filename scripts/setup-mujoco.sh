#!/usr/bin/env bash
# Installs the MuJoCo shared library that the `mujoco` cargo feature links against, into
# .mujoco/ inside the repository, from the `mujoco` wheel on PyPI whose version matches the
# mujoco-rs crate (its version's `+mj-X.Y.Z` suffix, read from Cargo.lock).
#
# Usage:   eval "$(scripts/setup-mujoco.sh)"     # sets the environment in this shell
#          cargo test --release --features mujoco
#
# The library is found at run time through LD_LIBRARY_PATH; with --rpath the script also
# prints a RUSTFLAGS rpath link argument instead, so binaries find it on their own (changing
# RUSTFLAGS rebuilds every crate once).
#
# It prints the environment to use (and only that, on stdout); progress goes to stderr.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

version=$(awk '/^name = "mujoco-rs"/ {getline; print}' Cargo.lock | sed -n 's/.*+mj-\([0-9.]*\)".*/\1/p')
if [ -z "$version" ]; then
    echo "setup-mujoco: cannot find the mujoco-rs version in Cargo.lock" >&2
    exit 1
fi
lib_dir="$root/.mujoco/lib"
lib="libmujoco.so.$version"

if [ ! -f "$lib_dir/$lib" ]; then
    echo "setup-mujoco: fetching mujoco==$version from PyPI" >&2
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    python3 -m pip download --quiet --no-deps --only-binary=:all: "mujoco==$version" -d "$tmp" >&2
    wheel=$(ls "$tmp"/mujoco-"$version"-*.whl | head -n 1)
    mkdir -p "$lib_dir"
    python3 - "$wheel" "$lib_dir" "$lib" <<'PY'
import sys, zipfile, shutil, os
wheel, out, name = sys.argv[1:4]
with zipfile.ZipFile(wheel) as z:
    member = next((n for n in z.namelist() if n.endswith("/" + name)), None)
    if member is None:
        sys.exit(f"setup-mujoco: {name} is not in {os.path.basename(wheel)}")
    with z.open(member) as src, open(os.path.join(out, name), "wb") as dst:
        shutil.copyfileobj(src, dst)
PY
fi
# Both names: libmujoco.so for the linker, libmujoco.so.X.Y.Z for the loader (its SONAME).
ln -sfn "$lib" "$lib_dir/libmujoco.so"
echo "setup-mujoco: MuJoCo $version in $lib_dir" >&2

echo "export MUJOCO_DYNAMIC_LINK_DIR=\"$lib_dir\""
if [ "${1:-}" = "--rpath" ]; then
    echo "export RUSTFLAGS=\"\${RUSTFLAGS:-} -C link-arg=-Wl,-rpath,$lib_dir\""
else
    echo "export LD_LIBRARY_PATH=\"$lib_dir\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}\""
fi
