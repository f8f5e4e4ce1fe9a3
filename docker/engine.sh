#!/usr/bin/env bash
# The container engine this machine has, with the options it needs here, so that `make image`, the
# tests and people run the same thing:
#
#   docker/engine.sh --which                the engine's name (exit 2, with why, if none works)
#   docker/engine.sh build|run|create ...   that command, with the options below
#   docker/engine.sh compose ...            `docker compose`, or podman-compose with the options
#   docker/engine.sh ...                    any other command as it is (images, rm, logs, ...)
#
# docker where its daemon answers (`docker info`), else podman (SIMBOT_ENGINE=docker|podman picks).
# Podman gets the OCI runtime runc, and explicit ulimits: its defaults (nofile 1048576, nproc
# 4194304) are above this machine's hard limits, and the container then fails to start ("error
# setting rlimits ... operation not permitted"). nofile is the hard limit of this shell; nproc is
# that, but at most 32768, the hard limit podman 4.3 runs itself and conmon with (measured in
# /proc/PID/limits), which a container cannot exceed. Podman builds in Docker's image format: the
# OCI format has no HEALTHCHECK, and podman drops it with only a warning.
set -euo pipefail

die() {
    echo "docker/engine.sh: $*" >&2
    exit 2
}

works() {
    command -v "$1" >/dev/null && "$1" info >/dev/null 2>&1
}

which_engine() {
    case ${SIMBOT_ENGINE:-} in
        docker | podman) works "$SIMBOT_ENGINE" || die "SIMBOT_ENGINE=$SIMBOT_ENGINE: \`$SIMBOT_ENGINE info\` fails"
            echo "$SIMBOT_ENGINE" ;;
        "") if works docker; then echo docker
            elif works podman; then echo podman
            else die "no container engine: docker's daemon does not answer (docker info) and podman is missing or fails (podman info); on Debian: apt-get install podman"
            fi ;;
        *) die "SIMBOT_ENGINE=$SIMBOT_ENGINE: docker or podman" ;;
    esac
}

# A hard limit of this shell as an engine's ulimit (soft = hard), capped at $2 when given.
limit() {
    local hard
    hard=$(ulimit -H "$1")
    [[ $hard == unlimited ]] && hard=${2:-1048576}
    [[ -n ${2:-} && $hard -gt $2 ]] && hard=$2
    echo "$hard:$hard"
}

podman_options() {
    local options=(--ulimit "nofile=$(limit -n)" --ulimit "nproc=$(limit -u 32768)")
    command -v runc >/dev/null && options+=(--runtime runc)
    echo "${options[@]}"
}

engine=$(which_engine)
[[ $# -gt 0 ]] || die "usage: docker/engine.sh --which | COMMAND ARGS..."
command=$1
shift
case $engine:$command in
    *:--which) echo "$engine" ;;
    podman:build)
        # shellcheck disable=SC2046  # the options are words without spaces
        exec podman build --format docker $(podman_options) "$@" ;;
    podman:run | podman:create)
        # shellcheck disable=SC2046
        exec podman "$command" $(podman_options) "$@" ;;
    docker:compose) exec docker compose "$@" ;;
    podman:compose)
        command -v podman-compose >/dev/null \
            || die "podman-compose is not installed (apt-get install podman-compose, or pip install podman-compose)"
        options=$(podman_options)
        exec podman-compose --podman-run-args "$options" --podman-build-args "$options" "$@" ;;
    *) exec "$engine" "$command" "$@" ;;
esac
