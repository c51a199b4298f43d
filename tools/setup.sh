#!/usr/bin/env bash
# Installs what cryofit needs beyond the Rust toolchain. Used by the README and by .ci/run.
#
#   tools/setup.sh            check the toolchain (rust-toolchain.toml pins it; rustfmt, clippy)
#   tools/setup.sh --tables   also install the pinned CoolProp (tools/requirements.txt), needed
#                             only to regenerate data/fluids/ with tools/fluid_tables.py
set -euo pipefail
cd "$(dirname "$0")/.."

want_tables=0
for arg in "$@"; do
    case "$arg" in
        --tables) want_tables=1 ;;
        -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
        *) echo "tools/setup.sh: unknown option '$arg' (try --help)" >&2; exit 2 ;;
    esac
done

need() {
    if ! command -v "$1" >/dev/null 2>&1; then
        echo "tools/setup.sh: '$1' not found: $2" >&2
        exit 1
    fi
}

need cargo "install Rust with rustup (https://rustup.rs); rust-toolchain.toml selects the version"
# rustup installs the pinned toolchain and its rustfmt/clippy components on first use
cargo fmt --version >/dev/null 2>&1 || { echo "tools/setup.sh: rustfmt missing: rustup component add rustfmt" >&2; exit 1; }
cargo clippy --version >/dev/null 2>&1 || { echo "tools/setup.sh: clippy missing: rustup component add clippy" >&2; exit 1; }

if [ "$want_tables" = 1 ]; then
    need python3 "install Python 3.9 or newer"
    python3 -m pip install --quiet -r tools/requirements.txt
    python3 -c "import CoolProp; print('CoolProp', CoolProp.__version__)"
fi
