#!/usr/bin/env bash
# scripts/blender.sh - Loom's way to get a headless Blender >= 4.2 and run it.
#
# Which Blender (first match wins):
#   1. $LOOM_BLENDER: an executable (path or command name) that must report
#      Blender >= 4.2 with --version; anything else is an error, not a fallback.
#      LOOM_BLENDER=chroot forces choice 3.
#   2. `blender` on PATH, if its --version says >= 4.2.
#   3. Debian trixie's `blender` package (Blender 4.3) in a minbase Debian
#      chroot that this script provisions once with debootstrap and caches in
#      ${LOOM_CACHE:-$HOME/.cache/loom}/blender-trixie (outside the clone).
# Inside Loom's own chroot, the chroot's /usr/bin/blender is used directly.
#
# Run `scripts/blender.sh --help` for the commands.  Design notes are in the
# comments next to the code that implements them.

set -euo pipefail

readonly MIN_MAJOR=4 MIN_MINOR=2
readonly SUITE=trixie
# Packages installed into the chroot.  Debian's blender pulls in python3 and
# everything Cycles needs to render on the CPU headless; nothing else was
# needed in testing.
readonly CHROOT_PACKAGES=(blender)
# Bump when the provisioning recipe changes: a cache made by another recipe is
# rebuilt (atomically) on the next run.
readonly RECIPE=1
# Marker file at the top of a complete chroot.  It is written last, just
# before the temporary build directory is renamed into place, so a cache
# without it is never used.  Inside the chroot it is /.loom-blender-chroot,
# which is also how scripts (and the host-exec wrappers) tell they are inside.
readonly MARKER_NAME=.loom-blender-chroot
# Where the chroot shows the host's root file system (see cmd_enter).
readonly HOST_MNT=host
readonly CHROOT_PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
# Top-level directories that belong to the operating system: inside the chroot
# these are trixie's own.  "host" is reserved for the view of the host's /.
readonly OS_DIRS=" bin boot dev etc host lib lib32 lib64 libx32 lost+found proc run sbin sys usr var "
# Top-level host directories always shared with the chroot at the same path
# (if they exist).  Others are shared on demand only (see cmd_enter): a fixed
# allow-list rather than "every non-OS directory", so unrelated top-level
# directories of the machine are not exposed writable to the chroot.
readonly ALWAYS_SHARED=(home root tmp srv opt media)
readonly APT_OPTS=(-o DPkg::Lock::Timeout=600)

PROG=${0##*/}
# Host tools such as chroot live in sbin, which a non-root PATH may lack.
# (Appended, so this does not change which 'blender' is found first.)
PATH=$PATH:/usr/sbin:/sbin
SCRIPT_PATH=$(readlink -f -- "${BASH_SOURCE[0]}")
if [[ -n ${LOOM_CACHE:-} ]]; then
    CACHE_DIR=$LOOM_CACHE
elif [[ -n ${HOME:-} ]]; then
    CACHE_DIR=$HOME/.cache/loom
else
    CACHE_DIR=
fi
ROOT=${CACHE_DIR:+$CACHE_DIR/blender-$SUITE}
LOCK_FILE=${CACHE_DIR:+$CACHE_DIR/blender-$SUITE.lock}
LOG_FILE=${CACHE_DIR:+$CACHE_DIR/blender-$SUITE.provision.log}

usage() {
    cat <<EOF
Usage: $PROG COMMAND [ARGS...]

Get a headless Blender >= $MIN_MAJOR.$MIN_MINOR for Loom and run it.

Commands:
  run [BLENDER_ARGS...]   Run Blender with exactly these arguments (add -b for
                          background mode yourself).  The exit status is
                          Blender's.  Example:
                            $PROG run -b --factory-startup --python-exit-code 1 \\
                                --python tests/blender/test_blender_runs.py
  exec CMD [ARGS...]      Run any command in the same environment as 'run'
                          (inside the chroot when that is the Blender in use).
  info                    Print JSON about the Blender in use:
                            {"blender": PATH or "chroot", "version": "4.3.2",
                             "with_osl": true|false, "chroot": ROOT or null}
  provision               Make sure the Debian $SUITE chroot is provisioned, even
                          if another Blender would be chosen.  Needs root.
  clean                   Delete the cached chroot (waits for chroot runs).
  host-exec-wrapper BIN OUT
                          Write OUT, a /bin/sh script that runs the host program
                          BIN with its arguments.  Called from Blender inside the
                          chroot it re-enters the host's file system (shown
                          read-only at /$HOST_MNT, with the shared directories
                          writable) so BIN runs with the host's own libraries and
                          data; called anywhere else it just execs BIN.
  -h, --help              Show this help.

Choice of Blender (first match wins):
  1. \$LOOM_BLENDER, an executable reporting Blender >= $MIN_MAJOR.$MIN_MINOR
     (LOOM_BLENDER=chroot forces 3);
  2. 'blender' on PATH if it is >= $MIN_MAJOR.$MIN_MINOR;
  3. Debian $SUITE's blender package in a chroot provisioned on first use with
     debootstrap (about 2.5 minutes and 1.3 GB, needs root) and cached in
     \${LOOM_CACHE:-\$HOME/.cache/loom}/blender-$SUITE.

Inside the chroot, host paths keep their meaning: /home, /root, /tmp, /srv,
/opt, /media, /var/tmp, the clone's top-level directory (e.g. /work), and the
top-level directories of \$HOME, \$TMPDIR, the working directory, existing
absolute paths in the arguments and \$LOOM_BLENDER_SHARE entries are
bind-mounted at the same path (writable).  /usr, /etc, /var, ... are the
chroot's own; the host's whole / is visible read-only at /host.  The working
directory is kept.  PATH is reset, LC_ALL and LANG are C.UTF-8, LD_LIBRARY_PATH,
LD_PRELOAD and PYTHONHOME are dropped, everything else (HOME, TMPDIR,
LOOM_*, ...) is passed through, and LOOM_BLENDER_CHROOT is set to the
chroot's path on the host.  Runs as non-root use a user namespace (best
effort; provisioning itself needs root).

Environment:
  LOOM_BLENDER        Blender executable to use, or "chroot"
  LOOM_CACHE          cache directory (default \$HOME/.cache/loom)
  LOOM_BLENDER_SHARE  extra colon-separated host paths to show in the chroot
EOF
}

die() {
    printf '%s: error: %s\n' "$PROG" "$*" >&2
    exit 1
}

note() {
    printf '%s: %s\n' "$PROG" "$*" >&2
}

json_str() {
    local s=$1
    s=${s//\\/\\\\}
    s=${s//\"/\\\"}
    printf '"%s"' "$s"
}

# ---------------------------------------------------------------------------
# Choosing a Blender

# Print "X.Y.Z" for the Blender executable $1, or fail.  The output is
# captured first (no pipe into grep, which could kill blender with SIGPIPE and
# trip pipefail), and the "Blender X.Y[.Z]" line is searched for because some
# builds print warnings before it.
blender_version() {
    local out line
    out=$(timeout 120 "$1" --version 2>/dev/null) || return 1
    while IFS= read -r line; do
        if [[ $line =~ ^Blender\ ([0-9]+\.[0-9]+(\.[0-9]+)?) ]]; then
            printf '%s\n' "${BASH_REMATCH[1]}"
            return 0
        fi
    done <<<"$out"
    return 1
}

version_ok() {
    local major minor rest
    IFS=. read -r major minor rest <<<"$1"
    ((major > MIN_MAJOR || (major == MIN_MAJOR && minor >= MIN_MINOR)))
}

# Sets SEL_KIND (host|chroot), SEL_BIN (path or "chroot") and, for host
# Blenders, SEL_VERSION.
select_blender() {
    local bin ver
    SEL_VERSION=
    if [[ -f /$MARKER_NAME && -x /usr/bin/blender ]]; then
        # Already inside Loom's chroot (e.g. a script run by the chroot's
        # Blender calls us again): its Blender is the one.
        SEL_KIND=host SEL_BIN=/usr/bin/blender
        SEL_VERSION=$(blender_version /usr/bin/blender) || die "cannot get the version of /usr/bin/blender inside the chroot"
        return
    fi
    if [[ -n ${LOOM_BLENDER:-} ]]; then
        if [[ $LOOM_BLENDER == chroot ]]; then
            SEL_KIND=chroot SEL_BIN=chroot
            return
        fi
        bin=$LOOM_BLENDER
        if [[ $bin != */* ]]; then
            bin=$(type -P -- "$bin") || die "LOOM_BLENDER=$LOOM_BLENDER: no such command on PATH"
        fi
        [[ -f $bin && -x $bin ]] || die "LOOM_BLENDER=$LOOM_BLENDER is not an executable file"
        ver=$(blender_version "$bin") || die "LOOM_BLENDER=$LOOM_BLENDER: '$bin --version' does not report a Blender version"
        version_ok "$ver" || die "LOOM_BLENDER=$LOOM_BLENDER is Blender $ver; Loom needs Blender >= $MIN_MAJOR.$MIN_MINOR"
        SEL_KIND=host SEL_BIN=$bin SEL_VERSION=$ver
        return
    fi
    if bin=$(type -P blender); then
        if ver=$(blender_version "$bin") && version_ok "$ver"; then
            SEL_KIND=host SEL_BIN=$bin SEL_VERSION=$ver
            return
        fi
        note "ignoring $bin (version ${ver:-unknown}; Loom needs >= $MIN_MAJOR.$MIN_MINOR); using the Debian $SUITE chroot"
    fi
    SEL_KIND=chroot SEL_BIN=chroot
}

# ---------------------------------------------------------------------------
# The chroot: provisioning

need_cache_dir() {
    [[ -n $CACHE_DIR ]] || die "neither LOOM_CACHE nor HOME is set; cannot place the Blender chroot cache"
}

chroot_ready() {
    [[ -f $ROOT/$MARKER_NAME && -x $ROOT/usr/bin/blender ]] &&
        grep -qx "recipe=$RECIPE" "$ROOT/$MARKER_NAME"
}

marker_value() {
    sed -n "s/^$1=//p" "$ROOT/$MARKER_NAME" | head -n1
}

# Delete a directory tree we made, refusing if anything is mounted below it
# (rm -rf through a leaked bind mount of /work would be a disaster; all our
# own mounts live in private mount namespaces, so normally there are none).
safe_rm() {
    local dir=$1 mnt
    [[ -e $dir ]] || return 0
    dir=$(readlink -f -- "$dir")
    while read -r _ _ _ _ mnt _; do
        if [[ $mnt == "$dir" || $mnt == "$dir"/* ]]; then
            die "refusing to delete $dir: $mnt is mounted inside it (unmount it first)"
        fi
    done </proc/self/mountinfo
    rm -rf --one-file-system -- "$dir"
}

ensure_host_tools() {
    local t missing=()
    for t in unshare chroot flock mount timeout; do
        type -P "$t" >/dev/null || missing+=("$t")
    done
    ((${#missing[@]} == 0)) || die "missing host tools: ${missing[*]} (Debian packages util-linux, coreutils, mount)"
}

ensure_debootstrap() {
    type -P debootstrap >/dev/null && return 0
    type -P apt-get >/dev/null || die "debootstrap is not installed and there is no apt-get to install it"
    note "installing debootstrap on the host with apt-get"
    local pkgs=(debootstrap debian-archive-keyring)
    if ! DEBIAN_FRONTEND=noninteractive apt-get "${APT_OPTS[@]}" install -y --no-install-recommends "${pkgs[@]}" >>"$LOG_FILE" 2>&1; then
        # Most likely stale or missing package lists: refresh once and retry.
        if ! DEBIAN_FRONTEND=noninteractive apt-get "${APT_OPTS[@]}" update >>"$LOG_FILE" 2>&1 ||
            ! DEBIAN_FRONTEND=noninteractive apt-get "${APT_OPTS[@]}" install -y --no-install-recommends "${pkgs[@]}" >>"$LOG_FILE" 2>&1; then
            die "could not install debootstrap with apt-get (see $LOG_FILE)"
        fi
    fi
    type -P debootstrap >/dev/null || die "debootstrap still missing after apt-get install"
}

# Run "$@" on the host, output to the log; on failure show the log's tail.
logged() {
    local what=$1
    shift
    if ! "$@" >>"$LOG_FILE" 2>&1; then
        tail -n 25 "$LOG_FILE" >&2 || true
        die "$what failed (full log: $LOG_FILE)"
    fi
}

# Run a command inside chroot $1 with only /proc and /dev (for apt and dpkg).
# A private mount namespace makes the mounts disappear with the process, so an
# interrupted provisioning leaves nothing mounted.
in_new_root() {
    local root=$1
    shift
    unshare --mount --propagation private -- "$BASH" "$SCRIPT_PATH" __enter provision "$root" / -- "$@"
}

# Build the chroot in a temporary sibling directory and rename it into place
# only when complete.  Called with the exclusive lock held.
provision() {
    local t0=$SECONDS tmp old ver avail d
    ((EUID == 0)) || die "provisioning the Blender chroot needs root (debootstrap, chroot); run '$PROG provision' as root once, or set LOOM_BLENDER to a Blender >= $MIN_MAJOR.$MIN_MINOR"
    ensure_host_tools
    : >"$LOG_FILE"
    ensure_debootstrap

    # Leftovers of interrupted provisionings (we hold the lock, so nobody
    # else is building).
    for d in "$ROOT".tmp.* "$ROOT".old.*; do
        [[ -e $d ]] || continue
        note "removing leftover $d"
        safe_rm "$d"
    done

    avail=$(df -Pk -- "$CACHE_DIR" | awk 'NR == 2 { print $4 }')
    ((avail > 3 * 1024 * 1024)) || die "less than 3 GiB free in $CACHE_DIR; the Blender chroot needs about 2 GiB"

    tmp=$(mktemp -d "$ROOT.tmp.XXXXXX")
    # mktemp makes it 0700; as the chroot's / it must be 0755 (apt's
    # download sandbox user _apt and any non-root process must traverse it).
    chmod 755 "$tmp"
    PROVISION_TMP=$tmp
    # Remove the half-built tree on failure or interruption.  (SIGKILL
    # leaves it behind; the next provisioning removes it, see above.)
    trap 'safe_rm "$PROVISION_TMP"' EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM

    note "provisioning Blender in a Debian $SUITE chroot at $ROOT (one-time, about 2 minutes; log: $LOG_FILE)"
    # No mirror argument: debootstrap's default Debian mirror is used, and
    # the chroot's sources.list points at it.  Run in a private mount
    # namespace so the /proc and /sys that debootstrap mounts inside the
    # target vanish even if it is killed.
    logged "debootstrap --variant=minbase $SUITE" \
        unshare --mount --propagation private -- debootstrap --variant=minbase "$SUITE" "$tmp"
    note "debootstrap done after $((SECONDS - t0)) s; installing ${CHROOT_PACKAGES[*]}"

    # Never start services inside the chroot.
    printf '#!/bin/sh\nexit 101\n' >"$tmp/usr/sbin/policy-rc.d"
    chmod 755 "$tmp/usr/sbin/policy-rc.d"
    logged "apt-get update in the chroot" \
        in_new_root "$tmp" apt-get "${APT_OPTS[@]}" update
    logged "apt-get install ${CHROOT_PACKAGES[*]} in the chroot" \
        in_new_root "$tmp" apt-get "${APT_OPTS[@]}" install -y --no-install-recommends "${CHROOT_PACKAGES[@]}"
    # The .debs and package lists are not needed to run (saves ~400 MB).
    logged "apt-get clean in the chroot" in_new_root "$tmp" apt-get clean
    rm -rf -- "$tmp"/var/lib/apt/lists/*

    # minbase has no /etc/mtab; Blender's file browser code reads it at
    # startup and otherwise prints "could not get a list of mounted
    # file-systems".
    ln -sfn ../proc/self/mounts "$tmp/etc/mtab"
    # Mount points for the host's / (see cmd_enter) and for the usual shared
    # directories, including the top of this clone (so that runs as
    # non-root, which cannot create mount points, work too).
    mkdir -p -- "$tmp/$HOST_MNT"
    for d in "${ALWAYS_SHARED[@]}" "$(top_dir "$SCRIPT_PATH")"; do
        [[ $OS_DIRS == *" $d "* ]] || mkdir -p -- "$tmp/$d"
    done

    ver=$(in_new_root "$tmp" blender --version 2>/dev/null | sed -n 's/^Blender \([0-9][0-9.]*\).*/\1/p' | head -n1) || true
    [[ -n $ver ]] || die "the chroot's blender does not run ('blender --version' failed; see $LOG_FILE)"
    version_ok "$ver" || die "Debian $SUITE's blender is $ver; Loom needs >= $MIN_MAJOR.$MIN_MINOR"

    printf 'blender_version=%s\nrecipe=%s\nsuite=%s\npackages=%s\nprovisioned=%s\n' \
        "$ver" "$RECIPE" "$SUITE" "${CHROOT_PACKAGES[*]}" "$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
        >"$tmp/$MARKER_NAME"
    sync -f "$tmp/$MARKER_NAME" 2>/dev/null || true

    if [[ -e $ROOT ]]; then
        # An older recipe (or a tree without marker): swap, then delete.
        old=$(mktemp -d "$ROOT.old.XXXXXX")
        mv -T -- "$ROOT" "$old/tree"
        mv -T -- "$tmp" "$ROOT"
        safe_rm "$old"
    else
        mv -T -- "$tmp" "$ROOT"
    fi
    trap - EXIT INT TERM
    note "Blender $ver ready in $ROOT after $((SECONDS - t0)) s ($(du -sh -- "$ROOT" | cut -f1))"
}

# Open the lock file on fd LOCK_FD.  Read-only, so that users who may not
# write to a cache provisioned by root can still take the (shared) lock.
open_lock() {
    [[ -e $LOCK_FILE ]] || : 2>/dev/null >>"$LOCK_FILE" || die "cannot create $LOCK_FILE"
    exec {LOCK_FD}<"$LOCK_FILE" || die "cannot read $LOCK_FILE"
}

# Make sure the chroot is there; leaves a *shared* lock held on fd LOCK_FD
# for as long as this process (and, through exec, Blender and its children)
# runs, so that 'clean' or a recipe rebuild never deletes a tree in use.
# Provisioning takes the lock exclusively, so two concurrent first runs
# provision only once: the second waits and then finds the marker.
ensure_chroot() {
    need_cache_dir
    mkdir -p -- "$CACHE_DIR" 2>/dev/null || die "cannot create the cache directory $CACHE_DIR (set LOOM_CACHE)"
    open_lock
    if ! flock -n -s "$LOCK_FD"; then
        note "waiting for the lock on $LOCK_FILE (another run is provisioning the chroot)"
        flock -s "$LOCK_FD"
    fi
    chroot_ready && return 0
    if ! flock -n -x "$LOCK_FD"; then
        note "waiting for the lock on $LOCK_FILE (another provisioning, or runs of an outdated chroot)"
        flock -x "$LOCK_FD"
    fi
    chroot_ready || provision
    flock -s "$LOCK_FD"
}

# ---------------------------------------------------------------------------
# The chroot: running

# First component of absolute path $1 ("work" for /work/main).
top_dir() {
    local t=${1#/}
    printf '%s\n' "${t%%/*}"
}

# Run "$@" inside the chroot, as 'run' and 'exec' do.  Does not return.
exec_in_chroot() {
    ensure_host_tools
    ensure_chroot
    local unshare_args=(--mount --propagation private)
    if ((EUID != 0)); then
        # Without root, a user namespace gives the mount and chroot rights.
        unshare_args=(--user --map-root-user "${unshare_args[@]}")
    fi
    exec unshare "${unshare_args[@]}" -- "$BASH" "$SCRIPT_PATH" __enter run "$ROOT" "$PWD" -- "$@"
}

# Internal: runs in the new private mount namespace, sets up the mounts and
# execs the command in the chroot.  None of these mounts is visible outside
# this process tree and all vanish when it ends: nothing to clean up.
#
# Why this layout:
# - Paths must mean the same inside and outside.  Binding the host's / over
#   the chroot is impossible (the chroot *is* the OS part), so host
#   directories are rbind-mounted at the same path: /proc, /sys, /dev (with
#   /dev/shm and /dev/pts), /var/tmp, the top-level directories in
#   ALWAYS_SHARED, the top-level directory of this clone (/work), and the
#   top-level directory of $HOME, $TMPDIR, the working directory, every
#   existing absolute path in the arguments and every path in
#   $LOOM_BLENDER_SHARE (colon-separated).  When such a path lies under an OS
#   directory (HOME=/var/lib/ci, say), the path itself is bound instead,
#   unless that would hide files of the chroot's own (then a warning says
#   so, and the host's file is still reachable as /host/PATH).
# - The host's whole / is rbind-mounted read-only at /host, and the shared
#   directories are bound writable over it too, so /host looks like the host
#   does from the outside.  host-exec-wrapper scripts chroot into /host to run
#   host-built programs (loom-bake) with the host's libraries.  (The top
#   mount is read-only; submounts of the host that were already separate
#   mounts keep their flags: mount(8) in bookworm cannot do recursive
#   read-only.)
cmd_enter() {
    local mode=$1 root=$2 cwd=$3
    shift 3
    [[ ${1:-} == -- ]] && shift
    local chroot_bin
    chroot_bin=$(type -P chroot)

    if [[ $mode == provision ]]; then
        mount --rbind /proc "$root/proc"
        mount --rbind /dev "$root/dev"
        local proxy_env=() v
        for v in http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY; do
            [[ -n ${!v:-} ]] && proxy_env+=("$v=${!v}")
        done
        exec "$chroot_bin" "$root" /usr/bin/env -i PATH="$CHROOT_PATH" HOME=/root \
            LC_ALL=C.UTF-8 DEBIAN_FRONTEND=noninteractive "${proxy_env[@]}" "$@"
    fi

    local h=$root/$HOST_MNT d p arg
    # First a copy of the host's mount tree at /host, taken before any of our
    # own mounts exist below $root.  All shared directories are bound *from
    # this copy*: $root usually lies inside a shared directory ($HOME), and
    # binding the live /root after mounting things below $root would copy
    # those mounts too, again for every later bind (175 mounts instead of
    # ~35 in testing, growing with each shared directory).
    mount --rbind / "$h"

    SHARED=()
    for d in "${ALWAYS_SHARED[@]}"; do
        [[ -d /$d && ! -L /$d ]] && share_path "/$d" "/$d" "$root"
    done
    share_path /var/tmp /var/tmp "$root"
    share_path "$(dirname -- "$(dirname -- "$SCRIPT_PATH")")" "this clone" "$root"
    share_path "$HOME" "HOME" "$root"
    share_path "${TMPDIR:-}" "TMPDIR" "$root"
    share_path "$cwd" "the working directory" "$root"
    local extra=()
    IFS=: read -ra extra <<<"${LOOM_BLENDER_SHARE:-}"
    for p in "${extra[@]}"; do
        share_path "$p" "LOOM_BLENDER_SHARE entry $p" "$root"
    done
    for arg in "${@:2}"; do  # $1 is the command to run in the chroot
        [[ $arg == /* && -e $arg ]] || continue
        if [[ -d $arg ]]; then
            share_path "$arg" "argument" "$root"
        else
            share_path "$(dirname -- "$arg")" "the directory of argument $arg" "$root"
        fi
    done

    # Only now make /host read-only: its shared directories are separate
    # (writable) mounts by now, which this does not affect.
    mount -o remount,bind,ro "$h"
    for d in proc sys dev; do
        mount --rbind "/$d" "$root/$d"
    done

    if [[ ! -d $root/$cwd ]]; then
        note "warning: working directory $cwd does not exist in the chroot; using /"
        cwd=/
    fi
    exec "$chroot_bin" "$root" /usr/bin/env -C "$cwd" \
        -u LD_LIBRARY_PATH -u LD_PRELOAD -u PYTHONHOME -u LANGUAGE \
        PATH="$CHROOT_PATH" LC_ALL=C.UTF-8 LANG=C.UTF-8 LOOM_BLENDER_CHROOT="$root" \
        "$@"
}

# Bind host directory $1 at the same path in the chroot $2, taking it from
# the pristine copy of the host at $2/host (see cmd_enter), and bind that
# copy onto itself so it stays writable when /host is made read-only.
share_at() {
    local src=$2/$HOST_MNT$1
    mount --rbind "$src" "$src"
    mount --rbind "$src" "$2$1"
    SHARED+=("$1")
}

# Make host path $1 (described as $2 in warnings) visible at the same path in
# the chroot $3: share its top-level directory, or, under an OS directory,
# the path itself if that hides none of the chroot's own files.
share_path() {
    local p=$1 what=$2 root=$3 s q top parts part
    [[ -n $p && -d $p ]] || return 0
    p=$(readlink -f -- "$p") || return 0
    [[ $p == / ]] && return 0
    for s in "${SHARED[@]}"; do
        [[ $p == "$s" || $p == "$s"/* ]] && return 0
    done
    top=$(top_dir "$p")
    if [[ $OS_DIRS != *" $top "* ]]; then
        # Not part of the OS: share the whole top-level directory, hiding
        # whatever the chroot has there (only /root's dot files).
        if [[ ! -d $root/$top ]] && ! mkdir -p -- "$root/$top" 2>/dev/null; then
            note "warning: $what ($p) is not visible in the chroot (cannot create $root/$top)"
            return 0
        fi
        share_at "/$top" "$root"
        return 0
    fi
    # Under an OS directory.  Walk the path inside the chroot: a symlink
    # would lead elsewhere (maybe out of the chroot), and an existing
    # non-empty directory would be hidden.
    IFS=/ read -ra parts <<<"${p#/}"
    q=$root
    for part in "${parts[@]}"; do
        q=$q/$part
        if [[ -L $q ]]; then
            note "warning: $what ($p) is not visible in the chroot ($q is a symlink there); the host's is /$HOST_MNT$p"
            return 0
        fi
    done
    if [[ -e $q ]] && { [[ ! -d $q ]] || [[ -n $(ls -A -- "$q") ]]; }; then
        note "warning: $what ($p) is not visible in the chroot (it would hide the chroot's own $p); the host's is /$HOST_MNT$p"
        return 0
    fi
    if ! mkdir -p -- "$q" 2>/dev/null; then
        note "warning: $what ($p) is not visible in the chroot (cannot create the mount point)"
        return 0
    fi
    share_at "$p" "$root"
}

# ---------------------------------------------------------------------------
# Commands

cmd_run() {
    select_blender
    if [[ $SEL_KIND == host ]]; then
        exec "$SEL_BIN" "$@"
    fi
    exec_in_chroot blender "$@"
}

cmd_exec() {
    (($# > 0)) || die "exec: no command given"
    select_blender
    if [[ $SEL_KIND == host ]]; then
        exec "$@"
    fi
    exec_in_chroot "$@"
}

cmd_info() {
    local out osl version chroot_json
    select_blender
    if [[ $SEL_KIND == chroot ]]; then
        ensure_chroot
        version=$(marker_value blender_version)
        chroot_json=$(json_str "$ROOT")
    else
        version=$SEL_VERSION
        chroot_json=null
    fi
    # with_osl: does this Cycles build have OSL (Debian's 4.3 has not)?
    out=$(cmd_run -b --factory-startup --python-expr \
        'import _cycles; print("LOOM_WITH_OSL=%s" % bool(_cycles.with_osl))' 2>/dev/null) ||
        die "Blender ($SEL_BIN) failed to run a Python expression"
    case $out in
        *LOOM_WITH_OSL=True*) osl=true ;;
        *LOOM_WITH_OSL=False*) osl=false ;;
        *) die "could not read _cycles.with_osl from Blender ($SEL_BIN)" ;;
    esac
    printf '{"blender": %s, "version": %s, "with_osl": %s, "chroot": %s}\n' \
        "$(json_str "$SEL_BIN")" "$(json_str "$version")" "$osl" "$chroot_json"
}

cmd_provision() {
    (($# == 0)) || die "provision takes no arguments"
    ensure_host_tools
    ensure_chroot
    note "chroot ready: $ROOT (Blender $(marker_value blender_version))"
}

cmd_clean() {
    need_cache_dir
    [[ -e $ROOT ]] || { note "nothing to clean at $ROOT"; return 0; }
    mkdir -p -- "$CACHE_DIR"
    open_lock
    if ! flock -n -x "$LOCK_FD"; then
        note "waiting for runs in the chroot to finish"
        flock -x "$LOCK_FD"
    fi
    safe_rm "$ROOT"
    note "removed $ROOT"
}

# Why a nested chroot rather than calling the host's dynamic loader directly
# (/host/lib64/ld-linux-x86-64.so.2 --library-path /host/... /host/BIN): the
# loader route was tried and is subtly wrong.  On Debian /lib64/ld-linux*.so.2
# is an *absolute* symlink, so inside the chroot it resolves to trixie's
# loader; libraries reached through absolute symlinks (libblas.so.3 and
# liblapack.so.3 go through /etc/alternatives, and oiiotool needs them) are
# silently loaded from trixie, mixing two glibc generations; anything not on
# the list falls back to trixie's ld.so.cache; /proc/self/exe names the loader,
# not the program; and /etc, /usr/share, gconv and locale data are trixie's.
# Chrooting into /host (the host's / with the shared directories writable)
# makes the program see exactly the host, at the same paths, while staying
# in the same process tree and mount namespace as Blender.
cmd_host_exec_wrapper() {
    (($# == 2)) || die "usage: $PROG host-exec-wrapper PATH_TO_HOST_BINARY OUT_WRAPPER"
    local bin=$1 out=$2 outdir top q tmp
    if [[ $bin != */* ]]; then
        bin=$(type -P -- "$bin") || die "host-exec-wrapper: no command '$1' on PATH"
    fi
    # Absolute, but symlinks kept: they resolve within the host's view.
    bin=$(realpath -s -- "$bin")
    [[ -f $bin && -x $bin ]] || die "host-exec-wrapper: $bin is not an executable file"
    outdir=$(dirname -- "$out")
    [[ -d $outdir ]] || die "host-exec-wrapper: directory $outdir does not exist"
    outdir=$(readlink -f -- "$outdir")
    top=${outdir#/}
    top=${top%%/*}
    if [[ -n $top && $OS_DIRS == *" $top "* ]]; then
        note "warning: $outdir is under /$top, which the chroot may not share with the host; put the wrapper under /tmp, \$HOME or the clone"
    fi
    q=${bin//\'/\'\\\'\'}
    tmp=$(mktemp "$outdir/.${out##*/}.XXXXXX")
    cat >"$tmp" <<EOF
#!/bin/sh
# Generated by Loom's scripts/blender.sh host-exec-wrapper; do not edit.
# Runs the host program below with all arguments.  Inside Loom's Blender
# chroot (marker /$MARKER_NAME) it chroots back into the host's file system,
# shown at /$HOST_MNT, so the program gets the host's own libraries and data;
# anywhere else it simply execs the program.  Exit status is the program's.
bin='$q'
if [ -f /$MARKER_NAME ] && [ -d /$HOST_MNT/usr ]; then
    dir=\$(pwd)
    [ -d "/$HOST_MNT\$dir" ] || dir=/
    exec /usr/sbin/chroot /$HOST_MNT /usr/bin/env -C "\$dir" "\$bin" "\$@"
fi
exec "\$bin" "\$@"
EOF
    chmod 755 "$tmp"
    mv -f -- "$tmp" "$out"
}

main() {
    local cmd=${1:-}
    (($# > 0)) && shift
    case $cmd in
        run) cmd_run "$@" ;;
        exec) cmd_exec "$@" ;;
        info) (($# == 0)) || die "info takes no arguments"; cmd_info ;;
        provision) cmd_provision "$@" ;;
        clean) cmd_clean "$@" ;;
        host-exec-wrapper) cmd_host_exec_wrapper "$@" ;;
        __enter) cmd_enter "$@" ;;
        -h | --help | help) usage ;;
        "") usage >&2; exit 2 ;;
        *) printf '%s: unknown command: %s\n\n' "$PROG" "$cmd" >&2; usage >&2; exit 2 ;;
    esac
}

main "$@"
