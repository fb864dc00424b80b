#!/usr/bin/env bash
# Installs the Debian packages octovk needs to build, test and run; skips what is present.
# Idempotent: safe to run before every build.
set -euo pipefail

packages=(
  build-essential cmake pkg-config       # toolchain
  libvulkan-dev glslang-tools            # Vulkan loader/headers, GLSL -> SPIR-V compiler
  mesa-vulkan-drivers vulkan-tools       # lavapipe (Vulkan on the CPU) and vulkaninfo
  libeigen3-dev                          # math
  liboctomap-dev octomap-tools           # .bt/.ot/.graph I/O, the test oracle, graph2tree, sample data
  libdynamicedt3d-dev                    # the distance field's oracle in tests and bench (not the library)
  googletest libgtest-dev                # tests
  libpng-dev                             # TUM RGB-D depth images
  libsqlite3-dev libpq-dev               # the map store (octovk integrate --store, octovk store)
  postgresql                             # its tests start a private PostgreSQL server
  libcairo2-dev libfontconfig-dev fonts-dejavu-core  # octovk render / distance: pictures, text
  python3 bzip2                          # test data preparation (FR-079 log, scan.dat.bz2)
  gnuplot-nox                            # bench/plot_results.py draws the benchmark plot
  vulkan-validationlayers                # the tests run once under the Khronos validation layer
  patchelf xz-utils                      # scripts/bundle.sh: the bundle's RUNPATH, its packed data
  python3-dev pybind11-dev libdlpack-dev # the Python module (python/)
  python3-numpy python3-torch python3-pytest  # its tests: arrays, tensors through DLPack
  python3-cairo                          # python/examples/tum_integrate.py --picture
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages present"
  exit 0
fi

echo "setup: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "setup: error: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
