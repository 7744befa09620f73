#!/usr/bin/env bash
# Mesa's software Vulkan driver (lavapipe, Debian's `mesa-vulkan-drivers`) and the Vulkan loader,
# so that the learned module's GPU path (feature `wgpu`: burn's CubeCL backend on wgpu) runs its
# kernels on a machine without a GPU (learn/tests/gpu.rs). Installed when missing (root, or
# through sudo). Prints the variables to export:
#   eval "$(scripts/setup-lavapipe.sh)"
# They pin the Vulkan loader to lavapipe and give Mesa a runtime folder.
set -euo pipefail

icd=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
if [ ! -f "$icd" ] || ! ldconfig -p | grep -q 'libvulkan.so.1'; then
    if [ "$(id -u)" = 0 ]; then
        sudo=""
    elif command -v sudo >/dev/null; then
        sudo="sudo"
    else
        echo "setup-lavapipe: lavapipe is missing and this user cannot install it (not root, no sudo)" >&2
        exit 1
    fi
    $sudo apt-get update -q >&2
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends \
        mesa-vulkan-drivers libvulkan1 >&2
fi
[ -f "$icd" ] || { echo "setup-lavapipe: $icd not found after installing it" >&2; exit 1; }
runtime="${XDG_RUNTIME_DIR:-}"
if [ -z "$runtime" ] || [ ! -d "$runtime" ]; then
    runtime="$(mktemp -d)"
    chmod 700 "$runtime"
fi
echo "export VK_ICD_FILENAMES='$icd' XDG_RUNTIME_DIR='$runtime'"
