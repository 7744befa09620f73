#!/usr/bin/env bash
# Installs OpenSim 4.6 (the `opensim` wheel on PyPI: Python bindings with the full C++ library)
# and numpy into a virtual environment at .opensim/venv inside the repository, for the
# side-by-side checks in validation/opensim/.
#
# Usage:   eval "$(scripts/setup-opensim.sh)"     # sets MUSCULO_OPENSIM_PYTHON in this shell
#          validation/opensim/run.sh
#
# Idempotent: when the environment already imports opensim 4.6 it only checks that and exits.
# It prints the environment to use (and only that, on stdout); progress goes to stderr.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)

version=4.6
venv="$root/.opensim/venv"
python="$venv/bin/python"

# Prints the installed opensim version, or nothing when the environment cannot import it.
installed_version() {
    [ -x "$python" ] || return 0
    "$python" -c 'import numpy, opensim; print(opensim.__version__)' 2>/dev/null || true
}

have=$(installed_version)
if [ "$have" != "$version" ]; then
    if [ ! -x "$python" ]; then
        echo "setup-opensim: creating $venv" >&2
        mkdir -p "$root/.opensim"
        python3 -m venv "$venv" >&2
    fi
    echo "setup-opensim: installing opensim==$version and numpy from PyPI (about 72 MB)" >&2
    "$python" -m pip install --quiet --disable-pip-version-check --only-binary=opensim \
        "opensim==$version" numpy >&2
    have=$(installed_version)
    if [ "$have" != "$version" ]; then
        echo "setup-opensim: the environment in $venv does not import opensim $version" \
            "(got '${have:-nothing}'); run: $python -c 'import opensim'" >&2
        exit 1
    fi
fi
echo "setup-opensim: OpenSim $have in $venv" >&2

echo "export MUSCULO_OPENSIM_PYTHON=\"$python\""
