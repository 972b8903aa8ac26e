#!/usr/bin/env bash
# tools/setup.sh - bring a Debian 12 machine to the point where this project
# builds and runs, then build it. Idempotent: when everything is present it
# only checks and re-runs the (no-op) build, which takes a few seconds.
#
#   tools/setup.sh            run it
#   source tools/setup.sh     run it, then export build/hybrid-env.sh into this shell
#
# Steps
#   1. missing Debian packages -> apt-get update + install (only if something is missing)
#   2. deb-src entry /etc/apt/sources.list.d/hybrid-granular-src.sources (derived from
#      debian.sources) and Debian's LAMMPS source package of exactly the installed
#      lammps version, unpacked at $HYBRID_CACHE/lammps-src (full LAMMPS headers)
#   3. Python venv at $HYBRID_CACHE/venv from tools/requirements.txt
#      (recreated when that file's hash changes)
#   4. a PLUGIN-enabled LAMMPS built from that same source tree (packages PLUGIN and
#      GRANULAR, MPI, C++ exceptions, shared library liblammps_plugin.so, program
#      lmp_plugin), installed at $HYBRID_CACHE/lammps-plugin; cached, rebuilt only when
#      the source version or the build options change (stamp lammps-plugin.stamp).
#      Takes several minutes the first time (log: $HYBRID_CACHE/lammps-plugin.log).
#   5. cmake configure (Ninja, Release, -DLAMMPS_SOURCE_DIR=... -DLAMMPS_PLUGIN_PREFIX=...)
#      + build into build/
#   6. build/hybrid-env.sh for other scripts to source (puts build/mpm_solver and
#      build/lammps_fix_hybrid (lmp_hybrid) on PATH, exports LAMMPS_PLUGIN_PREFIX)
#
# Environment
#   HYBRID_CACHE        cache dir (default ${XDG_CACHE_HOME:-$HOME/.cache}/hybrid-granular),
#                       shared by all clones on the machine
#   HYBRID_CMAKE_ARGS   extra arguments for the cmake configure step (forces a reconfigure)
#   HYBRID_BUILD_JOBS   parallel build jobs (default: nproc)

# ---- sourced: run as a child process (so set -e / exit cannot hurt the caller's
# shell), then pull the environment file into the caller.
if [[ "${BASH_SOURCE[0]}" != "$0" ]]; then
  _hybrid_tools="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
  if bash "$_hybrid_tools/setup.sh" "$@"; then
    # shellcheck source=/dev/null
    source "$_hybrid_tools/../build/hybrid-env.sh"
    unset _hybrid_tools
    return 0
  else
    _hybrid_rc=$?
    unset _hybrid_tools
    return "$_hybrid_rc"
  fi
fi

set -Eeuo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$REPO/build"
CACHE="${HYBRID_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/hybrid-granular}"
VENV="$CACHE/venv"
LAMMPS_SRC="$CACHE/lammps-src"
LAMMPS_STAMP="$CACHE/lammps-src.stamp"
LMP_PLUGIN_PREFIX="$CACHE/lammps-plugin"
LMP_PLUGIN_BUILD="$CACHE/lammps-plugin-build"
LMP_PLUGIN_STAMP="$CACHE/lammps-plugin.stamp"
LMP_PLUGIN_LOG="$CACHE/lammps-plugin.log"
# Options of the PLUGIN-enabled LAMMPS (changing them triggers a rebuild). Shared library
# (plugins need it), suffix "plugin" (liblammps_plugin.so, lmp_plugin) so that it can never
# be mistaken for Debian's liblammps.so.0, and an RPATH to its own lib directory
# (LAMMPS_INSTALL_RPATH=on would set an empty one in this LAMMPS version).
LMP_PLUGIN_OPTS=(-D PKG_PLUGIN=on -D PKG_GRANULAR=on -D BUILD_MPI=on -D BUILD_OMP=off
                 -D LAMMPS_EXCEPTIONS=on -D BUILD_SHARED_LIBS=on -D LAMMPS_MACHINE=plugin
                 -D CMAKE_INSTALL_LIBDIR=lib -D CMAKE_INSTALL_RPATH="$LMP_PLUGIN_PREFIX/lib"
                 -D LAMMPS_SIZES=smallbig -D CMAKE_BUILD_TYPE=Release
                 -D WITH_JPEG=off -D WITH_PNG=off -D WITH_FFMPEG=off -D WITH_GZIP=on)
REQ="$REPO/tools/requirements.txt"
SRC_SOURCES=/etc/apt/sources.list.d/hybrid-granular-src.sources
JOBS="${HYBRID_BUILD_JOBS:-$(nproc)}"

PACKAGES=(build-essential cmake ninja-build pkg-config git python3-venv python3-dev
          dpkg-dev lammps liblammps-dev liggghts libliggghts-dev openmpi-bin libopenmpi-dev
          libeigen3-dev libhdf5-openmpi-dev libtomlplusplus-dev libcli11-dev
          googletest libgtest-dev)

log() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: ERROR: %s\n' "$*" >&2; exit 1; }
trap 'printf "setup: ERROR: command failed (exit %d, line %d): %s\n" "$?" "$LINENO" "$BASH_COMMAND" >&2' ERR

as_root() {
  if [[ $EUID -eq 0 ]]; then "$@"
  elif command -v sudo >/dev/null 2>&1; then sudo "$@"
  else die "need root (or sudo) to run: $*"
  fi
}

APT_GET=(env DEBIAN_FRONTEND=noninteractive apt-get -q -o DPkg::Lock::Timeout=600)

# ---------------------------------------------------------------- 1. packages
ensure_packages() {
  local installed missing=() p
  installed="$(dpkg-query -W -f='${Package} ${db:Status-Status}\n' "${PACKAGES[@]}" 2>/dev/null || true)"
  for p in "${PACKAGES[@]}"; do
    grep -qx "$p installed" <<<"$installed" || missing+=("$p")
  done
  if [[ ${#missing[@]} -eq 0 ]]; then
    log "Debian packages present (${#PACKAGES[@]})"
    return
  fi
  log "installing ${missing[*]}"
  as_root "${APT_GET[@]}" update || die "apt-get update failed"
  as_root "${APT_GET[@]}" install -y --no-install-recommends "${missing[@]}" \
    || die "apt-get install failed for: ${missing[*]}"
}

# ------------------------------------------------- 2. deb-src + LAMMPS source
# Print deb822 stanzas that mirror the enabled 'deb' stanzas of debian.sources as
# 'deb-src' (stanzas that already carry deb-src are skipped: nothing to add).
derive_deb_src() {
  local base=/etc/apt/sources.list.d/debian.sources
  if [[ -r $base ]]; then
    awk 'BEGIN { RS = ""; FS = "\n"; n = 0 }
      {
        types = ""; enabled = 1
        for (i = 1; i <= NF; i++) {
          if ($i ~ /^Types:/)   { types = $i; sub(/^Types:[ \t]*/, "", types) }
          if ($i ~ /^Enabled:[ \t]*no/) enabled = 0
        }
        if (!enabled || types == "") next
        nt = split(types, t, /[ \t]+/); has_deb = 0; has_src = 0
        for (j = 1; j <= nt; j++) { if (t[j] == "deb") has_deb = 1; if (t[j] == "deb-src") has_src = 1 }
        if (!has_deb || has_src) next
        if (n++) print ""
        for (i = 1; i <= NF; i++) print ($i ~ /^Types:/ ? "Types: deb-src" : $i)
      }' "$base"
  elif [[ -r /etc/apt/sources.list ]]; then
    # one-line format fallback: "deb [signed-by=...] URI SUITE COMPONENTS..."
    awk '$1 == "deb" {
        signed = ""; k = 2
        if ($2 ~ /^\[/) {
          while (k <= NF) { o = $k; gsub(/[][]/, "", o); if (o ~ /^signed-by=/) { sub(/^signed-by=/, "", o); signed = o }
                            if ($k ~ /\]$/) { k++; break } ; k++ }
        }
        if (n++) print ""
        print "Types: deb-src"; print "URIs: " $k; print "Suites: " $(k + 1)
        comps = ""; for (i = k + 2; i <= NF && $i !~ /^#/; i++) comps = comps (comps ? " " : "") $i
        print "Components: " comps
        if (signed != "") print "Signed-By: " signed
      }' /etc/apt/sources.list
  fi
}

# Writes $SRC_SOURCES if its content differs; sets DEB_SRC_CHANGED=1 if it wrote it.
DEB_SRC_CHANGED=0
ensure_deb_src() {
  local content
  content="$(derive_deb_src)"
  if [[ -z $content ]]; then
    grep -rqs '^[^#]*deb-src' /etc/apt/sources.list /etc/apt/sources.list.d/ \
      || die "no Debian 'deb' entries found in /etc/apt/sources.list.d/debian.sources or /etc/apt/sources.list"
    return 0   # deb-src already configured by the system
  fi
  content="# Written by hybrid-granular tools/setup.sh: deb-src mirror of debian.sources (for apt-get source lammps)"$'\n'"$content"
  if [[ -f $SRC_SOURCES && "$(cat "$SRC_SOURCES")" == "$content" ]]; then
    return 0
  fi
  log "adding deb-src entries: $SRC_SOURCES"
  printf '%s\n' "$content" | as_root tee "$SRC_SOURCES" >/dev/null || die "cannot write $SRC_SOURCES"
  DEB_SRC_CHANGED=1
}

ensure_lammps_source() {
  local spkg sver dirver work tree final old
  read -r spkg sver < <(dpkg-query -W -f='${source:Package} ${source:Version}\n' lammps) \
    || die "lammps is not installed"
  [[ -n ${sver:-} ]] || die "cannot determine the source version of the installed lammps"
  LAMMPS_VERSION="$sver"
  ensure_deb_src

  if [[ -f $LAMMPS_STAMP && "$(cat "$LAMMPS_STAMP")" == "$spkg $sver" && -f $LAMMPS_SRC/src/lammps.h ]]; then
    log "LAMMPS source $sver present: $LAMMPS_SRC"
    return
  fi

  log "fetching LAMMPS source package $spkg=$sver (matches installed lammps)"
  if [[ $DEB_SRC_CHANGED -eq 1 ]] || ! apt-get source --print-uris "$spkg=$sver" >/dev/null 2>&1; then
    log "apt-get update (source indexes)"
    as_root "${APT_GET[@]}" update || die "apt-get update failed"
  fi
  apt-get source --print-uris "$spkg=$sver" >/dev/null 2>&1 \
    || die "source package $spkg=$sver is not available from the configured deb-src entries ($SRC_SOURCES)"

  dirver="${sver#*:}"                     # drop an epoch, if any, for directory names
  work="$CACHE/.lammps-download.$$"
  rm -rf "$work"; mkdir -p "$work"
  ( cd "$work" && apt-get source -q "$spkg=$sver" ) \
    || { rm -rf "$work"; die "apt-get source $spkg=$sver failed (dpkg-dev installed?)"; }
  tree="$(find "$work" -mindepth 1 -maxdepth 1 -type d | head -n 1)"
  [[ -n $tree && -f $tree/src/lammps.h ]] \
    || { rm -rf "$work"; die "unpacked LAMMPS source has no src/lammps.h (in $work)"; }

  final="$CACHE/lammps-$dirver"
  rm -rf "$final"
  mv "$tree" "$final"
  rm -rf "$work"
  if [[ -e $LAMMPS_SRC && ! -L $LAMMPS_SRC ]]; then rm -rf "$LAMMPS_SRC"; fi
  ln -sfn "$(basename "$final")" "$LAMMPS_SRC"
  printf '%s %s\n' "$spkg" "$sver" > "$LAMMPS_STAMP"
  for old in "$CACHE"/lammps-*; do          # trees of earlier versions
    [[ -d $old && ! -L $old && $old != "$final" ]] && rm -rf "$old"
  done
  log "LAMMPS source $sver unpacked: $LAMMPS_SRC -> $(basename "$final")"
}

# ------------------------------------------------------------------ 3. venv
pick_python() {
  local c
  for c in python3 /usr/bin/python3; do
    if command -v "$c" >/dev/null 2>&1 && "$c" -c 'import venv, ensurepip' >/dev/null 2>&1; then
      command -v "$c"; return 0
    fi
  done
  return 1
}

ensure_venv() {
  local hash stamp="$VENV/.requirements.sha256" py
  [[ -f $REQ ]] || die "missing $REQ"
  hash="$(sha256sum "$REQ" | cut -d' ' -f1)"
  if [[ -x $VENV/bin/python && -f $stamp && "$(cat "$stamp")" == "$hash" ]] \
     && "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1; then
    log "Python venv up to date: $VENV"
    return
  fi
  py="$(pick_python)" || die "no python3 with venv support (install python3-venv)"
  log "creating Python venv $VENV (from $py) and installing tools/requirements.txt"
  rm -rf "$VENV"
  "$py" -m venv "$VENV" || die "python venv creation failed ($py -m venv $VENV)"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip \
    || die "pip upgrade failed in $VENV"
  # mpi4py is compiled here against the system Open MPI (mpicc from libopenmpi-dev).
  MPICC="$(command -v mpicc)" "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$REQ" \
    || die "pip install -r tools/requirements.txt failed (venv left incomplete; rerun to retry)"
  "$VENV/bin/python" -c 'import mpi4py; mpi4py.rc.initialize = False; from mpi4py import MPI; v = MPI.Get_library_version(); assert "Open MPI" in v, v' \
    || die "mpi4py in $VENV is not built against the system Open MPI"
  printf '%s\n' "$hash" > "$stamp"
}

# ------------------------------------------ 4. PLUGIN-enabled LAMMPS (cached)
ensure_plugin_lammps() {
  local want
  want="$(cat "$LAMMPS_STAMP") | ${LMP_PLUGIN_OPTS[*]}"
  if [[ -f $LMP_PLUGIN_STAMP && "$(cat "$LMP_PLUGIN_STAMP")" == "$want" \
        && -x $LMP_PLUGIN_PREFIX/bin/lmp_plugin ]]; then
    log "PLUGIN-enabled LAMMPS present: $LMP_PLUGIN_PREFIX/bin/lmp_plugin"
    return
  fi
  log "building a PLUGIN-enabled LAMMPS from $LAMMPS_SRC (several minutes; log: $LMP_PLUGIN_LOG)"
  rm -rf "$LMP_PLUGIN_BUILD" "$LMP_PLUGIN_PREFIX" "$LMP_PLUGIN_STAMP"
  local t0=$SECONDS
  if ! { cmake -S "$LAMMPS_SRC/cmake" -B "$LMP_PLUGIN_BUILD" -G Ninja \
           -D CMAKE_INSTALL_PREFIX="$LMP_PLUGIN_PREFIX" "${LMP_PLUGIN_OPTS[@]}" \
         && cmake --build "$LMP_PLUGIN_BUILD" -j "$JOBS" \
         && cmake --install "$LMP_PLUGIN_BUILD"; } >"$LMP_PLUGIN_LOG" 2>&1; then
    tail -n 30 "$LMP_PLUGIN_LOG" >&2
    die "building the PLUGIN-enabled LAMMPS failed (full log: $LMP_PLUGIN_LOG)"
  fi
  [[ -x $LMP_PLUGIN_PREFIX/bin/lmp_plugin ]] || die "PLUGIN-enabled LAMMPS installed no bin/lmp_plugin (log: $LMP_PLUGIN_LOG)"
  OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "$LMP_PLUGIN_PREFIX/bin/lmp_plugin" -h </dev/null \
    | grep -w PLUGIN >/dev/null \
    || die "$LMP_PLUGIN_PREFIX/bin/lmp_plugin does not list the PLUGIN package (log: $LMP_PLUGIN_LOG)"
  rm -rf "$LMP_PLUGIN_BUILD"      # objects are not needed once installed
  printf '%s\n' "$want" > "$LMP_PLUGIN_STAMP"
  log "PLUGIN-enabled LAMMPS built in $((SECONDS - t0))s: $LMP_PLUGIN_PREFIX/bin/lmp_plugin"
}

# ----------------------------------------------------------------- 5. build
cache_get() { sed -n "s|^$1:[A-Z]*=||p" "$BUILD/CMakeCache.txt" 2>/dev/null | head -n 1; }

configure_and_build() {
  local need=0
  # shellcheck disable=SC2206
  local extra=(${HYBRID_CMAKE_ARGS:-})
  if [[ ! -f $BUILD/CMakeCache.txt || ! -f $BUILD/build.ninja ]]; then
    need=1
  elif [[ "$(cache_get CMAKE_GENERATOR)" != Ninja || "$(cache_get CMAKE_HOME_DIRECTORY)" != "$REPO" ]]; then
    log "build/ was configured by another generator or source tree; clearing its CMake cache"
    rm -rf "$BUILD/CMakeCache.txt" "$BUILD/CMakeFiles"
    need=1
  elif [[ "$(cache_get LAMMPS_SOURCE_DIR)" != "$LAMMPS_SRC" || "$(cache_get CMAKE_BUILD_TYPE)" != Release \
          || "$(cache_get LAMMPS_PLUGIN_PREFIX)" != "$LMP_PLUGIN_PREFIX" || ${#extra[@]} -gt 0 ]]; then
    need=1
  elif [[ $LMP_PLUGIN_STAMP -nt $BUILD/CMakeCache.txt ]]; then
    need=1     # the PLUGIN-enabled LAMMPS was (re)built since the last configure
  fi
  if [[ $need -eq 1 ]]; then
    log "configuring (cmake, Ninja, Release)"
    cmake -S "$REPO" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DLAMMPS_SOURCE_DIR="$LAMMPS_SRC" -DLAMMPS_PLUGIN_PREFIX="$LMP_PLUGIN_PREFIX" \
      --no-warn-unused-cli "${extra[@]}" \
      || die "cmake configure failed (see output above; build/CMakeFiles/CMakeError.log)"
  fi
  log "building (cmake --build build -j$JOBS)"
  cmake --build "$BUILD" -j "$JOBS" || die "build failed (see compiler output above)"
}

# ------------------------------------------------------------- 6. env file
write_env_file() {
  local tmp="$BUILD/.hybrid-env.sh.$$"
  {
    echo "# Generated by tools/setup.sh - source this file: . build/hybrid-env.sh"
    printf 'export HYBRID_ROOT=%q\n' "$REPO"
    printf 'export HYBRID_CACHE=%q\n' "$CACHE"
    printf 'export HYBRID_VENV=%q\n' "$VENV"
    printf 'export LAMMPS_SOURCE_DIR=%q\n' "$LAMMPS_SRC"
    printf 'export LAMMPS_SOURCE_VERSION=%q\n' "$LAMMPS_VERSION"
    printf 'export LAMMPS_PLUGIN_PREFIX=%q\n' "$LMP_PLUGIN_PREFIX"
    printf 'case ":$PATH:" in *:%q:*) ;; *) export PATH=%q:"$PATH" ;; esac\n' \
      "$BUILD/mpm_solver" "$BUILD/mpm_solver"
    printf 'case ":$PATH:" in *:%q:*) ;; *) export PATH=%q:"$PATH" ;; esac\n' \
      "$BUILD/lammps_fix_hybrid" "$BUILD/lammps_fix_hybrid"
    if [[ $EUID -eq 0 ]]; then
      echo "# running as root: Open MPI refuses root without these"
      echo "export OMPI_ALLOW_RUN_AS_ROOT=1"
      echo "export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"
    fi
  } > "$tmp"
  mv -f "$tmp" "$BUILD/hybrid-env.sh"
}

# ------------------------------------------------------------------- main
command -v dpkg-query >/dev/null 2>&1 || die "this script expects Debian (dpkg-query not found)"
mkdir -p "$CACHE" "$BUILD" || die "cannot create $CACHE or $BUILD"
LAMMPS_VERSION=""

# One setup at a time per machine for the shared cache (apt, LAMMPS source, venv)...
exec 9>"$CACHE/.setup.lock"
if ! flock -n 9; then log "waiting for another setup run (lock $CACHE/.setup.lock)"; flock 9; fi
ensure_packages
ensure_lammps_source
ensure_venv
ensure_plugin_lammps
flock -u 9

# ...and one build at a time per build directory.
exec 8>"$BUILD/.setup.lock"
if ! flock -n 8; then log "waiting for another build in $BUILD"; flock 8; fi
configure_and_build
write_env_file
flock -u 8

log "LAMMPS_SOURCE_DIR=$LAMMPS_SRC (lammps $LAMMPS_VERSION)"
log "PLUGIN-enabled LAMMPS: $LMP_PLUGIN_PREFIX/bin/lmp_plugin"
log "env: source $BUILD/hybrid-env.sh"
log "done in ${SECONDS}s"
