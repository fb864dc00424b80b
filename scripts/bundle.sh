#!/usr/bin/env bash
# Packs a Release build into one self-contained folder for a machine that has a Vulkan driver but
# none of Debian's packages (a lent GPU machine: no Vulkan loader, no OctoMap, no libpng, no
# octomap-tools). The folder holds
#   run.sh       runs the test suite, the graph2tree parity checks and the benchmark (run.sh --help)
#   bin/         octovk, octovk_bench, graph2tree and log2graph (octomap-tools), bzip2, xz
#   tests/       every test executable of the build
#   lib/         the shared libraries these load that a bare x86-64 Linux lacks (OctoMap, libpng,
#                zlib, the Vulkan loader, ...); lib/compat/ libstdc++ and libgcc_s, used by run.sh
#                only where the machine's own are too old
#   data/        OctoMap's sample data, the repository's test data, the whole FR-079 scan graph
# and finds all of it relative to itself, so it can be copied anywhere (the device tool carries
# ignored paths of the repository: the default place, .bundle/, is ignored by git).
#
# Usage: scripts/bundle.sh [OUT_DIR]      (default: .bundle at the repository root)
# Environment: BUILD_DIR, the Release build to pack (default: build/ when it is a Release build,
# else build-bundle/); it is configured and brought up to date first.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out="${1:-$root/.bundle}"
octomap_data=/usr/share/doc/liboctomap-dev/examples/data

fail() {
  echo "bundle: error: $*" >&2
  exit 1
}

# Reuse build/ when it is a Release build (the usual one here); a Debug build/ stays untouched.
if [ -n "${BUILD_DIR:-}" ]; then
  build="$BUILD_DIR"
elif grep -qs '^CMAKE_BUILD_TYPE:STRING=Release$' "$root/build/CMakeCache.txt" ||
  [ ! -e "$root/build/CMakeCache.txt" ]; then
  build="$root/build"
else
  build="$root/build-bundle"
fi
echo "bundle: building $build (Release)" >&2
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DOCTOVK_BUILD_BENCH=ON >/dev/null
cmake --build "$build" -j "$(nproc)"

for tool in graph2tree log2graph bzip2 xz strip ldd objdump patchelf; do
  command -v "$tool" >/dev/null || fail "$tool is missing (scripts/setup.sh installs it)"
done
[ -f "$octomap_data/spherical_scan.graph" ] || fail "$octomap_data is missing (install liboctomap-dev)"

# A fresh folder each time: nothing of an older build may stay behind in it.
case "$out" in
  "" | / | "$root" | "$HOME") fail "refusing to replace '$out'" ;;
esac
rm -rf "$out"
mkdir -p "$out/bin" "$out/tests" "$out/lib/compat" "$out/data"

# Programs and test executables, stripped (the device tool carries at most 64 MiB in all), with
# the RUNPATH $ORIGIN/../lib: they load the bundle's libraries without LD_LIBRARY_PATH, as when a
# test runs octovk with the environment cleared (cli_test's file-limit test, on lavapipe).
copy_stripped() {  # copy_stripped SRC DST_DIR
  local dst
  dst="$2/$(basename "$1")"
  cp "$1" "$dst"
  strip --strip-unneeded "$dst"
  # shellcheck disable=SC2016  # $ORIGIN is for the dynamic loader, not the shell
  patchelf --set-rpath '$ORIGIN/../lib' "$dst"
}
copy_stripped "$build/octovk" "$out/bin"
copy_stripped "$build/bench/octovk_bench" "$out/bin"
for tool in graph2tree log2graph bzip2 xz; do copy_stripped "$(command -v "$tool")" "$out/bin"; done
tests=()
for exe in "$build"/tests/octovk_*; do
  [ -f "$exe" ] && [ -x "$exe" ] || continue
  # The PostgreSQL store's tests need a PostgreSQL server, which a lent machine lacks; the
  # store's SQLite tests stand for it there.
  [ "$(basename "$exe")" != octovk_store_postgres_tests ] || continue
  copy_stripped "$exe" "$out/tests"
  tests+=("$(basename "$exe")")
done
[ ${#tests[@]} -gt 0 ] || fail "no test executables in $build/tests"

# Libraries: every one the executables load, except those of the C/C++ runtime that any x86-64
# Linux with a Vulkan driver has (glibc's, the dynamic loader). libstdc++ and libgcc_s go to
# lib/compat: a machine whose own are newer keeps them (run.sh adds compat/ only when needed).
base_libs='^(linux-vdso\.so|ld-linux-x86-64\.so|libc\.so|libm\.so|libdl\.so|libpthread\.so|librt\.so|libresolv\.so)'
compat_libs='^(libstdc\+\+\.so|libgcc_s\.so)'
missing=0
while read -r name path; do
  if [ "$path" = "not" ]; then
    echo "bundle: error: $name is not found by ldd" >&2
    missing=1
    continue
  fi
  if [[ "$name" =~ $base_libs ]]; then continue; fi
  if [[ "$name" =~ $compat_libs ]]; then dest="$out/lib/compat"; else dest="$out/lib"; fi
  # Under its soname, the file itself (not the symlink), stripped of symbols only; RUNPATH
  # $ORIGIN, so that the libraries they load in turn (liboctomath, zlib) come from lib/ too.
  cp -L "$path" "$dest/$name"
  strip --strip-unneeded "$dest/$name"
  # shellcheck disable=SC2016
  [ "$dest" = "$out/lib/compat" ] || patchelf --set-rpath '$ORIGIN' "$dest/$name"
done < <(for f in "$out"/bin/* "$out"/tests/*; do ldd "$f"; done |
  awk '$2 == "=>" { print $1, $3 }' | sort -u)
[ $missing -eq 0 ] || fail "unresolved libraries"

# The Khronos validation layer, so that the suite can run under it there too (run.sh sets
# VK_LAYER_PATH to lib/layers; OCTOVK_VALIDATION=1 turns it on, as here).
layer_json=/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
layer_lib="$(ldconfig -p | awk '$1 == "libVkLayer_khronos_validation.so" && /x86-64/ { print $NF; exit }')"
[ -f "$layer_json" ] && [ -n "$layer_lib" ] ||
  fail "the validation layer is missing (apt-get install vulkan-validationlayers)"
mkdir -p "$out/lib/layers"
cp -L "$layer_lib" "$out/lib/libVkLayer_khronos_validation.so"
# The manifest names the library relative to itself.
sed 's|"library_path": *"[^"]*"|"library_path": "../libVkLayer_khronos_validation.so"|' \
  "$layer_json" > "$out/lib/layers/VkLayer_khronos_validation.json"

# Data. OctoMap's examples (small: all of it), the repository's test data and the hostile PNG of
# the fuzz corpus in the repository's own layout (a test reaches it as data/../fuzz/corpus/...).
mkdir -p "$out/data/octomap" "$out/data/tests/fuzz/corpus"
cp "$octomap_data"/* "$out/data/octomap/"
cp -r "$root/tests/data" "$out/data/tests/data"
cp -r "$root/tests/fuzz/corpus/depth_png" "$out/data/tests/fuzz/corpus/"
# The doc a layout test checks against the code, and the code it names (OCTOVK_SOURCE_DIR=data:
# data/docs/..., data/shaders/...; the node test reads the shaders' text).
mkdir -p "$out/data/docs" "$out/data/python"
cp "$root/docs/architecture.md" "$out/data/docs/"
cp -r "$root/shaders" "$root/src" "$root/include" "$out/data/"
cp -r "$root/python/src" "$out/data/python/"
# The pictures' text: one font and a fontconfig file naming only it (run.sh sets FONTCONFIG_FILE),
# since a bare machine may have neither and cairo would then draw the pictures without text.
mkdir -p "$out/data/fonts"
cp /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf "$out/data/fonts/"
cat > "$out/data/fonts/fonts.conf" <<'CONF'
<?xml version="1.0"?>
<!DOCTYPE fontconfig SYSTEM "urn:fontconfig:fonts.dtd">
<fontconfig>
  <dir prefix="relative">.</dir>
  <cachedir prefix="xdg">fontconfig</cachedir>
</fontconfig>
CONF
# The whole FR-079 graph (the bench's and the parity checks' input) made here, where python3 and
# log2graph are, so that the target needs neither; packed with xz (48 MB -> 5 MB: the device tool
# carries 64 MiB in all). run.sh unpacks it, and scan.dat from OctoMap's scan.dat.bz2, on first use.
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
"$root/bench/prepare_data.sh" "$scratch" >&2
mkdir -p "$out/data/bench"
xz -6 -c "$scratch/fr079.graph" > "$out/data/bench/fr079.graph.xz"

cp "$root/scripts/bundle_run.sh" "$out/run.sh"
chmod +x "$out/run.sh"
{
  echo "commit: $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "uncommitted changes in: $(git -C "$root" status --short 2>/dev/null | wc -l) paths"
  echo "built: $(date -u '+%Y-%m-%d %H:%M UTC') on $(. /etc/os-release && echo "$PRETTY_NAME")"
  echo "compiler: $(grep -m1 '^CMAKE_CXX_COMPILER:' "$build/CMakeCache.txt" | cut -d= -f2)" \
    "$("$(grep -m1 '^CMAKE_CXX_COMPILER:' "$build/CMakeCache.txt" | cut -d= -f2)" -dumpfullversion)"
  # The newest glibc symbol version any file needs: the target's glibc must be at least this.
  echo "needs glibc >= $(for f in "$out"/bin/* "$out"/tests/* "$out"/lib/*.so*; do
    objdump -T "$f" 2>/dev/null; done | grep -o 'GLIBC_[0-9.]*' | sed 's/GLIBC_//' | sort -uV | tail -1)"
  echo "tests: ${tests[*]}"
} > "$out/BUILD-INFO.txt"

# Nothing may point back into this checkout or its build: run.sh sets every path at run time.
if grep -rlF "$build" "$out/run.sh" "$out/BUILD-INFO.txt" >/dev/null 2>&1; then
  fail "run.sh or BUILD-INFO.txt names $build"
fi
echo "bundle: $out ($(du -sh "$out" | cut -f1)): $(ls "$out/bin" | wc -l) programs," \
  "${#tests[@]} test executables, $(find "$out/lib" -type f | wc -l) libraries" >&2
# The folder is larger than the device tool carries (64 MiB): it travels packed, as OUT.tar.xz
# beside it (about a quarter of its size), unpacked there by
#   mkdir -p /tmp/b && tar xJf .bundle.tar.xz -C /tmp/b && /tmp/b/.bundle/run.sh PART
tar -cf - -C "$(dirname "$out")" "$(basename "$out")" | xz -T0 -6 > "$out.tar.xz.tmp"
mv "$out.tar.xz.tmp" "$out.tar.xz"
echo "bundle: $out.tar.xz ($(du -sh "$out.tar.xz" | cut -f1)), to carry" >&2
