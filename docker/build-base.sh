#!/bin/sh
# Builds a minimal Debian root filesystem with debootstrap and imports it as a local image, for a
# machine whose container engine cannot pull the Dockerfile's base (no registry reachable, only
# Debian's package mirror): docker/build-image.sh runs it when `debian:<release>-slim` is neither
# present nor pullable.
#
#   docker/build-base.sh ENGINE RELEASE TAG      e.g. docker/build-base.sh podman bookworm simbot-base:bookworm
#
# The result stands in for the official slim image: the same release from Debian's archive
# (variant minbase: Essential and apt), the same apt sources (the release, its updates and its
# security suite), and, as the slim image does, no manual pages, documentation or translations.
# Python is not in it: the Dockerfile installs Debian's python3 on either base, so the two give
# the same interpreter. Needs root (debootstrap) and the `debootstrap` package.
# MIRROR overrides the Debian mirror; by default the one this machine's apt uses.
set -eu

if [ $# -ne 3 ]; then
    echo "usage: $0 ENGINE RELEASE TAG" >&2
    exit 2
fi
engine=$1 release=$2 tag=$3

command -v debootstrap >/dev/null || { echo "$0: debootstrap is not installed (apt-get install debootstrap)" >&2; exit 2; }
[ "$(id -u)" -eq 0 ] || { echo "$0: debootstrap needs root" >&2; exit 2; }

# The first Debian archive this machine's apt lists (one-line or deb822 sources), not its security one.
host_mirror() {
    cat /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources 2>/dev/null \
        | grep -Eo 'https?://[^ ]*/debian/?( |$)' | grep -v security | head -n 1 | tr -d ' '
}
mirror=${MIRROR:-$(host_mirror)}
mirror=${mirror:-http://deb.debian.org/debian}
security=$(echo "$mirror" | sed 's#/debian/*$#/debian-security#')

root=$(mktemp -d "${TMPDIR:-/tmp}/simbot-base.XXXXXX")
trap 'rm -rf "$root"' EXIT

echo "debootstrap $release (minbase) from $mirror into $root" >&2
debootstrap --variant=minbase "$release" "$root" "$mirror" >&2

# The slim image's dpkg filters: later packages install no docs, manuals or translations...
cat >"$root/etc/dpkg/dpkg.cfg.d/docker" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/lintian/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
EOF
# ...and those debootstrap installed go the same way.
find "$root/usr/share/doc" -mindepth 1 -not -name copyright -not -type d -delete
find "$root/usr/share/doc" -mindepth 1 -type d -empty -delete
rm -rf "$root/usr/share/man/"* "$root/usr/share/info/"* "$root/usr/share/groff/"* "$root/usr/share/lintian/"*
find "$root/usr/share/locale" -mindepth 1 -maxdepth 1 -not -name locale.alias -exec rm -rf {} +

# The release, its updates and its security suite, as the official image lists them.
rm -f "$root/etc/apt/sources.list"
cat >"$root/etc/apt/sources.list.d/debian.sources" <<EOF
Types: deb
URIs: $mirror
Suites: $release $release-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: $security
Suites: $release-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
# The release's updates and security fixes, which debootstrap (the release alone) leaves out and
# the official image has.
chroot "$root" sh -c 'apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get upgrade -y -q' >&2
rm -rf "$root/var/lib/apt/lists/"* "$root/var/cache/apt/"*.bin "$root/var/cache/apt/archives/"*.deb \
    "$root/var/log/"*.log "$root/var/log/apt/"*
# The host's name servers, which debootstrap copied in (apt above used them); the engine supplies
# its own at run time.
: >"$root/etc/resolv.conf"

tar --numeric-owner -C "$root" -c . \
    | "$engine" import --change 'CMD ["bash"]' - "$tag" >/dev/null
echo "$tag: $release from $mirror" >&2
