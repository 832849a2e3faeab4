#!/usr/bin/env bash
# Renders every windowed example under Xvfb with Mesa's software Vulkan (lavapipe) in screenshot
# mode and saves target/screenshots/NAME.png (and NAME_start.png, its starting pose). Builds the
# examples first.
set -euo pipefail
cd "$(dirname "$0")/.."
out=target/screenshots
mkdir -p "$out"
examples=(hanging_cloth subdivision_compare drape flag tablecloth character avian_playground laundry inflatables tearing crowd)
cargo build --features examples $(printf -- '--example %s ' "${examples[@]}")
icd=$(ls /usr/share/vulkan/icd.d/lvp_icd.*.json | head -n 1)
for name in "${examples[@]}"; do
  rm -f "$out/$name.png" "$out/${name}_start.png"
  echo "screenshot: $name"
  BEVY_ASSET_ROOT="$PWD" WGPU_BACKEND=vulkan VK_ICD_FILENAMES="$icd" BEVY_CLOTH_SCREENSHOT="$PWD/$out/$name.png" \
    BEVY_CLOTH_SCREENSHOT_START="$PWD/$out/${name}_start.png" \
    timeout 600 xvfb-run -a -s "-screen 0 1280x720x24" "target/debug/examples/$name" \
    > "$out/$name.log" 2>&1 || { tail -n 30 "$out/$name.log"; exit 1; }
  for f in "$out/$name.png" "$out/${name}_start.png"; do
    [ -f "$f" ] || { echo "no $f from $name"; tail -n 30 "$out/$name.log"; exit 1; }
  done
done
