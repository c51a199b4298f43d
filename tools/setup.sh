#!/usr/bin/env bash
# Installs what cryofit needs beyond the Rust toolchain. Used by the README and by .ci/run.
#
#   tools/setup.sh            check the toolchain (rust-toolchain.toml pins it; rustfmt, clippy)
#                             and install Debian's chromium when it is missing: the dashboard's
#                             browser test (tests/tests/e2e/dashboard.rs) loads the pages in it
#                             headless. Needs root (or sudo) and apt-get; without them it says
#                             so and goes on (that test then skips, except under CI=true).
#   tools/setup.sh --tables   also install the pinned CoolProp (tools/requirements.txt), needed
#                             only to regenerate data/fluids/ with tools/fluid_tables.py
set -euo pipefail
cd "$(dirname "$0")/.."

want_tables=0
for arg in "$@"; do
    case "$arg" in
        --tables) want_tables=1 ;;
        -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
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

# headless Chromium for the dashboard's browser test (idempotent: nothing to do when present)
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
    sudo_cmd=""
    if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null 2>&1; then sudo_cmd="sudo -n"; fi
    if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = 0 ] || [ -n "$sudo_cmd" ]; }; then
        echo "tools/setup.sh: installing chromium (Debian package) for the dashboard's browser test" >&2
        $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null
        $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
            chromium fonts-dejavu-core </dev/null >/dev/null
    else
        echo "tools/setup.sh: chromium is missing and cannot be installed here (needs apt-get as root);" \
             "the dashboard's browser test will skip (and fail under CI=true)" >&2
    fi
fi

if [ "$want_tables" = 1 ]; then
    need python3 "install Python 3.9 or newer"
    python3 -m pip install --quiet -r tools/requirements.txt
    python3 -c "import CoolProp; print('CoolProp', CoolProp.__version__)"
fi
