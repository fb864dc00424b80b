#!/usr/bin/env bash
# The main job: installs what is needed, builds, and integrates a scan graph into an OctoMap file.
# Without arguments it integrates OctoMap's sample scan (spherical_scan.graph) at 0.05 m and
# writes out/spherical_scan.bt and out/spherical_scan.ot. With arguments, they go to `octovk`:
#   scripts/run.sh integrate my.graph -o my.bt --resolution 0.1
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/scripts/setup.sh"
"$root/scripts/build.sh"
if [ $# -gt 0 ]; then
  exec "$root/build/octovk" "$@"
fi
mkdir -p "$root/out"
exec "$root/build/octovk" integrate /usr/share/doc/liboctomap-dev/examples/data/spherical_scan.graph \
  -o "$root/out/spherical_scan.bt" -o "$root/out/spherical_scan.ot" --resolution 0.05
