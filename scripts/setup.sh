#!/usr/bin/env bash
# Installs what Loom needs to build and test, from Debian's own packages only, when it is missing.
# Idempotent: packages already installed are not touched; nothing is downloaded from anywhere else.
set -euo pipefail

PKGS=(
  build-essential cmake pkg-config ninja-build ccache
  libopenimageio-dev openimageio-tools libopenexr-dev libimath-dev libopencolorio-dev
  nlohmann-json3-dev libcli11-dev libtbb-dev libceres-dev libeigen3-dev libcerf-dev libfftw3-dev libnanoflann-dev libembree-dev libspdlog-dev libfmt-dev libssl-dev
  libgtest-dev libgmock-dev libbenchmark-dev clang libclang-rt-dev
  debootstrap util-linux time python3 python3-numpy python3-matplotlib nodejs
)

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "loom setup: all ${#PKGS[@]} Debian packages present"
  exit 0
fi

if [[ $(id -u) -ne 0 ]]; then
  SUDO=sudo
else
  SUDO=
fi
echo "loom setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get -o DPkg::Lock::Timeout=600 update -q
$SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends "${missing[@]}"
