#!/usr/bin/env bash
# Installs Dask's distributed scheduler (`dask[distributed]` from PyPI) into a virtual
# environment at .dask/venv inside the repository, for examples/dask_augment.py and its
# check in validation/dask/run.sh.
#
# Usage:   eval "$(scripts/setup-dask.sh)"     # sets MUSCULO_DASK_PYTHON in this shell
#
# Idempotent; prints the environment to use on stdout, progress on stderr.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
version=2026.8.0
venv="$root/.dask/venv"
python="$venv/bin/python"
installed() {
    [ -x "$python" ] || return 0
    "$python" -c 'import distributed; print(distributed.__version__)' 2>/dev/null || true
}
if [ "$(installed)" != "$version" ]; then
    if [ ! -x "$python" ]; then
        echo "setup-dask: creating $venv" >&2
        mkdir -p "$root/.dask"
        python3 -m venv "$venv" >&2
    fi
    echo "setup-dask: installing dask[distributed]==$version from PyPI" >&2
    "$python" -m pip install --quiet --disable-pip-version-check "dask[distributed]==$version" >&2
    if [ "$(installed)" != "$version" ]; then
        echo "setup-dask: $venv does not import distributed $version" >&2
        exit 1
    fi
fi
echo "export MUSCULO_DASK_PYTHON=$python"
