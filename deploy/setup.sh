#!/usr/bin/env bash
# Installs the missing Debian packages (apt only when something is missing), then configures and
# builds Release into build/. Idempotent; fast when nothing changed.
#   deploy/setup.sh [--build-dir DIR] [--sanitize] [--no-build] [--no-test-packages]
# --no-test-packages leaves out what only the tests use (chromium, python3-websocket, python3-pil),
# for images that only run the programs (deploy/Containerfile).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir="$here/build"
sanitize=OFF
do_build=1
test_packages=1
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) build_dir=$2; shift 2 ;;
    --sanitize) sanitize=ON; shift ;;
    --no-build) do_build=0; shift ;;
    --no-test-packages) test_packages=0; shift ;;
    -h|--help) sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "setup.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

packages=(cmake ninja-build g++ pkg-config ccache libgtest-dev libbenchmark-dev
  libopenni2-dev libopencv-dev libjpeg-dev libeigen3-dev liblcm-dev liblcm-bin libglib2.0-dev
  libdraco-dev draco pocl-opencl-icd ocl-icd-opencl-dev opencl-headers
  opencl-clhpp-headers clinfo iproute2 procps libssl-dev clang libclang-rt-14-dev
  libboost-dev nodejs)
# The web viewer's browser test drives Debian's chromium over the DevTools protocol.
[ "$test_packages" -eq 0 ] || packages+=(chromium python3-websocket python3-pil)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
# npm is its own Debian package; a nodejs build that bundles npm (and conflicts with the package)
# already provides the command.
command -v npm >/dev/null 2>&1 || dpkg -s npm >/dev/null 2>&1 || missing+=(npm)
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${#missing[@]} missing package(s): ${missing[*]}"
  sudo_cmd=()
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
    sudo_cmd=(sudo)
  fi
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "setup: all ${#packages[@]} packages present"
fi

# The web page's JavaScript (three.js with its Draco decoder, uPlot), pinned by package-lock.json;
# vdeform-web serves it from the build folder. npm ci only when the lock file changed.
web="$here/viewer_client/web"
if ! cmp -s "$web/package-lock.json" "$web/node_modules/.vd-installed-lock" 2>/dev/null; then
  echo "setup: npm ci in viewer_client/web"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
  cp "$web/package-lock.json" "$web/node_modules/.vd-installed-lock"
fi

# PoCL needs a writable kernel cache or it reports zero devices. The build and the tests use one in
# the build folder; the caller's own setting (unset: PoCL's default, ~/.cache/pocl/kcache) is the
# one a server started by hand uses, warmed below.
runtime_pocl_cache=${POCL_CACHE_DIR-}
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$build_dir/pocl-cache}
mkdir -p "$POCL_CACHE_DIR"

[ "$do_build" -eq 1 ] || exit 0
if [ ! -f "$build_dir/CMakeCache.txt" ]; then
  cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DVD_SANITIZE=$sanitize
fi
jobs=$(nproc 2>/dev/null || echo 2)
cmake --build "$build_dir" -j "$jobs"

# PoCL compiles every kernel the first time a process on this account launches it: 10-15 s on a
# 2-core machine, during which a server started by hand cannot listen (the program) and then drops
# the stream's first seconds (each kernel's first launch). A dozen frames of the tube through the
# server now, in the cache that server will use, moves that wait here (1-2 s once cached).
if [ "$sanitize" = OFF ]; then
  if ! (if [ -n "$runtime_pocl_cache" ]; then export POCL_CACHE_DIR=$runtime_pocl_cache; else unset POCL_CACHE_DIR; fi
    "$build_dir/server/vdeform-server" --input synthetic:tube --count 12 --quiet >/dev/null 2>&1); then
    echo "setup: warming the OpenCL kernel cache failed; the server's first start will compile the kernels" >&2
  fi
fi
