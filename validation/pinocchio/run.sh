#!/usr/bin/env bash
# Regenerates the musculo-vs-Pinocchio speed table (validation/pinocchio/README.md): sets up
# Pinocchio (scripts/setup-pinocchio.sh), builds musculo and examples/dynamics_timing.rs, builds
# the C++ timing program speed.cpp against the `pin` wheel (once; again only when speed.cpp is
# newer than the binary), then runs speed.py, which prints the table.
#
# Usage:   validation/pinocchio/run.sh [--python-only] [speed.py options: --count B --batches K]
#   --python-only   skip the C++ program (Pinocchio timed from Python only)
# The C++ build needs g++ and two header-only packages from PyPI in the same environment
# (cmeel-eigen: Eigen; cmeel-urdfdom-headers: included by Pinocchio's MJCF parser headers); when
# they cannot be installed or the build fails, the table is made from Python alone and says so.
# Exit status 1 when a model's M, τ or total mass in Pinocchio disagrees with musculo's.
set -euo pipefail
cd "$(dirname "$0")/../.."

if [ -z "${MUSCULO_PINOCCHIO_PYTHON:-}" ]; then
    eval "$(scripts/setup-pinocchio.sh)"
fi
cpp=1
if [ "${1:-}" = "--python-only" ]; then
    cpp=0
    shift
fi

cargo build --release --bin musculo
cargo build --release --example dynamics_timing

out=target/pinocchio
bin="$out/speed_cpp"
src=validation/pinocchio/speed.cpp
mkdir -p "$out"
if [ $cpp -eq 1 ] && { [ ! -x "$bin" ] || [ "$src" -nt "$bin" ]; }; then
    # The cmeel wheels (pin, libpinocchio, eigenpy, boost, ...) install under one prefix.
    site=$("$MUSCULO_PINOCCHIO_PYTHON" -c 'import sysconfig; print(sysconfig.get_path("purelib"))')
    prefix="$site/cmeel.prefix"
    if [ ! -d "$prefix/include/eigen3" ] || [ ! -d "$prefix/include/urdfdom_headers" ]; then
        echo "pinocchio/run.sh: installing the C++ build's headers" \
            "(cmeel-eigen, cmeel-urdfdom-headers)" >&2
        "$MUSCULO_PINOCCHIO_PYTHON" -m pip install --quiet --disable-pip-version-check \
            "cmeel-eigen==3.4.1" "cmeel-urdfdom-headers==3.0.0" >&2 || true
    fi
    echo "pinocchio/run.sh: building $bin against $prefix (about 1 to 2 minutes)" >&2
    rm -f "$bin"
    # The definitions are those of the wheel's CMake targets (lib/cmake/pinocchio); with
    # PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION the algorithms run from libpinocchio_default.so.
    if ! g++ -std=c++17 -O3 -DNDEBUG -w \
        -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION \
        -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 \
        -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12 \
        -I"$prefix/include" -I"$prefix/include/eigen3" \
        -I"$prefix/include/urdfdom_headers" -I"$prefix/include/urdfdom" \
        "$src" -o "$bin" -L"$prefix/lib" -Wl,-rpath,"$prefix/lib" \
        -lpinocchio_parsers -lpinocchio_default; then
        echo "pinocchio/run.sh: the C++ build failed (above); timing Pinocchio from Python only" >&2
        rm -f "$bin"
    fi
fi
if [ $cpp -eq 0 ]; then
    set -- --no-cpp "$@"
fi
"$MUSCULO_PINOCCHIO_PYTHON" validation/pinocchio/speed.py "$@"
