#!/usr/bin/env bash
# Installs Pinocchio 4.1.0 (the `pin` wheel on PyPI: Python bindings with the full C++ library,
# its headers and its CMake files) and numpy into a virtual environment at .pinocchio/venv
# inside the repository, for the side-by-side timing in validation/pinocchio/.
#
# Usage:   eval "$(scripts/setup-pinocchio.sh)"     # sets MUSCULO_PINOCCHIO_PYTHON in this shell
#          validation/pinocchio/run.sh
#
# Idempotent: when the environment already imports pinocchio 4.1.0 it only checks that and exits.
# It prints the environment to use (and only that, on stdout); progress goes to stderr.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

version=4.1.0
venv="$root/.pinocchio/venv"
python="$venv/bin/python"

# Prints the installed pinocchio version, or nothing when the environment cannot import it.
installed_version() {
    [ -x "$python" ] || return 0
    "$python" -c 'import numpy, pinocchio; print(pinocchio.__version__)' 2>/dev/null || true
}

have=$(installed_version)
if [ "$have" != "$version" ]; then
    if [ ! -x "$python" ]; then
        echo "setup-pinocchio: creating $venv" >&2
        mkdir -p "$root/.pinocchio"
        python3 -m venv "$venv" >&2
    fi
    echo "setup-pinocchio: installing pin==$version and numpy from PyPI" >&2
    "$python" -m pip install --quiet --disable-pip-version-check --only-binary=pin \
        "pin==$version" numpy >&2
    have=$(installed_version)
    if [ "$have" != "$version" ]; then
        echo "setup-pinocchio: the environment in $venv does not import pinocchio $version" \
            "(got '${have:-nothing}'); run: $python -c 'import pinocchio'" >&2
        exit 1
    fi
fi
echo "setup-pinocchio: Pinocchio $have in $venv" >&2

echo "export MUSCULO_PINOCCHIO_PYTHON=\"$python\""
