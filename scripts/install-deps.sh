#!/usr/bin/env bash
# Installs the Debian 12 packages CrowdMPM builds and tests with: the engine, the tests, the SWIG
# bindings for Python, Java and C# and their packages (wheel, jar, nupkg), and opencv-doc for
# its example video vtest.avi, which the video tests run end to end; Chromium for the test of the
# HTML report. Safe to run again: installs only what is missing.
set -euo pipefail
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO=sudo; fi
PACKAGES=(cmake make g++ libeigen3-dev libopencv-dev nlohmann-json3-dev catch2
          swig python3-dev python3-numpy default-jdk-headless mono-mcs mono-runtime clang
          libclang-rt-14-dev opencv-doc libsqlite3-dev pkg-config
          python3-build python3-wheel python3-setuptools python3-venv python3-pip nuget chromium)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
