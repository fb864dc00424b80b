#!/usr/bin/env bash
# Proves that another project can use octovk as installed: installs the built tree (default
# build/, from scripts/build.sh) into a temporary prefix with `cmake --install`, then
#   1. configures tests/consumer with find_package(octovk) while OctoMap's package is disabled,
#      builds core_consumer (octovk::octovk only) and runs it;
#   2. configures it with find_package(octovk COMPONENTS octomap), builds and runs core_consumer
#      and octomap_consumer (a .bt written and read back);
#   3. configures it with find_package(octovk COMPONENTS octomap store), builds and runs
#      store_consumer (two scans committed to an SQLite store and read back);
#   4. builds all three with plain g++ and `pkg-config --cflags --libs octovk` (octovk-octomap,
#      octovk-store) and runs them;
# and checks that the core (its exported targets, its pkg-config flags, the headers they reach, the
# libraries a core-only program loads) is free of OctoMap. A consumer program exits 77 (skipped)
# without a Vulkan device; with CI set it fails instead.
# Usage: scripts/consumer.sh [BUILD_DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$(cd "${1:-$root/build}" 2>/dev/null && pwd)" || build="${1:-$root/build}"
src="$root/tests/consumer"
die() { echo "consumer.sh: error: $*" >&2; exit 1; }

[ -f "$build/CMakeCache.txt" ] ||
  die "$build is not a configured build tree: build it first (scripts/build.sh)"
work="$(mktemp -d "${TMPDIR:-/tmp}/octovk-consumer.XXXXXX")"
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"

echo "consumer.sh: installing $build into $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log" 2>&1 ||
  { cat "$work/install.log" >&2; die "cmake --install failed (is $build fully built? run scripts/build.sh)"; }
for f in bin/octovk include/octovk/octovk.hpp include/octovk/vulkan_interop.hpp \
  include/octovk/device_types.h include/octovk/octomap_io.hpp include/octovk/store.hpp; do
  [ -f "$prefix/$f" ] || die "the install lacks $f"
done
"$prefix/bin/octovk" --help >/dev/null || die "the installed program $prefix/bin/octovk does not run"
cmakedir="$(dirname "$(find "$prefix" -name octovkConfig.cmake -print -quit)")"
pcdir="$(dirname "$(find "$prefix" -name octovk.pc -print -quit)")"
[ -f "$cmakedir/octovkConfigVersion.cmake" ] || die "the install lacks octovkConfig.cmake or its version file"
[ -f "$pcdir/octovk-octomap.pc" ] || die "the install lacks octovk.pc or octovk-octomap.pc"
core_lib="$(find "$prefix" \( -name liboctovk.a -o -name liboctovk.so \) -print -quit)"
[ -n "$core_lib" ] || die "the install lacks the core library liboctovk"
# (grep without -q reads all of nm's output: no SIGPIPE to trip pipefail)
if nm -C "$core_lib" | grep 'octom[a-z]*::' >/dev/null; then
  die "the core library $core_lib defines or uses OctoMap symbols ($(nm -C "$core_lib" |
    grep -m1 -o 'octom[a-z]*::[^ ]*')): that code belongs in src/io (octovk::octomap)"
fi
if grep -il octom "$cmakedir"/octovkTargets*.cmake; then
  die "the exported core target (octovkTargets*.cmake above) names OctoMap: octovk::octovk must not link it"
fi

skipped=0
run() {  # PROGRAM: runs it; 0 passes, 77 is a skip (no device, CI unset), anything else fails
  local rc=0
  "$1" || rc=$?
  if [ "$rc" -eq 77 ]; then
    skipped=$((skipped + 1))
  elif [ "$rc" -ne 0 ]; then
    die "$1 failed (exit $rc)"
  fi
}
configure_build() {  # DIR, then cmake arguments
  local dir="$1"
  shift
  if ! { cmake -S "$src" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" "$@" &&
    cmake --build "$dir" -j "$(nproc)"; } >"$dir.log" 2>&1; then
    cat "$dir.log" >&2
    die "the consumer in $dir did not configure or build (log above)"
  fi
}

echo "consumer.sh: find_package(octovk) without OctoMap: octovk::octovk"
configure_build "$work/core" -DCONSUMER_OCTOMAP=OFF -DCMAKE_DISABLE_FIND_PACKAGE_octomap=ON
run "$work/core/core_consumer"

echo "consumer.sh: find_package(octovk COMPONENTS octomap): octovk::octovk and octovk::octomap"
configure_build "$work/both"
run "$work/both/core_consumer"
run "$work/both/octomap_consumer"

echo "consumer.sh: find_package(octovk COMPONENTS octomap store): octovk::store too"
configure_build "$work/store" -DCONSUMER_STORE=ON
run "$work/store/store_consumer"

echo "consumer.sh: pkg-config octovk / octovk-octomap / octovk-store with g++"
export PKG_CONFIG_PATH="$pcdir${PKG_CONFIG_PATH:+:$PKG_CONFIG_PATH}"
core_flags="$(pkg-config --cflags --libs octovk)" || die "pkg-config octovk failed"
octomap_flags="$(pkg-config --cflags --libs octovk-octomap)" || die "pkg-config octovk-octomap failed"
store_flags="$(pkg-config --cflags --libs octovk-store)" || die "pkg-config octovk-store failed"
case "$core_flags" in *octom*) die "pkg-config octovk names OctoMap: $core_flags" ;; esac
# The headers the core's flags reach: octovk's installed ones, none of OctoMap's.
# shellcheck disable=SC2086
g++ -std=c++20 -M $core_flags "$src/core_main.cpp" >"$work/core.deps"
header="$(grep -m1 -o '[^ ]*/octovk/octovk\.hpp' "$work/core.deps" || true)"
if [ -z "$header" ] || [ "$(realpath "$header")" != "$(realpath "$prefix/include/octovk/octovk.hpp")" ]; then
  die "pkg-config octovk does not lead to the installed headers in $prefix/include (got: ${header:-none})"
fi
if grep -q "/octomap/" "$work/core.deps"; then
  die "octovk's core headers include OctoMap: $(grep -o '[^ ]*/octomap/[^ ]*' "$work/core.deps" | head -3 | tr '\n' ' ')"
fi
# (the rpath matters only for a shared build, -DBUILD_SHARED_LIBS=ON)
rpath="-Wl,-rpath,$(pkg-config --variable=libdir octovk)"
# shellcheck disable=SC2086
g++ -std=c++20 -O1 -o "$work/core_pc" "$src/core_main.cpp" -Wl,--no-as-needed "$rpath" $core_flags
# shellcheck disable=SC2086
g++ -std=c++20 -O1 -o "$work/octomap_pc" "$src/octomap_main.cpp" "$rpath" $octomap_flags
# shellcheck disable=SC2086
g++ -std=c++20 -O1 -o "$work/store_pc" "$src/store_main.cpp" "$rpath" $store_flags
run "$work/core_pc"
run "$work/octomap_pc"
run "$work/store_pc"

if [ "$skipped" -gt 0 ]; then
  echo "consumer.sh: built everything; $skipped program run(s) SKIPPED: no Vulkan device"
else
  echo "consumer.sh: passed: CMake package and pkg-config, core without OctoMap, .bt round trip, a store"
fi
