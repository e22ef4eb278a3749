#!/bin/sh
# Builds the stack's images with podman where no image registry is reachable (tests/integration/test_containers.py,
# docs/operator.md): a Debian bookworm base made by debootstrap from Debian's packages, python/postgres/redis/nginx
# stand-ins on it (docker/ci/*.Containerfile), and the API and CPU worker images from docker/*.Dockerfile with that
# base as PYTHON_IMAGE and the torch wheel from a folder on disk. Layers are cached: a second run rebuilds only what
# changed. Run from the repository root as root. Prints one "built NAME in S s" line per image.
#   TORCH_WHEELS  folder holding the locked torch wheel (default: pip's find-links, /opt/wheels here)
#   CA_CERTS      folder of extra certificate authorities for pip in the builds (default /usr/local/share/ca-certificates)
#   TAG           tag of the images (default ci): localhost/l03-grader-api:$TAG, localhost/l03-grader-worker-cpu:$TAG, ...
set -eu
cd "$(dirname "$0")/../.."
: "${CONTAINERS_CONF:=$PWD/docker/ci/containers.conf}"
export CONTAINERS_CONF
TAG=${TAG:-ci}
CA_CERTS=${CA_CERTS:-/usr/local/share/ca-certificates}
TORCH_WHEELS=${TORCH_WHEELS:-$(pip config get global.find-links 2>/dev/null || echo /opt/wheels)}
BASE=localhost/debian:bookworm
PYTHON=localhost/l03-python:3.11-bookworm

timed() {  # NAME COMMAND...: run it, say how long it took
    name=$1; shift; start=$(date +%s)
    "$@"
    echo "built $name in $(( $(date +%s) - start )) s"
}

debian_base() {
    root=$(mktemp -d /var/tmp/l03-debootstrap.XXXXXX)
    trap 'rm -rf "$root"' EXIT
    debootstrap --variant=minbase bookworm "$root" http://deb.debian.org/debian >/dev/null
    tar -C "$root" -c . | podman import --quiet - "$BASE"
    rm -rf "$root"; trap - EXIT
}

build() {  # CONTAINERFILE IMAGE [podman build options]
    file=$1; image=$2; shift 2
    podman build --quiet --network host --format docker --layers -f "$file" -t "$image" "$@" . >/dev/null
}

podman image exists "$BASE" || timed "$BASE" debian_base
timed "$PYTHON" build docker/ci/python.Containerfile "$PYTHON" --build-arg DEBIAN_IMAGE="$BASE" \
    --build-context cacerts="$CA_CERTS"
for service in postgres redis nginx; do
    timed "localhost/l03-grader-$service:$TAG" build "docker/ci/$service.Containerfile" \
        "localhost/l03-grader-$service:$TAG" --build-arg DEBIAN_IMAGE="$BASE"
done
timed "localhost/l03-grader-api:$TAG" build docker/api.Dockerfile "localhost/l03-grader-api:$TAG" \
    --build-arg PYTHON_IMAGE="$PYTHON"
timed "localhost/l03-grader-worker-cpu:$TAG" build docker/worker-cpu.Dockerfile "localhost/l03-grader-worker-cpu:$TAG" \
    --build-arg PYTHON_IMAGE="$PYTHON" --build-arg TORCH_INDEX_URL= --build-context wheels="$TORCH_WHEELS"
