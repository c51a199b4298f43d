#!/usr/bin/env bash
# Builds the cryofit image from local parts only (no registry, nothing pulled).
#
#   docker/build-image.sh [--tag NAME] [--binary PATH]
#
# Without --binary it runs `cargo build --release -p cryofit` (a no-op when the binary is up to
# date; CARGO_TARGET_DIR is honoured) and uses target/release/cryofit. The binary is stripped and
# staged with the shared libraries `ldd` reports (so the image runs the same glibc the binary was
# linked against), an unprivileged user `cryofit` (uid 10001) and an nsswitch.conf for name
# resolution, then `docker build` turns docker/Dockerfile (FROM scratch) into the image.
# Tags NAME (default cryofit:latest) and cryofit:VERSION; prints the image's size.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/.." && pwd)"

tag=cryofit:latest
binary=
while [ $# -gt 0 ]; do
    case "$1" in
        --tag) tag="${2:?--tag needs a name}"; shift 2 ;;
        --binary) binary="${2:?--binary needs a path}"; shift 2 ;;
        -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
        *) echo "docker/build-image.sh: unknown option '$1' (try --help)" >&2; exit 2 ;;
    esac
done

if [ -z "$binary" ]; then
    (cd "$repo" && cargo build --release -p cryofit --quiet)
    binary="${CARGO_TARGET_DIR:-$repo/target}/release/cryofit"
fi
if [ ! -x "$binary" ]; then
    echo "docker/build-image.sh: no executable cryofit binary at $binary" >&2
    exit 1
fi
version=$("$binary" --version | awk '{print $2}')

stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
root="$stage/rootfs"
mkdir -p "$root/usr/local/bin" "$root/etc" "$stage/data" "$stage/tmp"
chmod 1777 "$stage/tmp"
if command -v strip >/dev/null 2>&1; then
    strip --strip-all -o "$root/usr/local/bin/cryofit" "$binary"
else
    cp "$binary" "$root/usr/local/bin/cryofit"
fi
chmod 0755 "$root/usr/local/bin/cryofit"

# the dynamic loader and every library the binary needs, at the paths the loader looks them up
libs=$(ldd "$binary" | awk '/=> \//{print $3} /^[[:space:]]*\/.*ld-linux/{print $1}')
if ! grep -q 'ld-linux' <<<"$libs"; then
    echo "docker/build-image.sh: ldd found no dynamic loader for $binary:" >&2
    ldd "$binary" >&2 || true
    exit 1
fi
for lib in $libs; do
    mkdir -p "$root$(dirname "$lib")"
    cp -L "$lib" "$root$lib"
done

cat >"$root/etc/passwd" <<'PASSWD'
root:x:0:0:root:/root:/sbin/nologin
cryofit:x:10001:10001:cryofit:/data:/sbin/nologin
PASSWD
cat >"$root/etc/group" <<'GROUP'
root:x:0:
cryofit:x:10001:
GROUP
# glibc resolves host names (the coordinator's service name) through /etc/hosts, then DNS
echo 'hosts: files dns' >"$root/etc/nsswitch.conf"

cp "$here/Dockerfile" "$stage/Dockerfile"
# the classic builder needs nothing but the engine; BuildKit is used where buildx is installed
if ! docker buildx version >/dev/null 2>&1; then
    export DOCKER_BUILDKIT=0
fi
if ! docker build --quiet --build-arg "VERSION=$version" -t "$tag" -t "cryofit:$version" "$stage" \
    >"$stage/build.log" 2>&1; then
    cat "$stage/build.log" >&2
    echo "docker/build-image.sh: docker build failed" >&2
    exit 1
fi
size=$(docker image inspect -f '{{.Size}}' "$tag")
echo "built $tag (cryofit $version): $((size / 1024 / 1024)) MiB ($size bytes)"
