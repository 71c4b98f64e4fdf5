#!/usr/bin/env bash
# Run commands inside a cached Debian chroot that has a newer FreeCAD than the host's 0.20:
# FreeCAD 1.0 from Debian trixie, FreeCAD 1.1 from Debian sid.
#
# Usage:
#   tools/freecad-chroot.sh VERSION ensure               build the chroot if it is missing
#   tools/freecad-chroot.sh VERSION run CMD [ARG...]     run CMD in the chroot (cwd = repo root)
#   tools/freecad-chroot.sh VERSION freecadcmd [ARG...]  run that FreeCAD's FreeCADCmd in the chroot
#   tools/freecad-chroot.sh VERSION script FILE [ARG...] run a Python file in FreeCADCmd as
#                       __main__ with sys.argv = [FILE, ARG...]; exceptions and
#                       sys.exit() give the exit code (`freecadcmd FILE` does not)
#   tools/freecad-chroot.sh VERSION path                 print the chroot's directory
#   tools/freecad-chroot.sh VERSION versions             the Debian versions of its key packages
# VERSION is 1.0 (trixie) or 1.1 (sid); tools/freecad10.sh and tools/freecad11.sh name it for you.
#
# Environment:
#   BSPLINECAM_CHROOTS  folder of the chroots (default /var/cache/bsplinecam)
#   BSPLINECAM_TRIXIE   the 1.0 chroot's directory (default $BSPLINECAM_CHROOTS/trixie)
#   BSPLINECAM_SID      the 1.1 chroot's directory (default $BSPLINECAM_CHROOTS/sid)
#   BSPLINECAM_MIRROR   Debian mirror (default: the host's apt mirror, else
#                       http://deb.debian.org/debian)
#
# The chroot is complete only once the stamp file "$ROOT/.bsplinecam-complete"
# exists; a directory without it (interrupted build) is removed and rebuilt.
# Each `run` happens in its own private mount namespace (unshare -m), so the
# bind mounts (/proc, /dev, /sys, /tmp, repo root) are invisible to other runs
# and vanish when the command ends, even if it is killed. A shared flock keeps
# a rebuild from deleting the chroot while commands run in it.
# Requires root.
set -euo pipefail

SCRIPT="$(readlink -f "${BASH_SOURCE[0]}")"
REPO_ROOT="$(dirname "$(dirname "$SCRIPT")")"
CHROOTS="${BSPLINECAM_CHROOTS:-/var/cache/bsplinecam}"
VERSION="${1:-}"
shift || true
# APT_UPDATE: options of `apt-get update` in the chroot.  sid's Release files of a mirror snapshot
# can be past their Valid-Until date, which apt refuses unless told.
case "$VERSION" in
1.0) SUITE=trixie; ROOT="${BSPLINECAM_TRIXIE:-$CHROOTS/trixie}"; APT_UPDATE=() ;;
1.1) SUITE=sid; ROOT="${BSPLINECAM_SID:-$CHROOTS/sid}"; APT_UPDATE=(-o Acquire::Check-Valid-Until=false) ;;
*) printf 'tools/freecad-chroot.sh: the first argument is the FreeCAD version, 1.0 or 1.1 (got "%s")\n' "$VERSION" >&2
   exit 2 ;;
esac
PROG="tools/freecad-chroot.sh $VERSION"
ROOT="${ROOT%/}"
STAMP="$ROOT/.bsplinecam-complete"
LOCK="$ROOT.lock"
# Packages installed in the chroot. Changing this list makes `ensure` install
# the difference into an existing chroot (no full rebuild).  python3-opencamlib: FreeCAD's own
# 3D Surface op (the benchmark peer) imports it as opencamlib.ocl.
PACKAGES=(freecad-python3 python3-numpy python3-numba python3-opencamlib xvfb xauth linuxcnc-uspace)
# Packages whose Debian versions every test log records (an upstream change shows there).
REPORTED=(freecad-python3 'libocct-modeling-algorithms-*' python3 python3-numpy python3-opencamlib
    'python3-pyside*.qtcore' linuxcnc-uspace)
CHROOT_PATH="/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"

msg() { printf '%s: %s\n' "$PROG" "$*" >&2; }
die() { msg "error: $*"; exit 1; }

usage() {
    sed -n '2,23p' "$SCRIPT" | sed 's/^# \{0,1\}//' >&2
    exit 2
}

need_root() {
    [[ $EUID -eq 0 ]] || die "must run as root (chroot, mount and debootstrap need it)"
}

host_mirror() {
    if [[ -n "${BSPLINECAM_MIRROR:-}" ]]; then
        printf '%s\n' "${BSPLINECAM_MIRROR%/}"
        return
    fi
    local m=""
    # deb822 sources first, then one-line sources; skip the security archive.
    m="$(grep -hsE '^[[:space:]]*URIs:' /etc/apt/sources.list.d/*.sources 2>/dev/null \
        | awk '{for (i = 2; i <= NF; i++) print $i}' \
        | grep -E '^https?://.*/debian/?$' | head -n1 || true)"
    if [[ -z "$m" ]]; then
        m="$(grep -hsE '^[[:space:]]*deb[[:space:]]' /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null \
            | sed -E 's/\[[^]]*\]//' | awk '{print $2}' \
            | grep -E '^https?://.*/debian/?$' | head -n1 || true)"
    fi
    m="${m:-http://deb.debian.org/debian}"
    printf '%s\n' "${m%/}"
}

install_debootstrap() {
    if command -v debootstrap >/dev/null 2>&1 || [[ -x /usr/sbin/debootstrap ]]; then
        return
    fi
    msg "installing debootstrap on the host"
    local cand
    cand="$(apt-cache policy debootstrap 2>/dev/null | awk '/Candidate:/ {print $2}')"
    if [[ -z "$cand" || "$cand" == "(none)" ]]; then
        msg "apt lists lack debootstrap; running apt-get update"
        apt-get update -q >&2
    fi
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends debootstrap >&2
}

# Mounts of anything at or below $1 in the current mount namespace.
mounts_below() {
    awk -v d="$1" '$5 == d || index($5, d "/") == 1 {print $5}' /proc/self/mountinfo
}

remove_partial() {
    local m
    # Only possible if an old non-namespaced process left mounts behind;
    # never let rm recurse into a bind-mounted host /dev or /tmp.
    while read -r m; do
        [[ -n "$m" ]] || continue
        msg "unmounting leftover $m"
        umount -R -l "$m" 2>/dev/null || true
    done < <(mounts_below "$ROOT" | sort -r)
    if [[ -n "$(mounts_below "$ROOT")" ]]; then
        die "$ROOT still has mounts below it; refusing to delete it"
    fi
    msg "removing incomplete chroot $ROOT"
    rm -rf --one-file-system "$ROOT"
}

# Runs in a private mount namespace (see build_locked).
inner_build() {
    local mirror="$1" mode="$2" pkgs=("${PACKAGES[@]}")
    local start=$SECONDS

    if [[ "$mode" == full ]]; then
        local script_arg=()
        if [[ ! -e "/usr/share/debootstrap/scripts/$SUITE" ]]; then
            script_arg=(/usr/share/debootstrap/scripts/sid)
        fi
        msg "debootstrap --variant=minbase $SUITE $ROOT $mirror"
        mkdir -p "$ROOT"
        debootstrap --variant=minbase "$SUITE" "$ROOT" "$mirror" "${script_arg[@]}" >&2 \
            || die "debootstrap failed (log: $ROOT/debootstrap/debootstrap.log)"

        # Smaller and faster: no docs/man/locales, no fsync, no recommends.
        cat >"$ROOT/etc/dpkg/dpkg.cfg.d/01bsplinecam" <<'EOF'
force-unsafe-io
path-exclude=/usr/share/doc/*
path-include=/usr/share/doc/*/copyright
path-exclude=/usr/share/man/*
path-exclude=/usr/share/info/*
path-exclude=/usr/share/locale/*
path-include=/usr/share/locale/locale.alias
EOF
        cat >"$ROOT/etc/apt/apt.conf.d/01bsplinecam" <<'EOF'
APT::Install-Recommends "false";
APT::Install-Suggests "false";
Acquire::Languages "none";
Dpkg::Use-Pty "false";
EOF
        printf 'deb %s %s main\n' "$mirror" "$SUITE" >"$ROOT/etc/apt/sources.list"
        # No daemons may start inside the chroot.
        printf '#!/bin/sh\nexit 101\n' >"$ROOT/usr/sbin/policy-rc.d"
        chmod 755 "$ROOT/usr/sbin/policy-rc.d"
    fi

    cp -L /etc/resolv.conf "$ROOT/etc/resolv.conf" 2>/dev/null || true
    mount_common
    msg "installing in chroot: ${pkgs[*]}"
    chroot_env apt-get "${APT_UPDATE[@]}" update -q >&2 \
        || die "apt-get update failed in the $SUITE chroot: is $mirror reachable?"
    chroot_env env DEBIAN_FRONTEND=noninteractive \
        apt-get install -y -q --no-install-recommends "${pkgs[@]}" >&2
    chroot_env apt-get clean
    rm -rf "$ROOT"/var/lib/apt/lists/* "$ROOT/debootstrap" 2>/dev/null || true

    msg "checking FreeCADCmd"
    chroot_env sh -c "$(freecadcmd_snippet)" sh -c 'import FreeCAD, Part' >&2 \
        || die "FreeCADCmd does not work in the chroot"
    umount_common

    printf '%s\n' "${pkgs[@]}" >"$STAMP.tmp"
    mv "$STAMP.tmp" "$STAMP"
    msg "chroot ready in $ROOT ($((SECONDS - start)) s)"
}

# Called with the exclusive lock held; decides whether work is needed.
build_locked() {
    local mode
    if [[ -f "$STAMP" ]]; then
        local missing
        missing="$(printf '%s\n' "${PACKAGES[@]}" | grep -vxF -f "$STAMP" || true)"
        [[ -n "$missing" ]] || return 0
        msg "package list changed; adding: $(echo "$missing" | tr '\n' ' ')"
        mode=update
    else
        [[ -e "$ROOT" ]] && remove_partial
        install_debootstrap
        mode=full
    fi
    if ! unshare --mount --propagation private "$SCRIPT" "$VERSION" __build "$(host_mirror)" "$mode"; then
        # nothing half-installed stays behind: a new chroot that failed is removed whole
        [[ "$mode" == full && -e "$ROOT" ]] && remove_partial
        die "could not build the FreeCAD $VERSION chroot ($SUITE); it needs Debian's mirror $(host_mirror) (network) and root"
    fi
}

stamp_current() {
    [[ -f "$STAMP" ]] && ! printf '%s\n' "${PACKAGES[@]}" | grep -qvxF -f "$STAMP"
}

ensure() {
    need_root
    stamp_current && return 0
    mkdir -p "$(dirname "$ROOT")"
    exec 8>>"$LOCK"
    msg "chroot incomplete or outdated; taking the build lock $LOCK"
    flock -x 8
    build_locked
    exec 8>&-
}

# --- mounts (only ever done inside a private mount namespace) -------------

MOUNTED=()

bind() { # bind SRC DST [extra mount options]
    local src="$1" dst="$ROOT$2"
    shift 2
    mkdir -p "$dst"
    mount "$@" "$src" "$dst"
    MOUNTED+=("$dst")
}

mount_common() {
    bind /proc /proc --rbind
    bind /sys /sys --rbind
    bind /dev /dev --rbind
}

umount_common() {
    local i
    for ((i = ${#MOUNTED[@]} - 1; i >= 0; i--)); do
        umount -R -l "${MOUNTED[i]}" 2>/dev/null || msg "warning: could not unmount ${MOUNTED[i]}"
    done
    MOUNTED=()
}

# Run a command in the chroot with a clean environment, cwd = repo root when
# it is reachable at the same path (bound itself or under /tmp), / otherwise.
chroot_env() {
    local cwd=/ v
    # The repo is reachable at the same path when bind-mounted itself or under the /tmp bind.
    [[ -d "$ROOT$REPO_ROOT" && "$REPO_ROOT" -ef "$ROOT$REPO_ROOT" ]] && cwd="$REPO_ROOT"
    local envs=(HOME=/root USER=root LOGNAME=root "PATH=$CHROOT_PATH"
        LANG=C.UTF-8 LC_ALL=C.UTF-8 "TERM=${TERM:-dumb}" QT_QPA_PLATFORM=offscreen)
    for v in $(compgen -e); do
        case "$v" in
        BSPLINECAM_* | CI | PYTHONUNBUFFERED | PYTHONDONTWRITEBYTECODE | PYTHONHASHSEED)
            envs+=("$v=${!v}") ;;
        esac
    done
    chroot "$ROOT" /usr/bin/env -i -C "$cwd" "${envs[@]}" "$@"
}

# sh snippet that execs FreeCAD's command-line binary with "$@".
freecadcmd_snippet() {
    cat <<'EOF'
for c in /usr/bin/freecadcmd /usr/bin/FreeCADCmd /usr/lib/freecad/bin/freecadcmd-python3 /usr/lib/freecad/bin/FreeCADCmd \
         /usr/lib/freecad-python3/bin/FreeCADCmd; do
    [ -x "$c" ] && exec "$c" "$@"
done
echo "freecad-chroot.sh: FreeCADCmd not found in the chroot" >&2
exit 127
EOF
}

# Python str literal for $1 (argv strings cannot contain NUL).
py_str() {
    local s="$1"
    s="${s//\\/\\\\}"
    s="${s//\'/\\\'}"
    s="${s//$'\n'/\\n}"
    s="${s//$'\r'/\\r}"
    printf "'%s'" "$s"
}

# `freecadcmd FILE` runs FILE under its stem as module name, ignores its
# exit status and runs it a second time when it raises; `freecadcmd -c CODE`
# returns a proper status, so wrap the file with runpy.
script() {
    [[ $# -gt 0 ]] || die "script: missing FILE"
    local file a argv
    file="$(readlink -f "$1")"
    [[ -f "$file" ]] || die "script: no such file: $1"
    shift
    argv="$(py_str "$file")"
    for a in "$@"; do
        argv+=", $(py_str "$a")"
    done
    run sh -c "$(freecadcmd_snippet)" sh -c \
        "import sys, runpy; sys.argv = [$argv]; runpy.run_path(sys.argv[0], run_name='__main__')"
}

# Runs in a private mount namespace with the shared lock held.
inner_run() {
    [[ -f "$STAMP" ]] || die "chroot $ROOT is not complete (rebuilt concurrently?)"
    trap umount_common EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM
    mount_common
    bind /tmp /tmp --bind
    if [[ ! "$REPO_ROOT" -ef "$ROOT$REPO_ROOT" ]]; then
        bind "$REPO_ROOT" "$REPO_ROOT" --bind
    fi
    # The project venv (cadquery's OCCT) runs on the host's Python: mount that Python's prefix
    # read-only at the same path so cross-checks inside the chroot reach the second OCCT too.
    local venv_py="$REPO_ROOT/.venv/bin/python" prefix
    if [[ -x "$venv_py" ]]; then
        prefix="$(dirname "$(dirname "$(readlink -f "$venv_py")")")"
        if [[ "$prefix" != /usr && "$prefix" != /usr/local && -d "$prefix" ]]; then
            bind "$prefix" "$prefix" --bind -o ro
        fi
    fi
    local rc=0
    chroot_env "$@" 8>&- || rc=$?
    exit "$rc"
}

run() {
    [[ $# -gt 0 ]] || die "run: missing command"
    ensure
    exec 8>>"$LOCK"
    flock -s 8
    exec unshare --mount --propagation private "$SCRIPT" "$VERSION" __run "$@"
}

main() {
    [[ $# -gt 0 ]] || usage
    local cmd="$1"
    shift
    case "$cmd" in
    ensure) ensure ;;
    run) run "$@" ;;
    freecadcmd) run sh -c "$(freecadcmd_snippet)" sh "$@" ;;
    script) script "$@" ;;
    path) printf '%s\n' "$ROOT" ;;
    versions) run dpkg-query -W -f='${db:Status-Abbrev} ${Package} ${Version}\n' "${REPORTED[@]}" 2>/dev/null | sed -n 's/^ii *//p' ;;
    __build) inner_build "$@" ;;
    __run) inner_run "$@" ;;
    -h | --help | help) usage ;;
    *) msg "unknown command: $cmd"; usage ;;
    esac
}

main "$@"
