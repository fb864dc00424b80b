#!/usr/bin/env bash
# Checks a bundle (scripts/bundle.sh) the way a machine without Debian's packages would run it:
# copies it to a fresh folder elsewhere and runs its run.sh there with an empty environment, in a
# private mount namespace where this checkout (and its build), Debian's OctoMap, libpng and
# Vulkan loader, octomap-tools and OctoMap's example data are hidden. Then every bundled
# executable's libraries must resolve, without LD_LIBRARY_PATH, to the bundle or to glibc and the
# C++ runtime, and the parts run as on the GPU machine. Needs root (unshare -m, mount).
#
# Usage: scripts/bundle_check.sh [PART...]   (default: info parity; also tests, bench; see run.sh)
# Environment: BUNDLE (default: .bundle, made by scripts/bundle.sh when missing), CHECK_DIR (where
# the copy and its results go; default: a new folder under /tmp, kept for reading).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bundle="${BUNDLE:-$root/.bundle}"
parts=("$@")
[ ${#parts[@]} -gt 0 ] || parts=(info parity)
[ "$(id -u)" -eq 0 ] || { echo "bundle_check: needs root (a mount namespace hides the system's libraries)" >&2; exit 1; }
[ -x "$bundle/run.sh" ] || "$root/scripts/bundle.sh" "$bundle"
check="${CHECK_DIR:-$(mktemp -d /tmp/octovk-bundle-check.XXXXXX)}"
rm -rf "$check/bundle"
mkdir -p "$check"
cp -a "$bundle" "$check/bundle"

# What a bare machine lacks, made unreadable inside the namespace (the real files behind the links).
hidden=(/usr/bin/graph2tree /usr/bin/log2graph)
for lib in liboctomap.so.1.9 liboctomath.so.1.9 libpng16.so.16 libvulkan.so.1; do
  hidden+=("$(realpath "/usr/lib/x86_64-linux-gnu/$lib")")
done
hide="mount -t tmpfs none '$root' && mount -t tmpfs none /usr/share/doc/liboctomap-dev"
for f in "${hidden[@]}"; do hide+=" && mount --bind /dev/null '$f'"; done

# Each bundled file's libraries: the bundle's own, or glibc's and the C++ runtime's.
# shellcheck disable=SC2016  # expanded by the inner shell, $0 being the bundle's copy
libs_check='cd "$0" && for f in bin/* tests/* lib/*.so*; do ldd "$f" | sed "s|^|$f: |"; done |
  grep -v -e "=> $0/" -e "linux-vdso" -e "ld-linux" -e "statically linked" -e ":\s*$" \
    -e "=> /lib/x86_64-linux-gnu/lib\(c\|m\|stdc++\|gcc_s\)\.so" || true'
strays="$(unshare -m --propagation private sh -c "$hide && exec env -i PATH=/usr/bin:/bin bash -c '$libs_check' '$check/bundle'")"
if [ -n "$strays" ]; then
  echo "bundle_check: libraries from outside the bundle:" >&2
  echo "$strays" >&2
  exit 1
fi
echo "bundle_check: every library resolves to the bundle or the C/C++ runtime" >&2

status=0
for part in "${parts[@]}"; do
  unshare -m --propagation private sh -c "$hide && exec env -i PATH=/usr/bin:/bin HOME=/root \
    OUT='$check/results' '$check/bundle/run.sh' $part" || status=1
done
echo "bundle_check: results in $check/results (summary.txt); the checkout was hidden throughout" >&2
exit $status
