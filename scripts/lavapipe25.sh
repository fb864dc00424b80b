#!/usr/bin/env bash
# Fetches the second test driver: lavapipe from Mesa 25 (Debian bookworm-backports), unpacked with
# `dpkg -x` into build/mesa25/ beside the system's driver, which stays as it is. Writes
#   build/mesa25/lvp_icd.json   an ICD manifest pointing at the unpacked driver
#   build/mesa25/env.sh         `source` it to select that driver (VK_DRIVER_FILES, LD_LIBRARY_PATH)
# apt runs with a private configuration and package lists under build/mesa25/apt: the system's
# apt sources and installed packages are not touched. Skips the download when it is there.
# Usage: scripts/lavapipe25.sh [DIR]   (default: build/mesa25)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
dir="$(realpath -m "${1:-$root/build/mesa25}")"  # apt needs absolute paths
version="25.0.7-2~bpo12+1"
packages=(mesa-vulkan-drivers mesa-libgallium libdrm2 libdrm-amdgpu1 libdrm-intel1)

if [ -f "$dir/env.sh" ] && [ "$(cat "$dir/version" 2>/dev/null)" = "$version" ]; then
  echo "lavapipe25: Mesa $version present in $dir"
  exit 0
fi

fail() {
  echo "lavapipe25: error: $*" >&2
  echo "lavapipe25: the second test driver (Mesa 25 lavapipe) is unavailable; the tests cannot run on it" >&2
  exit 1
}

rm -rf "$dir"
apt_dir="$dir/apt"
mkdir -p "$apt_dir/lists/partial" "$apt_dir/cache/archives/partial" "$dir/debs" "$dir/root"
cat >"$apt_dir/sources.list" <<'EOF'
deb http://deb.debian.org/debian bookworm-backports main
deb http://deb.debian.org/debian bookworm main
EOF
apt_opts=(
  -o "Dir::Etc::SourceList=$apt_dir/sources.list" -o "Dir::Etc::SourceParts=/dev/null"
  -o "Dir::State::Lists=$apt_dir/lists" -o "Dir::Cache=$apt_dir/cache"
  -o "APT::Sandbox::User=$(id -un)" -o "Debug::NoLocking=1"
)
apt-get "${apt_opts[@]}" -qq update || fail "apt-get update of bookworm-backports failed"
pins=()
for p in "${packages[@]}"; do pins+=("$p/bookworm-backports"); done
(cd "$dir/debs" && apt-get "${apt_opts[@]}" -qq download "${pins[@]}") ||
  fail "apt-get download ${pins[*]} failed"
for deb in "$dir"/debs/*.deb; do dpkg -x "$deb" "$dir/root"; done
deb_version="$(dpkg-deb -f "$dir"/debs/mesa-vulkan-drivers_*.deb Version)"
[ "$deb_version" = "$version" ] ||
  echo "lavapipe25: note: bookworm-backports now has mesa-vulkan-drivers $deb_version (expected $version)"

lib="$dir/root/usr/lib/x86_64-linux-gnu"
[ -f "$lib/libvulkan_lvp.so" ] || fail "libvulkan_lvp.so is missing from the unpacked packages"
api="$(sed -n 's/.*"api_version": *"\([^"]*\)".*/\1/p' "$dir/root/usr/share/vulkan/icd.d/lvp_icd.json")"
cat >"$dir/lvp_icd.json" <<EOF
{ "file_format_version": "1.0.0", "ICD": { "library_path": "$lib/libvulkan_lvp.so", "api_version": "${api:-1.4.305}" } }
EOF
cat >"$dir/env.sh" <<EOF
# Selects Mesa $deb_version's lavapipe for Vulkan programs started from this shell.
export VK_DRIVER_FILES="$dir/lvp_icd.json"
export LD_LIBRARY_PATH="$lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
export OCTOVK_EXPECT_DRIVER="$deb_version"
EOF
echo "$version" >"$dir/version"
rm -rf "$dir/debs" "$apt_dir"
echo "lavapipe25: Mesa $deb_version lavapipe unpacked in $dir"
