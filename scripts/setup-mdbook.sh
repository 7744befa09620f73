#!/usr/bin/env bash
# mdBook for the book in docs/: `cargo install` from crates.io (no Debian package exists) into
# .mdbook/ (ignored), once; later runs find it there. Without its `serve` and `watch` features,
# which building the book does not need (about 5 minutes of CPU time on 2 cores). Prints the
# variables to export:
#   eval "$(scripts/setup-mdbook.sh)"
set -euo pipefail
cd "$(dirname "$0")/.."
version=0.5.4
root="$(pwd)/.mdbook"
if [ "$("$root/bin/mdbook" --version 2>/dev/null)" != "mdbook v$version" ]; then
    cargo install mdbook --locked --version "$version" --no-default-features --features search \
        --root "$root" >&2
fi
echo "export PATH='$root/bin':\"\$PATH\""
