#!/usr/bin/env bash
# `make image`: the test stage as simbot:test and the image as simbot, with docker or podman
# (docker/engine.sh picks). The Dockerfile's base (ARG BASE) is used where the engine has it or
# can pull it; otherwise docker/build-base.sh debootstraps the same Debian release from Debian's
# mirror into simbot-base:<release> (once; delete that image to make it again), and both builds
# start from that. Prints each step's wall time.
set -euo pipefail
cd "$(dirname "$0")/.."

engine=$(docker/engine.sh --which)
base=$(sed -n 's/^ARG BASE=//p' docker/Dockerfile)
release=${base##*:}
release=${release%-slim}
[[ -n $base && -n $release ]] || { echo "docker/build-image.sh: no ARG BASE=<image>:<release>-slim in docker/Dockerfile" >&2; exit 2; }
local_base=simbot-base:$release

# Runs a command under a title and says how long it took; its status is the command's (also where
# the caller tests it, and `set -e` does not apply).
step() {
    local start=$SECONDS status=0
    echo "== $1" >&2
    shift
    "$@" || status=$?
    echo "== $((SECONDS - start)) s" >&2
    return $status
}

if docker/engine.sh image inspect "$base" >/dev/null 2>&1; then
    from=$base
elif docker/engine.sh image inspect "$local_base" >/dev/null 2>&1; then
    from=$local_base
elif step "pull $base" docker/engine.sh pull "$base"; then
    from=$base
else
    echo "$engine cannot pull $base: building $local_base from Debian's packages instead" >&2
    step "debootstrap $local_base" docker/build-base.sh "$engine" "$release" "$local_base"
    from=$local_base
fi
echo "$engine, FROM $from" >&2

build=(--file docker/Dockerfile --build-arg "BASE=$from")
# A host behind a TLS-inspecting proxy trusts the proxy's CA in its bundle; pip in the build does too.
bundle=/etc/ssl/certs/ca-certificates.crt
[[ -f $bundle ]] && build+=(--secret "id=ca-certificates,src=$bundle")

step "build simbot:test" docker/engine.sh build "${build[@]}" --target test --tag simbot:test .
step "build simbot" docker/engine.sh build "${build[@]}" --tag simbot .
docker/engine.sh images --filter reference=simbot --filter reference=simbot-base >&2
