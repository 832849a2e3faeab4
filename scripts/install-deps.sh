#!/usr/bin/env bash
# Installs the Debian/Ubuntu packages bevy_cloth's examples and CI need (windowing, audio headers
# Bevy links against, Xvfb and Mesa's software Vulkan for headless screenshots). Skips what is
# already installed. Uses sudo when not run as root.
set -euo pipefail
packages=(pkg-config libudev-dev libwayland-dev libxkbcommon-dev libasound2-dev
          xvfb xauth mesa-vulkan-drivers libvulkan1)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "installing: ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
