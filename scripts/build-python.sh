#!/usr/bin/env bash
# Builds musculo's Python wheel (abi3, maturin from PyPI) and tests it in a fresh virtual
# environment with numpy and pytest; MUSCULO_TORCH=1 / MUSCULO_JAX=1 add torch / jax from PyPI
# for the wrappers' tests (skipped without them).
#   scripts/build-python.sh            # wheel in target/wheels, tests run
# Cached under .python/ (ignored); nothing is installed outside it.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
py=${PYTHON:-python3}
tools=.python/build-venv
if [ ! -x "$tools/bin/maturin" ]; then
    echo "build-python: installing maturin from PyPI into $tools" >&2
    "$py" -m venv "$tools"
    "$tools/bin/pip" install -q --disable-pip-version-check "maturin>=1.9,<2"
fi
rm -rf target/wheels
"$tools/bin/maturin" build --release --locked -m python/Cargo.toml -o target/wheels >&2
wheel=$(ls target/wheels/musculo-*.whl)
echo "build-python: built $wheel" >&2
test_env=.python/test-venv
rm -rf "$test_env"
"$py" -m venv "$test_env"
"$test_env/bin/pip" install -q --disable-pip-version-check "$wheel" numpy pytest
if [ "${MUSCULO_TORCH:-0}" = 1 ]; then
    "$test_env/bin/pip" install -q --disable-pip-version-check torch
fi
if [ "${MUSCULO_JAX:-0}" = 1 ]; then
    "$test_env/bin/pip" install -q --disable-pip-version-check jax
fi
# from outside the source tree, so that the installed package is the one tested
cd /tmp
MUSCULO_REFERENCE="${MUSCULO_REFERENCE:-$root/../shared/reference}" \
    "$root/$test_env/bin/python" -m pytest -q "$root/python/tests" --doctest-modules "$root/$test_env/lib/"python3*/site-packages/musculo/__init__.py
